"""The tabulated surrogate of collide: certified bound, capture, fallback, cache, smoothness.

Every number is checked against ``collide(method="exact")`` (itself checked against mpmath in
test_reference.py), never against values produced by the surrogate's own code.
"""

from pathlib import Path

import numpy as np
import pytest

import dashpot
import dashpot.provenance
from dashpot.physics import surrogate as sg

GRAVITY = sg.SURROGATE_MODELS
LEVELS = tuple(sg.LEVELS)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """A private cache directory, with the real tables built there once (~1 s each)."""
    directory = tmp_path_factory.mktemp("dashpot-cache")
    sg.clear_memory_cache()
    for model in GRAVITY:
        for level in LEVELS:
            sg.load_surrogate(model, level, directory=directory)
    yield directory
    sg.clear_memory_cache()


def domain_points(model, n, seed):
    """Random (ζ, ṽ) in the table domain, drawn with a seed the certification does not use."""
    rng = np.random.default_rng(seed)
    zeta = np.exp(rng.uniform(np.log(sg.ZETA_MIN), np.log(sg.ZETA_MAX[model]), n))
    log_vc = np.log(dashpot.critical_velocity(model, zeta))
    s = np.exp(rng.uniform(np.log(2 * sg.S_MIN), np.log(np.log(sg.VTILDE_MAX) - log_vc)))
    return zeta, np.exp(log_vc + s)


def relative(a, b):
    return np.abs(a / b - 1.0)


@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("model", GRAVITY)
def test_certified_bound_meets_target(cache, model, level):
    table = sg.load_surrogate(model, level, directory=cache)
    assert table.bound <= sg.LEVELS[level]["target"]
    assert table.bound == pytest.approx(sg.SAFETY * max(table.errors.values()))


@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("model", GRAVITY)
def test_errors_within_bound_on_independent_points(cache, model, level):
    zeta, vtilde = domain_points(model, 20_000, seed=12345)
    got = sg.surrogate_collide(model, zeta, vtilde, level=level, directory=cache)
    exact = dashpot.collide(model, zeta, vtilde)
    assert got.method == "surrogate" and got.rtol == sg.load_surrogate(
        model, level, directory=cache).bound
    assert not exact.captured.any() and not got.captured.any()
    for name in ("eps", "one_minus_eps", "contact_time", "release_speed"):
        assert relative(getattr(got, name), getattr(exact, name)).max() <= got.rtol, name
    depth = exact.release_depth != 0.0
    assert np.all(relative(got.release_depth[depth], exact.release_depth[depth]) <= got.rtol)
    np.testing.assert_array_equal(got.release_depth[~depth], exact.release_depth[~depth])


@pytest.mark.parametrize("model", GRAVITY)
def test_capture_flags_agree_everywhere(cache, model):
    rng = np.random.default_rng(7)
    zeta = np.exp(rng.uniform(np.log(1e-5), np.log(3.0), 4000))
    vc = dashpot.critical_velocity(model, zeta)
    finite = np.isfinite(vc)
    # Right at the critical speed (both sides, down to 1e-9 relative) and far from it.
    offset = rng.choice([-1.0, 1.0], zeta.size) * np.exp(rng.uniform(np.log(1e-9), 0.0,
                                                                       zeta.size))
    vtilde = np.where(finite, vc * np.exp(offset), np.exp(rng.uniform(-3, 16, zeta.size)))
    wide = np.exp(rng.uniform(np.log(1e-3), np.log(1e8), zeta.size))
    zeta, vtilde = np.concatenate([zeta, zeta]), np.concatenate([vtilde, wide])
    got = sg.surrogate_collide(model, zeta, vtilde, directory=cache)
    exact = dashpot.collide(model, zeta, vtilde)
    np.testing.assert_array_equal(got.captured, exact.captured)
    # Captured points carry exactly the exact solver's values (hybrid: release state within
    # the bound where IIb releases).
    c = exact.captured
    for name in ("eps", "one_minus_eps", "contact_time"):
        np.testing.assert_array_equal(getattr(got, name)[c], getattr(exact, name)[c])
    released = c & (exact.release_speed > 0)
    np.testing.assert_array_equal(got.release_speed[c & ~released],
                                  exact.release_speed[c & ~released])
    assert np.all(relative(got.release_speed[released], exact.release_speed[released])
                  <= got.rtol)


@pytest.mark.parametrize("model", GRAVITY)
def test_fallback_points_are_exact_bit_for_bit(cache, model):
    zmax = sg.ZETA_MAX[model]
    zeta = np.array([0.0, 1e-6, 5e-5, zmax * 1.01, 0.95, 2.5, 10.0, 0.3, 0.3, 0.01])
    vc = dashpot.critical_velocity(model, np.array([0.3, 0.01]))
    vtilde = np.array([1.0, 2.0, 3.0, 4e3, 5e4, 50.0, 1e3, vc[0] * (1 + 3e-5), 1e12,
                       vc[1] * (1 - 5e-8)])
    status, _, _ = sg._classify(sg.load_surrogate(model, directory=cache), zeta, vtilde)
    fallback = status == 2
    assert fallback.sum() >= 7
    got = sg.surrogate_collide(model, zeta, vtilde, directory=cache)
    exact = dashpot.collide(model, zeta, vtilde)
    for name in ("eps", "one_minus_eps", "contact_time", "captured", "release_depth",
                 "release_speed"):
        np.testing.assert_array_equal(getattr(got, name)[fallback],
                                      getattr(exact, name)[fallback], err_msg=name)


