"""The Python API at the top of the package: `import dashpot` stays cheap, the public names
exist, are documented and typed, and `analyze`/`read_impacts`/`load_scene`/`fit_scene`,
`SceneFit.report()`, `SceneFit.parameters` and the reprs give what a user reads.
"""

import dataclasses
import inspect
import json
import subprocess
import sys

import numpy as np
import pytest

import dashpot
from dashpot.synth.scene import write_scene

# What `import dashpot` must not load: the scientific stack (seconds of import time between
# them, and numba's compiler); each is imported where a name that needs it is first used.
HEAVY = ("numpy", "scipy", "scipy.stats", "pandas", "numba", "lmfit", "matplotlib", "h5py",
         "soundfile", "emcee", "uncertainties", "yaml")
API = ("analyze", "read_impacts", "load_scene", "fit_scene")
# A soft ball whose 30 bounces determine β and k (seed picked once).
BALL = dict(model="hybrid", beta=8.0, omega0=800.0, g=9.80665, v0=1.5, n_max=30)
MODELS = ("Ia", "hybrid")


def _fresh(code):
    """Standard output of `code` run in a new interpreter."""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    return run.stdout


def test_import_dashpot_loads_no_heavy_module():
    code = (f"import sys, json, dashpot; dashpot.__version__; dashpot.__all__; "
            f"print(json.dumps([m for m in {list(HEAVY)!r} if m in sys.modules]))")
    assert json.loads(_fresh(code)) == []


def test_names_and_submodules_are_reached_lazily():
    """A public name imports only what it needs; `dashpot.physics` works after a bare
    `import dashpot` as it did when the package imported it eagerly."""
    code = ("import sys, json, dashpot; dashpot.load_scene; a = 'lmfit' in sys.modules; "
            "dashpot.physics.MODELS; dashpot.fit.fit_model; "
            "print(json.dumps([a, 'lmfit' in sys.modules]))")
    assert json.loads(_fresh(code)) == [False, True]


def test_unknown_attribute_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        dashpot.no_such_name  # noqa: B018
    assert not hasattr(dashpot, "_private")


def test_public_names_exist_and_are_documented():
    assert set(API) <= set(dashpot.__all__) <= set(dir(dashpot))
    for name in dashpot.__all__:
        value = getattr(dashpot, name)
        if callable(value):
            assert inspect.getdoc(value), f"dashpot.{name} has no docstring"
    assert dashpot.MODELS == ("Ia", "Ib", "IIa", "IIb", "hybrid")


@pytest.mark.parametrize("name", API)
def test_api_functions_are_typed_numpydoc(name):
    function = getattr(dashpot, name)
    signature = inspect.signature(function)
    unannotated = [parameter for parameter in signature.parameters.values()
                   if parameter.annotation is inspect.Parameter.empty]
    assert unannotated == [], f"dashpot.{name}: no type hint on {unannotated}"
    assert signature.return_annotation is not inspect.Signature.empty
    doc = inspect.getdoc(function)
    for section in ("Parameters\n----------", "Returns\n-------", "Raises\n------"):
        assert section in doc, f"dashpot.{name}: no {section.splitlines()[0]} section"
    for parameter in signature.parameters:
        assert f"\n{parameter} :" in doc, f"dashpot.{name}: {parameter} not documented"


@pytest.fixture(scope="module")
def scene_files(tmp_path_factory):
    """A synthetic recording and a scene.yaml for it that gives the ball's mass."""
    folder = tmp_path_factory.mktemp("api")
    recording = write_scene(folder, "audio", seed=2511, **BALL)
    scene = folder / "scene.yaml"
    scene.write_text(f"name: light-ball\nrecording: {recording.name}\nsensor: audio\n"
                     f"models: [{', '.join(MODELS)}]\n"
                     f"apparatus:\n  mass: {{value: 0.0027, uncertainty: 0.0001}}\n")
    return recording, scene


@pytest.fixture(scope="module")
def analyzed(scene_files):
    recording, scene = scene_files
    return dashpot.analyze(recording, scene)


