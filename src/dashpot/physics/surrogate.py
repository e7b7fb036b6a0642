"""Fast, certified surrogate of :func:`dashpot.collide` for the gravity models (Ib, IIb, hybrid).

A fit calls ``collide`` a few hundred times with ~100 points each, and the exact solver's fixed
cost per call (~1 ms of Python-level root finding) dominates. This module tabulates the exact
solution once, as tensor-product quintic B-splines, caches the tables on disk, and evaluates them
in compiled loops (~0.05 µs per point, plus a few vectorized numpy operations per call).

Coordinates (chosen so that every tabulated function is analytic on the table)
------------------------------------------------------------------------------
* x = ln ζ (IIb, hybrid) or x = ln(ζ/√(1 − ζ²)) (Ib). Ib's critical speed grows like
  exp(πζ/√(1 − ζ²)) [1]_, whose singularity at ζ = 1 would otherwise sit just beyond the table
  edge; in this x it is an entire function (exp(π·eˣ)).
* s = ln(ṽ/ṽc(ζ)) > 0, the log-distance above the model's critical speed, and
  y = ln s + s. Near capture the solution is analytic in √s (ε ∝ √s for Ib and the hybrid, a
  square-root turn of the release time for IIb); ln s maps that branch point to y = −∞, and
  nearby singularities on the negative s axis (the hybrid's capture lies just above IIb's at
  small ζ) to a fixed distance π from the real y axis. For large s, y ≈ s, on which the
  large-speed limit is approached smoothly (corrections in 1/ṽ = e^{−s}/ṽc).

Tabulated fields (smooth on the table; relative accuracy maps to absolute accuracy)
-----------------------------------------------------------------------------------
* L = ln ε − ln(1 − ε) (the logit), minus ½ ln s for Ib and the hybrid (ε ∝ √s). Then
  ε = expit(L) and 1 − ε = expit(−L) both have relative error <= |ΔL|: one table keeps ε
  accurate near capture and 1 − ε accurate for nearly elastic contacts.
* ln(contact time).
* hybrid only: ln(vf/ṽ), the release speed at F = 0 (the climb needs vf, not only ε).
* ln ṽc(ζ) as a 1-D table in x.
The other outputs follow exactly as in :mod:`dashpot.physics.models`: release speed ε·ṽ (Ib,
IIb) or vf (hybrid), release depth 0 (Ib) or −2ζ·vf (IIb, hybrid).

Splines
-------
Uniform knots at the data nodes, quintic (C⁴ smooth: finite-difference Jacobians see no kinks),
with not-a-knot end conditions (the 6th differences of the coefficients vanish at both ends, so
no spurious boundary layer). Interpolation is separable: one small dense solve per axis. On a
uniform grid the knot interval is found by a floor, and the six nonzero B-splines are fixed
quintic polynomials of the offset in the interval [2]_: evaluation costs 36 multiply-adds per
point and field, in a loop compiled by numba.

Domain and fallback
-------------------
A point is served by the table if ζ_min <= ζ <= ζ_max(model) and s_min <= s <= s_max, with
s = ln ṽ − (tabulated ln ṽc). Points with s < −CAPTURE_BAND are captured (ṽ well below ṽc) and
get the exact solver's captured values in closed form. Everything else — the thin band around
the critical speed where the capture decision and ε ∝ √s are ill-conditioned, ζ outside the
table, ṽ above the table — is passed to the exact solver, on those points only. Ib for ζ >= 1
captures at every speed ([1]_; ``collide`` flags it so) and is answered directly.

Certification
-------------
Every table is checked against ``collide(method="exact")`` on a dense set of random points
(seeded, not used to build): the largest relative error in ε, 1 − ε, contact time and release
speed, times a safety factor of 2, is stored with the table as its certified ``bound`` and
returned as ``Collision.rtol``.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 (models Ib, IIb, hybrid; inelastic capture).
.. [2] C. de Boor, *A Practical Guide to Splines*, rev. ed., Springer (2001), ch. IX (B-splines)
   and ch. XIII (not-a-knot end conditions); the uniform quintic B-spline segments are the
   standard ones, e.g. in I. J. Schoenberg, *Cardinal Spline Interpolation*, SIAM (1973).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np
import platformdirs
from scipy.special import expit, lambertw

from .._validation import check_model, check_nonnegative, check_positive
from ..atomic import atomic_path
from .models import EXACT_RTOL, MODELS, Collision, collide, critical_velocity

__all__ = ["LEVELS", "SURROGATE_MODELS", "Surrogate", "CacheWarning", "build_surrogate",
           "cache_dir", "load_surrogate", "surrogate_collide"]

SURROGATE_MODELS = ("Ib", "IIb", "hybrid")
"""Models with a tabulated surrogate; Ia and IIa are closed forms and use the exact path."""

FORMAT_VERSION = 1  # bump when the file layout or the tabulated fields change

ZETA_MIN = 1e-4
"""Smallest damping ratio on the tables."""

ZETA_MAX = {"Ib": 0.9, "IIb": 2.0, "hybrid": 2.0}
"""Largest damping ratio on each model's table. Ib's ṽc is 1.7e3 at ζ = 0.9 and diverges at 1."""

VTILDE_MAX = 1e7
"""The tables reach at least this impact speed at every ζ (more where ṽc is larger)."""

S_MIN = 1e-4
"""Smallest s = ln(ṽ/ṽc) on the tables. Below it ε ∝ √s is ill-conditioned for the exact solver
itself (relative error ~1e-16/s), which the tables could not be certified against."""

CAPTURE_BAND = 1e-7
"""Points with −CAPTURE_BAND <= s < S_MIN go to the exact solver, which decides capture there;
below −CAPTURE_BAND they are captured. The band is far wider than the error of the tabulated
ln ṽc (~1e-14) and than the exact solver's capture fuzz, so the flags always agree."""