@pytest.mark.parametrize("model", ("Ia", "IIa"))
def test_gravity_free_models_use_the_closed_forms(cache, model):
    zeta, vtilde = np.array([0.0, 1e-3, 0.5, 0.99, 1.0, 3.0]), np.array([1, 2, 3, 4, 5, 6.0])
    got = sg.surrogate_collide(model, zeta, vtilde, directory=cache)
    exact = dashpot.collide(model, zeta, vtilde)
    assert got.method == "surrogate" and got.rtol == exact.rtol
    for name in ("eps", "one_minus_eps", "contact_time", "captured", "release_speed"):
        np.testing.assert_array_equal(getattr(got, name), getattr(exact, name))


def test_shapes_broadcast_like_collide(cache):
    got = sg.surrogate_collide("IIb", [[0.1], [0.2]], [1.0, 10.0, 100.0], directory=cache)
    assert got.eps.shape == (2, 3) and got.captured.shape == (2, 3)
    with pytest.raises(ValueError, match="vtilde"):
        sg.surrogate_collide("IIb", 0.1, -1.0, directory=cache)
    with pytest.raises(ValueError, match="model"):
        sg.surrogate_collide("III", 0.1, 1.0, directory=cache)


def test_cache_round_trip_and_corrupt_file(cache, tmp_path, monkeypatch):
    monkeypatch.setenv("DASHPOT_CACHE_DIR", str(tmp_path))
    sg.clear_memory_cache()
    first = sg.load_surrogate("Ib", "fast")
    path = tmp_path / first.path.split("/")[-1]
    assert path.exists() and "Ib-fast" in path.name and dashpot.__version__ in path.name
    assert not list(tmp_path.glob(".*.partial"))  # no temporary left
    zeta, vtilde = domain_points("Ib", 500, seed=3)
    before = sg.surrogate_collide("Ib", zeta, vtilde)
    # A second load reads the file: same numbers bit for bit, and the same build time recorded.
    sg.clear_memory_cache()
    second = sg.load_surrogate("Ib", "fast")
    assert second.build_seconds == first.build_seconds
    np.testing.assert_array_equal(second.coef, first.coef)
    np.testing.assert_array_equal(sg.surrogate_collide("Ib", zeta, vtilde).eps, before.eps)
    # A corrupt file is rebuilt (deterministically), never trusted.
    path.write_bytes(path.read_bytes()[:1000])
    sg.clear_memory_cache()
    rebuilt = sg.load_surrogate("Ib", "fast")
    assert rebuilt.build_seconds != first.build_seconds
    np.testing.assert_array_equal(rebuilt.coef, first.coef)
    assert rebuilt.bound == first.bound
    # A file with altered numbers fails its checksum and is rebuilt as well.
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    arrays["coef"] = arrays["coef"] * (1 + 1e-12)
    np.savez(path, **arrays)
    sg.clear_memory_cache()
    assert sg._read(path, first.params) is None
    np.testing.assert_array_equal(sg.load_surrogate("Ib", "fast").coef, first.coef)
    sg.clear_memory_cache()


def test_a_table_built_by_other_physics_code_is_rebuilt(cache, tmp_path, monkeypatch):
    # Between releases the solvers change under one version number: the cached table names
    # the physics source it was built with, and a table of other code is not read.
    monkeypatch.setenv("DASHPOT_CACHE_DIR", str(tmp_path))
    sg.clear_memory_cache()
    first = sg.load_surrogate("Ib", "fast")
    assert first.params["source"] == dashpot.provenance.source_fingerprint(
        Path(sg.__file__).parent)
    monkeypatch.setattr(sg, "_physics_source", lambda: "0" * 64)
    assert sg._read(Path(first.path), sg._build_params("Ib", "fast")) is None
    sg.clear_memory_cache()
    rebuilt = sg.load_surrogate("Ib", "fast")
    assert rebuilt.path != first.path and rebuilt.build_seconds != first.build_seconds
    np.testing.assert_array_equal(rebuilt.coef, first.coef)
    sg.clear_memory_cache()


@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("model", GRAVITY)
def test_finite_differences_along_log_speed_match_exact(cache, model, level):
    zeta, vtilde = domain_points(model, 300, seed=99)
    vc = dashpot.critical_velocity(model, zeta)
    keep = vtilde > vc * np.exp(10 * sg.S_MIN)  # stay on the table for the steps below
    zeta, vtilde = zeta[keep], vtilde[keep]
    bound = sg.load_surrogate(model, level, directory=cache).bound
    for step in (1e-4, 1e-5, 1e-6):
        def slope(evaluate):
            up = evaluate(zeta, vtilde * np.exp(step)).eps
            down = evaluate(zeta, vtilde * np.exp(-step)).eps
            return (up - down) / (2 * step)

        fd_surrogate = slope(lambda z, v: sg.surrogate_collide(model, z, v, level=level,
                                                               directory=cache))
        fd_exact = slope(lambda z, v: dashpot.collide(model, z, v))
        eps = dashpot.collide(model, zeta, vtilde).eps
        # Each side differs from the exact value by at most bound·ε (plus the exact solver's
        # own ~1e-13): the difference quotients then agree to ~bound·ε/step.
        tolerance = 2.0 * (bound + 1e-13) * eps / step
        assert np.all(np.abs(fd_surrogate - fd_exact) <= tolerance), step