def test_analyze_takes_a_scene_file_and_gives_the_steps_result(scene_files, analyzed):
    """analyze(recording, "scene.yaml") = fit_scene(read_impacts(recording), load_scene(...))."""
    recording, scene_path = scene_files
    impacts, scene_fit = analyzed
    scene = dashpot.load_scene(scene_path)
    assert isinstance(scene, dashpot.Scene) and scene.name == "light-ball"
    assert scene_fit.scene == scene and tuple(scene_fit.results) == MODELS
    read = dashpot.read_impacts(recording)
    np.testing.assert_array_equal(read["time"], impacts["time"])
    stepwise = dashpot.fit_scene(read, scene_path)
    for model in MODELS:
        assert stepwise.results[model].success
        for name in ("zeta", "beta", "k"):
            assert (stepwise.results[model].estimates[name].value
                    == scene_fit.results[model].estimates[name].value)


def test_bad_scene_path_is_one_input_error(scene_files, tmp_path):
    recording, _ = scene_files
    missing = tmp_path / "nowhere.yaml"
    with pytest.raises(dashpot.InputError, match="nowhere.yaml"):
        dashpot.analyze(recording, missing)


def test_report_is_the_printed_summary(analyzed):
    _, scene_fit = analyzed
    text = scene_fit.report()
    lines = text.splitlines()
    for model in MODELS:
        (line,) = [line for line in lines if line.strip().startswith(f"{model}:")]
        beta = scene_fit.results[model].estimates["beta"]
        assert "ζ = " in line and "β = " in line and "k = " in line and "χ²/ν" in line
        # β's printed value is the fit's, rounded to two digits of its error.
        printed = line.split("β = ")[1].split(" ± ")
        assert abs(float(printed[0].lstrip("(")) - beta.value) <= beta.stderr / 10
    assert any(line.strip().startswith("selection:") for line in lines)
    verbose = scene_fit.report(verbose=True)
    assert len(verbose.splitlines()) > len(lines)  # the notes on how each fit was made


def test_parameters_table(analyzed):
    _, scene_fit = analyzed
    table = scene_fit.parameters
    assert list(table.columns) == ["model", "parameter", "value", "stderr", "low68", "high68",
                                   "low95", "high95", "unit", "status", "note"]
    for model in MODELS:
        rows = table[table["model"] == model].set_index("parameter")
        estimates = scene_fit.results[model].estimates
        assert set(rows.index) == set(estimates)
        for name in ("beta", "k", "zeta"):
            assert rows.loc[name, "value"] == estimates[name].value
            assert rows.loc[name, "unit"] == estimates[name].unit
            assert rows.loc[name, "low95"] <= rows.loc[name, "low68"] <= rows.loc[name, "value"]
            assert rows.loc[name, "value"] <= rows.loc[name, "high68"] <= rows.loc[name, "high95"]
    assert table.loc[table["parameter"] == "k", "unit"].eq("N/m").all()


def test_reprs_are_one_short_line(analyzed):
    impacts, scene_fit = analyzed
    text = repr(scene_fit)
    assert "\n" not in text and len(text) < 160
    assert "'light-ball'" in text and f"{len(impacts)} impacts" in text
    assert f"fitted {', '.join(MODELS)}" in text
    fit = scene_fit.results["hybrid"]
    text = repr(fit)
    assert text.startswith("<FitResult hybrid: ζ = ") and "\n" not in text and len(text) < 200
    # ω0 unbounded above: β and k are said not to be determined, without the bound.
    omega0 = dataclasses.replace(fit.estimates["omega0"], high95=np.inf)
    loose = dataclasses.replace(fit, estimates={**fit.estimates, "omega0": omega0})
    assert "β not determined (" in dashpot.fit_report.fit_line(loose)
    text = repr(loose)
    assert "β not determined, k not determined, ε " in text and len(text) < 200
    failed = dataclasses.replace(fit, success=False,
                                 message="fit failed: captured before the last impact")
    assert repr(failed) == "<FitResult hybrid: failed: captured before the last impact>"
    results = {**scene_fit.results, "hybrid": failed}
    assert "failed hybrid" in repr(dataclasses.replace(scene_fit, results=results))