SAFETY = 2.0
"""Certified bound = SAFETY × the largest error measured on the certification points."""

LEVELS = {
    "fast": dict(target=1e-6, nx=64, ny=120, n_critical=400, n_certify=200_000),
    "standard": dict(target=1e-9, nx=200, ny=340, n_critical=1200, n_certify=200_000),
}
"""Accuracy levels: target relative error and grid sizes (nodes in x and y on the domain).

The grids were chosen so that the certified bound meets the target for every model."""

_MARGIN = 3  # extra nodes beyond each end of the domain: the ends of a spline are its weakest part
_CACHE_ENV = "DASHPOT_CACHE_DIR"
_LOADED: dict = {}  # in-memory cache: (model, level, directory) -> Surrogate

# Uniform quintic B-spline segments: on a knot interval with offset u in [0, 1), the six nonzero
# B-splines are these polynomials (rows, highest power last), scaled by 1/120 [2]_.
_QUINTIC = np.array([
    [1.0, -5.0, 10.0, -10.0, 5.0, -1.0],
    [26.0, -50.0, 20.0, 20.0, -20.0, 5.0],
    [66.0, 0.0, -60.0, 0.0, 30.0, -10.0],
    [26.0, 50.0, 20.0, -20.0, -20.0, 10.0],
    [1.0, 5.0, 10.0, 10.0, 5.0, -5.0],
    [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
]) / 120.0
_QUINTIC_T = np.ascontiguousarray(_QUINTIC.T)  # row p: coefficient of u**p in each weight
# A cardinal B-spline at its own node and the two neighbours on each side.
_AT_NODES = np.array([1.0, 26.0, 66.0, 26.0, 1.0]) / 120.0
# Sixth difference: zero where a quintic spline has no jump in its 5th derivative (not-a-knot).
_SIXTH_DIFFERENCE = np.array([1.0, -6.0, 15.0, -20.0, 15.0, -6.0, 1.0])


# --- uniform quintic splines -------------------------------------------------------------------

def _interpolation_matrix(n):
    """(n + 4)² system for the B-spline coefficients interpolating n uniform nodes (not-a-knot).

    Coefficient j belongs to the B-spline centred on node j − 2. Rows 0..n−1 interpolate
    node i; the last four rows ask the two leftmost and two rightmost interior knots to carry no
    5th-derivative jump, i.e. zero 6th differences of the coefficients there.
    """
    matrix = np.zeros((n + 4, n + 4))
    for i in range(n):
        matrix[i, i:i + 5] = _AT_NODES
    for row, start in zip(range(n, n + 4), (0, 1, n - 4, n - 3)):
        matrix[row, start:start + 7] = _SIXTH_DIFFERENCE
    return matrix


def _fit_coefficients(values):
    """B-spline coefficients of the uniform quintic interpolant of `values` on its grid.

    `values` has one axis per grid dimension (1 or 2) and optionally a trailing axis of fields;
    the tensor-product interpolation is solved one axis at a time.
    """
    coef = np.asarray(values, dtype=float)
    n_axes = coef.ndim if coef.ndim <= 1 else 2
    for axis in range(n_axes):
        moved = np.moveaxis(coef, axis, 0)
        matrix = _interpolation_matrix(moved.shape[0])
        rhs = np.concatenate([moved, np.zeros((4,) + moved.shape[1:])], axis=0)
        solved = np.linalg.solve(matrix, rhs.reshape(rhs.shape[0], -1)).reshape(rhs.shape)
        coef = np.moveaxis(solved, 0, axis)
    return coef


@numba.njit(cache=True, inline="always")
def _quintic_weights(t, n_nodes, weights):
    """Knot interval of grid coordinate t (node units, in [0, n_nodes − 1]; the right end is
    evaluated in the last interval), and the six nonzero B-spline weights there, written to
    `weights`: the segment polynomials of the offset in the interval [2]_, by Horner's rule."""
    cell = min(math.floor(t), n_nodes - 2.0)
    offset = t - cell
    for j in range(6):
        value = _QUINTIC_T[5, j]
        for power in range(4, -1, -1):
            value = value * offset + _QUINTIC_T[power, j]
        weights[j] = value
    return int(cell)


@numba.njit(cache=True, inline="always")
def _spline_1d_at(coef, start, step, x, weights):
    """Value at one point x of a 1-D uniform quintic spline with nodes start + i·step
    (`weights`: scratch space for six numbers)."""
    cell = _quintic_weights((x - start) / step, coef.size - 4, weights)
    value = 0.0
    for j in range(6):
        value += coef[cell + j] * weights[j]
    return value


@numba.njit(cache=True, inline="always")
def _add_patch(coef, cell_x, wx, cell_y, wy, out):
    """Add the first out.size fields of a tensor-product spline on the 6×6 patch at
    (cell_x, cell_y) with weights wx, wy to `out` (36 multiply-adds per field)."""
    for a in range(6):
        for b in range(6):
            weight = wx[a] * wy[b]
            for f in range(out.size):
                out[f] += coef[cell_x + a, cell_y + b, f] * weight


@numba.njit(cache=True)
def _evaluate_1d(coef, start, step, x):
    """Value of a 1-D uniform quintic spline with nodes start + i·step at the points x."""
    out = np.empty(x.size)
    weights = np.empty(6)
    for i in range(x.size):
        out[i] = _spline_1d_at(coef, start, step, x[i], weights)
    return out


@numba.njit(cache=True)
def _evaluate_2d(coef, x_start, x_step, y_start, y_step, x, y):
    """All fields of a tensor-product quintic spline at the points (x, y): shape (n, fields).

    36 multiply-adds per point and field on the 6×6 patch of coefficients around the point.
    """
    nx, ny, n_fields = coef.shape
    out = np.zeros((x.size, n_fields))
    wx = np.empty(6)
    wy = np.empty(6)
    for i in range(x.size):
        cell_x = _quintic_weights((x[i] - x_start) / x_step, nx - 4, wx)
        cell_y = _quintic_weights((y[i] - y_start) / y_step, ny - 4, wy)
        _add_patch(coef, cell_x, wx, cell_y, wy, out[i])
    return out


# --- coordinates -------------------------------------------------------------------------------

def _x_of_zeta(model, zeta):
    """Table coordinate x of the damping ratio (see module docstring)."""
    if model == "Ib":
        return np.log(zeta) - 0.5 * np.log1p(-zeta * zeta)
    return np.log(zeta)


def _zeta_of_x(model, x):
    """Inverse of :func:`_x_of_zeta`: ζ = eˣ/√(1 + e²ˣ) for Ib (no overflow for x < 350)."""
    if model == "Ib":
        return np.exp(x) / np.sqrt(1.0 + np.exp(2.0 * x))
    return np.exp(x)


def _y_of_s(s):
    """Table coordinate y = ln s + s of the log-distance s = ln(ṽ/ṽc) above capture."""
    return np.log(s) + s


def _s_of_y(y):
    """Inverse of :func:`_y_of_s`: s = W(eʸ) (principal Lambert W; used at build time only)."""
    return lambertw(np.exp(y)).real


# --- the tabulated fields ----------------------------------------------------------------------

def _root_capture(model):
    """Whether ε vanishes like √s at the critical speed (Ib, hybrid) rather than jumping (IIb)."""
    return model != "IIb"


def _fields_from_exact(model, result, vtilde, s):
    """Smooth table fields (last axis) from exact results at (ṽ, s = ln(ṽ/ṽc))."""
    logit = np.log(result.eps) - np.log(result.one_minus_eps)
    if _root_capture(model):
        logit = logit - 0.5 * np.log(s)
    fields = [logit, np.log(result.contact_time)]
    if model == "hybrid":
        fields.append(np.log(result.release_speed) - np.log(vtilde))
    return np.stack(fields, axis=-1)


@dataclass(frozen=True)
class Surrogate:
    """Tabulated solution of one gravity model at one accuracy level (see module docstring).

    Attributes
    ----------
    model, level : str
        Contact model and accuracy level.
    bound : float
        Certified relative error in ε, 1 − ε, contact time and release speed (and depth):
        SAFETY × the largest error found on ``n_certify`` independent random points.
    errors : dict
        Largest relative errors measured at certification, per quantity.
    params : dict
        Build parameters (domain, grid sizes, seeds); their hash names the cache file.
    x_start, x_step, y_start, y_step : float
        Uniform grid of the 2-D table (first node and spacing, margins included).
    coef : ndarray, shape (nx + 4, ny + 4, fields)
        B-spline coefficients of the tabulated fields.
    critical_start, critical_step : float
        Uniform grid of the 1-D table of ln ṽc(ζ) in x.
    critical_coef : ndarray
        Its B-spline coefficients.
    x_min, x_max, y_min, y_max : float
        Domain served by the table (inside the grid, which has margins).
    build_seconds : float
        Wall time of the build, certification included.
    path : str
        Cache file it was read from or written to ("" if not cached).
    nbytes : int
        Size of the tables in memory (bytes).
    """

    model: str
    level: str
    bound: float
    errors: dict
    params: dict
    x_start: float
    x_step: float
    y_start: float
    y_step: float
    coef: np.ndarray = field(repr=False)
    critical_start: float = 0.0
    critical_step: float = 1.0
    critical_coef: np.ndarray = field(default=None, repr=False)
    x_min: float = 0.0
    x_max: float = 0.0
    y_min: float = 0.0
    y_max: float = 0.0
    build_seconds: float = 0.0
    path: str = ""

    @property
    def nbytes(self):
        """Bytes held by the coefficient tables."""
        return int(self.coef.nbytes + self.critical_coef.nbytes)

    def log_critical(self, x):
        """Tabulated ln ṽc at table coordinate x (inside [x_min, x_max])."""
        return _evaluate_1d(self.critical_coef, self.critical_start, self.critical_step,
                            np.ascontiguousarray(x, dtype=float).ravel())

    def fields(self, x, y):
        """Tabulated fields at table coordinates (x, y): shape (n, fields)."""
        return _evaluate_2d(self.coef, self.x_start, self.x_step, self.y_start, self.y_step,
                            np.ascontiguousarray(x, dtype=float).ravel(),
                            np.ascontiguousarray(y, dtype=float).ravel())


# --- build -------------------------------------------------------------------------------------

def _build_params(model, level, overrides=None):
    """The parameters that fully determine a table (hashed into its cache file name)."""
    params = dict(LEVELS[level])
    params.update(overrides or {})
    params.update(model=model, level=level, format=FORMAT_VERSION, zeta_min=ZETA_MIN,
                  zeta_max=ZETA_MAX[model], vtilde_max=VTILDE_MAX, s_min=S_MIN,
                  margin=_MARGIN, safety=SAFETY, exact_rtol=EXACT_RTOL,
                  source=_physics_source())
    params.setdefault("seed", 20240601)
    return params


@functools.lru_cache(maxsize=1)
def _physics_source():
    """Digest of the physics code the tables are built and certified with (this folder's
    modules): between releases the solvers change under one version, and a table built by
    other code is rebuilt, not trusted."""
    from ..provenance import source_fingerprint

    return source_fingerprint(Path(__file__).resolve().parent)


def _params_hash(params):
    return hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()[:16]


def _package_version():
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("dashpot")
    except PackageNotFoundError:
        return "0+unknown"


def _grid(lower, upper, n):
    """n nodes spanning [lower, upper] plus _MARGIN on each side: (start, step, nodes)."""
    step = (upper - lower) / (n - 1)
    nodes = lower + step * np.arange(-_MARGIN, n + _MARGIN)
    return nodes[0], step, nodes


def _relative_errors(model, got, exact):
    """Largest relative errors of the surrogate's outputs against the exact ones (dict)."""
    def worst(a, b):
        return float(np.max(np.abs(a / b - 1.0))) if b.size else 0.0

    return {"eps": worst(got.eps, exact.eps),
            "one_minus_eps": worst(got.one_minus_eps, exact.one_minus_eps),
            "contact_time": worst(got.contact_time, exact.contact_time),
            "release_speed": worst(got.release_speed, exact.release_speed)}


def build_surrogate(model, level="fast", *, overrides=None):
    """Tabulate and certify the surrogate of one model at one level (no caching; see
    :func:`load_surrogate`).

    Parameters
    ----------
    model : {"Ib", "IIb", "hybrid"}
        Gravity model.
    level : {"fast", "standard"}
        Accuracy level (:data:`LEVELS`).
    overrides : dict, optional
        Replacement build parameters (``nx``, ``ny``, ``n_critical``, ``n_certify``, ``seed``),
        e.g. small tables for tests. They enter the cache hash.

    Returns
    -------
    Surrogate
        The table with its certified bound. Deterministic: the same parameters give the same
        numbers bit for bit.
    """
    model = check_model(model, SURROGATE_MODELS)
    level = check_model(level, tuple(LEVELS))
    params = _build_params(model, level, overrides)
    started = time.perf_counter()
    x_min, x_max = (float(v) for v in _x_of_zeta(model, np.array([ZETA_MIN, ZETA_MAX[model]])))

    # ln ṽc(ζ) on a fine 1-D grid: smooth in x, and its error shifts s, so it gets many nodes.
    c_start, c_step, c_nodes = _grid(x_min, x_max, params["n_critical"])
    log_vc_nodes = np.log(critical_velocity(model, _zeta_of_x(model, c_nodes)))
    critical_coef = _fit_coefficients(log_vc_nodes)

    # The s range reaches VTILDE_MAX at ζ_min, where ṽc is smallest (it grows with ζ).
    s_max = float(np.log(VTILDE_MAX) - log_vc_nodes[_MARGIN]) + 0.05
    y_min, y_max = float(_y_of_s(S_MIN)), float(_y_of_s(s_max))
    x_start, x_step, x_nodes = _grid(x_min, x_max, params["nx"])
    y_start, y_step, y_nodes = _grid(y_min, y_max, params["ny"])
    zeta_nodes = _zeta_of_x(model, x_nodes)
    s_nodes = _s_of_y(y_nodes)
    # Nodes sit at the exact critical speed times e^s; margin nodes in x need their own ṽc.
    log_vc_grid = np.log(critical_velocity(model, zeta_nodes))
    zeta_grid, s_grid = np.meshgrid(zeta_nodes, s_nodes, indexing="ij")
    vtilde_grid = np.exp(log_vc_grid[:, None] + s_grid)
    exact = collide(model, zeta_grid, vtilde_grid)
    if np.any(exact.captured):
        raise RuntimeError(f"{model}: exact solver captured on table nodes; widen S_MIN")
    coef = _fit_coefficients(_fields_from_exact(model, exact, vtilde_grid, s_grid))

    table = Surrogate(model=model, level=level, bound=np.inf, errors={}, params=params,
                      x_start=float(x_start), x_step=float(x_step), y_start=float(y_start),
                      y_step=float(y_step), coef=coef, critical_start=float(c_start),
                      critical_step=float(c_step), critical_coef=critical_coef,
                      x_min=x_min, x_max=x_max, y_min=y_min, y_max=y_max)
    errors = certify(table, params["n_certify"], params["seed"])
    bound = SAFETY * max(errors.values())
    return dataclasses.replace(table, bound=float(bound), errors=errors,
                    build_seconds=time.perf_counter() - started)


def certification_points(table, n, seed):
    """n random (ζ, ṽ) inside the table's domain, independent of its nodes.

    x uniform over the domain; y uniform over [y_min, y_max] (about a third of the points lie
    within s < 1 of the critical speed, the hardest part).
    """
    rng = np.random.default_rng([seed, n, SURROGATE_MODELS.index(table.model),
                                 list(LEVELS).index(table.level)])
    x = rng.uniform(table.x_min, table.x_max, n)
    y = rng.uniform(table.y_min, table.y_max, n)
    zeta = _zeta_of_x(table.model, x)
    # ṽ from the tabulated ṽc, so that every point lies in the domain as the table defines it.
    vtilde = np.exp(table.log_critical(x) + _s_of_y(y))
    return zeta, vtilde


def certify(table, n=200_000, seed=1):
    """Largest relative errors of `table` against the exact solver on n random domain points."""
    zeta, vtilde = certification_points(table, n, seed)
    got = _as_collision(table.model, _evaluate_surrogate(table, None, zeta, vtilde,
                                                         use_table_only=True), math.nan,
                        zeta.shape)
    exact = collide(table.model, zeta, vtilde)
    return _relative_errors(table.model, got, exact)


# --- cache -------------------------------------------------------------------------------------

class CacheWarning(RuntimeWarning):
    """The cache directory cannot be created, read or written: tables are kept in memory only."""


def _without_cache(directory, model, level, error):
    """Warn (one line) that a table is built and kept in memory because the cache failed."""
    reason = getattr(error, "strerror", None) or str(error).strip().splitlines()[0]
    warnings.warn(f"cannot use the surrogate cache {directory} ({reason}); the {model} "
                  f"{level} table is computed and kept in memory for this run only",
                  CacheWarning, stacklevel=3)


def cache_dir(directory=None):
    """Cache directory: `directory`, else $DASHPOT_CACHE_DIR, else the platform's user cache
    folder for dashpot from platformdirs (``~/.cache/dashpot`` on Linux or under
    $XDG_CACHE_HOME, ``~/Library/Caches/dashpot`` on macOS, ``%LOCALAPPDATA%\\dashpot\\Cache``
    on Windows)."""
    if directory is not None:
        return Path(directory)
    env = os.environ.get(_CACHE_ENV)
    return Path(env) if env else platformdirs.user_cache_path("dashpot", appauthor=False)


def _cache_path(directory, params):
    version = _package_version().replace("/", "_")
    return directory / (f"surrogate-{params['model']}-{params['level']}-v{version}-"
                        f"{_params_hash(params)}.npz")


_ARRAYS = ("coef", "critical_coef")
_SCALARS = ("x_start", "x_step", "y_start", "y_step", "critical_start", "critical_step",
            "x_min", "x_max", "y_min", "y_max", "bound", "build_seconds")


def _checksum(arrays):
    digest = hashlib.sha256()
    for name in _ARRAYS:
        array = np.ascontiguousarray(arrays[name], dtype="<f8")
        digest.update(name.encode() + str(array.shape).encode() + array.tobytes())
    return digest.hexdigest()


def _write(table, path):
    """Write atomically: a unique temporary file in the same directory, then os.replace.

    Replaces a file of the same name: the cache's own, stale or damaged (:func:`_read` found
    it unusable), or written by another process building the same table at the same time."""
    arrays = {name: getattr(table, name) for name in _ARRAYS}
    meta = {name: getattr(table, name) for name in _SCALARS}
    meta.update(model=table.model, level=table.level, errors=table.errors, params=table.params,
                hash=_params_hash(table.params), version=_package_version(),
                checksum=_checksum(arrays))
    # Through an open file: given a name without ".npz", np.savez would append one.
    with atomic_path(path, overwrite=True) as temporary, open(temporary, "wb") as stream:
        np.savez(stream, meta=np.array(json.dumps(meta)), **arrays)


def _read(path, params):
    """Table from `path` if it is intact and was built from `params`, else None."""
    try:
        # Open the file ourselves: np.load leaks its handle when a corrupt archive raises.
        with open(path, "rb") as stream, np.load(stream, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"][()]))
            arrays = {name: np.array(data[name], dtype=float) for name in _ARRAYS}
        if (meta["hash"] != _params_hash(params) or meta["params"] != params
                or meta["version"] != _package_version() or meta["checksum"] != _checksum(arrays)
                or not all(np.all(np.isfinite(a)) for a in arrays.values())
                or arrays["coef"].ndim != 3):
            return None
        scalars = {name: float(meta[name]) for name in _SCALARS}
        return Surrogate(model=meta["model"], level=meta["level"], errors=meta["errors"],
                         params=meta["params"], path=str(path), **arrays, **scalars)
    except Exception:  # noqa: BLE001 - any unreadable or inconsistent file is rebuilt, not trusted
        return None


def load_surrogate(model, level="fast", *, directory=None, overrides=None):
    """The surrogate of `model` at `level`: from memory, else from the disk cache, else built.

    Parameters
    ----------
    model : {"Ib", "IIb", "hybrid"}
    level : {"fast", "standard"}
    directory : path-like, optional
        Cache directory (default: $DASHPOT_CACHE_DIR, else the user cache folder; see
        :func:`cache_dir`).
    overrides : dict, optional
        Build parameters replacing the level's (see :func:`build_surrogate`).

    Returns
    -------
    Surrogate
        A file that is unreadable, fails its checksum, or was built with other parameters or
        another package version is rebuilt and replaced. If the cache directory cannot be
        created, read or written, the table is built and kept in memory only (``path`` "")
        with a :class:`CacheWarning`.
    """
    # Hot path (every surrogate_collide call): a dictionary look-up, no hashing or file access.
    quick = (model, level, None if directory is None else str(directory),
             os.environ.get(_CACHE_ENV), None if overrides is None else
             json.dumps(overrides, sort_keys=True))
    table = _LOADED.get(quick)
    if table is not None:
        return table
    model = check_model(model, SURROGATE_MODELS)
    level = check_model(level, tuple(LEVELS))
    params = _build_params(model, level, overrides)
    # A cache that cannot be used (no home folder, no permission, a file in the way, a full
    # disk) costs the build time, never the result.
    try:
        directory = cache_dir(directory)
        path = _cache_path(directory, params)
        table = _read(path, params) if path.exists() else None
    except (OSError, RuntimeError) as error:  # RuntimeError: Path.home() without a home
        _without_cache(directory or "~/.cache/dashpot", model, level, error)
        path = table = None
    if table is None:
        table = build_surrogate(model, level, overrides=overrides)
        if path is not None:
            try:
                _write(table, path)
            except OSError as error:
                _without_cache(directory, model, level, error)
            else:
                table = dataclasses.replace(table, path=str(path))
    _LOADED[quick] = table
    return table


def clear_memory_cache():
    """Forget the tables held in memory (the next load reads the disk cache)."""
    _LOADED.clear()


# --- evaluation --------------------------------------------------------------------------------

def _captured_fields(n, release_speed=None, zeta=None):
    """The exact solver's outputs where the ball is captured (release state as given, or none)."""
    speed = np.zeros(n) if release_speed is None else release_speed
    depth = np.full(n, -1.0) if release_speed is None else -2.0 * zeta * release_speed
    return dict(eps=np.zeros(n), one_minus_eps=np.ones(n), contact_time=np.full(n, np.inf),
                captured=np.ones(n, bool), release_depth=depth, release_speed=speed)


def _from_table(table, zeta, vtilde, x, s):
    """Outputs at points inside the table's domain, from the tabulated fields."""
    values = table.fields(x, _y_of_s(s))
    logit = values[:, 0]
    if _root_capture(table.model):
        logit = logit + 0.5 * np.log(s)
    eps = expit(logit)
    tau = np.exp(values[:, 1])
    if table.model == "hybrid":
        speed = vtilde * np.exp(values[:, 2])
        depth = -2.0 * zeta * speed
    else:
        speed = eps * vtilde
        depth = np.zeros(zeta.shape) if table.model == "Ib" else -2.0 * zeta * speed
    return dict(eps=eps, one_minus_eps=expit(-logit), contact_time=tau,
                captured=np.zeros(zeta.shape, bool), release_depth=depth, release_speed=speed)


def _classify(table, zeta, vtilde):
    """Per point: 0 table, 1 captured (well below ṽc), 2 exact solver; plus x and s."""
    x = np.full(zeta.shape, np.nan)
    s = np.full(zeta.shape, np.nan)
    status = np.full(zeta.shape, 2, np.int8)
    inside = (zeta >= ZETA_MIN) & (zeta <= ZETA_MAX[table.model])
    if table.model == "Ib":
        status[zeta >= 1.0] = 1  # over- and critically damped Ib never returns to ξ = 0
    if inside.any():
        xi = _x_of_zeta(table.model, zeta[inside])
        si = np.log(vtilde[inside]) - table.log_critical(xi)
        code = np.where((si >= S_MIN) & (_y_of_s(np.maximum(si, S_MIN)) <= table.y_max), 0,
                        np.where(si < -CAPTURE_BAND, 1, 2)).astype(np.int8)
        status[inside], x[inside], s[inside] = code, xi, si
    return status, x, s


def _evaluate_surrogate(table, release_table, zeta, vtilde, use_table_only=False):
    """Collision fields (dict of flat arrays) at (ζ, ṽ): table where possible, exact elsewhere."""
    n = zeta.size
    if use_table_only:
        x = _x_of_zeta(table.model, zeta)
        s = np.log(vtilde) - table.log_critical(x)
        return _from_table(table, zeta, vtilde, x, s)
    status, x, s = _classify(table, zeta, vtilde)
    out = {name: np.empty(n) for name in ("eps", "one_minus_eps", "contact_time",
                                          "release_depth", "release_speed")}
    out["captured"] = np.empty(n, bool)
    groups = [np.flatnonzero(status == code) for code in (0, 1, 2)]
    if groups[0].size == n:  # the common case: everything on the table
        return _from_table(table, zeta, vtilde, x, s)
    for code, index in enumerate(groups):
        if index.size == 0:
            continue
        z, v = zeta[index], vtilde[index]
        if code == 0:
            part = _from_table(table, z, v, x[index], s[index])
        elif code == 1 and release_table is None:
            part = _captured_fields(index.size)
        elif code == 1:
            part = _hybrid_captured(release_table, z, v)
        else:
            result = collide(table.model, z, v)
            part = {name: getattr(result, name) for name in out}
        for name, value in part.items():
            out[name][index] = value
    return out


def _hybrid_captured(iib, zeta, vtilde):
    """Hybrid points below its critical speed: captured, but released where IIb releases.

    Between IIb's critical speed and the hybrid's the force vanishes (release speed vf from the
    IIb table) but vf < 4ζ is too slow to climb back to z = R.
    """
    status, x, s = _classify(iib, zeta, vtilde)
    speed = np.zeros(zeta.size)
    on_table = np.flatnonzero(status == 0)
    if on_table.size:
        speed[on_table] = _from_table(iib, zeta[on_table], vtilde[on_table], x[on_table],
                                      s[on_table])["release_speed"]
    part = _captured_fields(zeta.size, speed, zeta)
    part["release_depth"] = np.where(status == 1, -1.0, part["release_depth"])
    exact = np.flatnonzero(status == 2)
    if exact.size:
        result = collide("hybrid", zeta[exact], vtilde[exact])
        for name in part:
            part[name][exact] = getattr(result, name)
    return part


def _as_collision(model, fields, rtol, shape):
    """A :class:`Collision` of the surrogate's flat field arrays, in the inputs' shape."""
    return Collision(model=model, method="surrogate", rtol=rtol,
                     **{name: value.reshape(shape) for name, value in fields.items()})


def surrogate_collide(model, zeta, vtilde, *, level="fast", directory=None):
    """:func:`dashpot.collide` from a precomputed, certified table (same inputs and outputs).

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
        Contact model. Ia and IIa are closed forms and are evaluated exactly.
    zeta : array_like
        Damping ratio ζ = β/ω0 (dimensionless), finite and >= 0.
    vtilde : array_like
        Impact speed ṽ = v0/v* with v* = g/ω0 (dimensionless), finite and > 0; broadcast
        against `zeta`.
    level : {"fast", "standard"}, default "fast"
        Table accuracy (:data:`LEVELS`): certified relative errors ≲ 1e-6 or ≲ 1e-9.
    directory : path-like, optional
        Cache directory of the tables (default $DASHPOT_CACHE_DIR, else the user cache
        folder; see :func:`cache_dir`).
        The first use of a model and level builds its table (seconds) and caches it.

    Returns
    -------
    Collision
        As from ``collide``, with ``method="surrogate"`` and ``rtol`` the table's certified
        bound on the relative error of ε, 1 − ε, contact time, release speed and depth (the
        exact bound for Ia and IIa). Capture flags are those of the exact solver. Points outside
        the table's domain, or within CAPTURE_BAND..S_MIN of the critical speed, are computed by
        the exact solver (bit for bit its values).

    Notes
    -----
    Domain: ZETA_MIN <= ζ <= ZETA_MAX[model] and S_MIN <= ln(ṽ/ṽc(ζ)) up to at least
    ṽ = VTILDE_MAX. See the module docstring for the coordinates and the certification.
    """
    model = check_model(model, MODELS)
    level = check_model(level, tuple(LEVELS))
    zeta = check_nonnegative("zeta", zeta)
    vtilde = check_positive("vtilde", vtilde)
    if model not in SURROGATE_MODELS:
        return dataclasses.replace(collide(model, zeta, vtilde), method="surrogate",
                                   rtol=EXACT_RTOL)
    table = load_surrogate(model, level, directory=directory)
    release_table = load_surrogate("IIb", level, directory=directory) if model == "hybrid" else None
    zeta, vtilde = np.broadcast_arrays(zeta, vtilde)
    shape = zeta.shape
    fields = _evaluate_surrogate(table, release_table, zeta.ravel(), vtilde.ravel())
    return _as_collision(model, fields, table.bound, shape)
