"""The HDF5 scene file: documented layout, units everywhere, plain-h5py tables, reproducible
numbers, atomic writes, and failed fits stored as such."""

import hashlib
import json
import re
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

import dashpot.fit.model_fit
import dashpot.store
from dashpot import __version__
from dashpot.analysis import scene_impacts
from dashpot.fit import SceneFit, fit_model, fit_scene, prepare_data
from dashpot.provenance import source_fingerprint
from dashpot.scene import Known, Scene
from dashpot.select import selection_table, summary_table
from dashpot.store import (
    FORMAT,
    atomic_path,
    file_sha256,
    read_fit,
    read_table,
    write_scene_fit,
    write_summary,
)
from dashpot.synth.scene import write_scene
from dashpot.truth import truth_comparison

MODELS = ("Ia", "IIb")
DOCS = Path(__file__).resolve().parents[1] / "docs" / "hdf5-layout.md"


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """One scene analysed twice from scratch, each written to its own file."""
    folder = tmp_path_factory.mktemp("store")
    recording = write_scene(folder / "ball", "timestamps", model="IIb", beta=30, omega0=3000,
                            g=9.81, v0=1.5, n_max=30, seed=1)
    scene = Scene(name="ball", sensor="timestamps", models=MODELS, gravity=9.81,
                  mass=Known(0.05, 0.001))
    paths, fits = [], []
    for copy in ("first", "second"):
        # From scratch each time; the number of evaluations is capped to keep this quick
        # (how well the models fit does not matter here).
        with np.errstate(over="raise", divide="raise", invalid="raise", under="ignore"):
            impacts = scene_impacts(recording, scene)
            data = prepare_data(impacts, scene)
            results = {model: fit_model(data, model, scene, max_nfev=300) for model in MODELS}
        selection, verdict = selection_table(results)
        scene_fit = SceneFit(scene=scene, data=data, results=results, selection=selection,
                             verdict=verdict)
        path = folder / copy / "fit.h5"
        write_scene_fit(path, scene_fit, impacts, input_path=recording,
                        config={"models": list(MODELS), "copy": "same"})
        paths.append(path)
        fits.append((impacts, scene_fit))
    return {"recording": recording, "scene": scene, "path": paths[0], "again": paths[1],
            "impacts": fits[0][0], "scene_fit": fits[0][1]}


def _datasets(path):
    """Every dataset of a file: name -> (value, attributes)."""
    found = {}
    with h5py.File(path, "r") as source:
        def visit(name, item):
            if isinstance(item, h5py.Dataset):
                found[name] = (item[()], dict(item.attrs))
        source.visititems(visit)
    return found


def _groups(path):
    """Every group of a file: name -> attributes (the root as "/")."""
    found = {}
    with h5py.File(path, "r") as source:
        found["/"] = dict(source.attrs)

        def visit(name, item):
            if isinstance(item, h5py.Group):
                found[name] = dict(item.attrs)
        source.visititems(visit)
    return found


def _plain_table(group):
    """A table group read with h5py and pandas only (as in docs/hdf5-layout.md)."""
    return pd.DataFrame({c: group[c].asstr()[()] if h5py.check_string_dtype(group[c].dtype)
                         else group[c][()] for c in group.attrs["columns"]})


def test_root_attributes_and_provenance(written):
    with h5py.File(written["path"], "r") as source:
        attrs = dict(source.attrs)
    assert attrs["format"] == FORMAT == "dashpot-scene-1"
    assert attrs["dashpot_version"] == __version__
    assert attrs["dashpot_source_sha256"] == source_fingerprint()
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", attrs["created"])
    assert attrs["input_file"] == "timestamps.csv"
    digest = hashlib.sha256(written["recording"].read_bytes()).hexdigest()
    assert attrs["input_sha256"] == digest == file_sha256(written["recording"])
    scene = json.loads(attrs["scene"])
    assert scene == json.loads(json.dumps(written["scene"].as_dict()))
    assert scene["mass"] == {"value": 0.05, "uncertainty": 0.001}
    assert scene["driving_acceleration"] == 9.81
    assert json.loads(attrs["config"]) == {"models": list(MODELS), "copy": "same"}
    assert attrs["verdict"] == written["scene_fit"].verdict


def test_documented_groups_and_datasets(written):
    groups = _groups(written["path"])
    datasets = _datasets(written["path"])
    expected_groups = {"/", "impacts", "bounces", "selection", "fits"}
    for model in MODELS:
        expected_groups |= {f"fits/{model}", f"fits/{model}/parameters",
                            f"fits/{model}/residuals", f"fits/{model}/predicted",
                            f"fits/{model}/intervals",
                            f"fits/{model}/eps_curve"}
    assert set(groups) == expected_groups
    for table in ("impacts", "bounces", "selection") + tuple(
            f"fits/{m}/parameters" for m in MODELS):
        columns = list(groups[table]["columns"])
        assert columns and all(f"{table}/{c}" in datasets for c in columns)
        lengths = {datasets[f"{table}/{c}"][0].shape for c in columns}
        assert len(lengths) == 1  # one row count per table
    assert "impacts/used_in_fit" in datasets
    for model in MODELS:
        assert {f"fits/{model}/{name}" for name in (
            "correlation", "residuals/time", "residuals/normalized", "predicted/times",
            "predicted/speeds", "predicted/restitution", "predicted/contact_durations",
            "predicted/at_data", "eps_curve/speed", "eps_curve/eps", "eps_curve/captured")
                } <= set(datasets)
        attrs = groups[f"fits/{model}"]
        assert {"success", "message", "chisqr", "redchi", "aic", "bic", "ndata", "nvarys",
                "nfev", "numerical_tolerance", "error_bound", "varied", "notes"} <= set(attrs)
    # The documentation lists exactly these items, with these units, in column order.
    documented = _documented_tree()
    found = {"/": None}
    for name in groups:
        if name != "/":
            found[_generic(name) + "/"] = None
    for name, (values, attrs) in datasets.items():
        found[_generic(name)] = (attrs["units"], _type_name(values.dtype, attrs))
    assert found == documented
    for table in ("impacts", "bounces", "selection", "fits/IIb/parameters"):
        listed = [path.rsplit("/", 1)[-1] for path in documented
                  if path.startswith(f"{_generic(table)}/") and not path.endswith("/")]
        assert [c for c in listed if c != "used_in_fit"] == list(groups[table]["columns"])
    text = DOCS.read_text()
    for attrs in groups.values():
        for key in attrs:
            assert f"`{key}`" in text, key


def _generic(name):
    """HDF5 path with the model replaced by <model>, as the documentation writes it."""
    parts = name.split("/")
    if parts[0] == "fits" and len(parts) > 1:
        parts[1] = "<model>"
    return "/" + "/".join(parts)


def _type_name(dtype, attrs):
    """The type's name as docs/hdf5-layout.md writes it (string, bool, float64, int64, or
    dimension for a netCDF dimension without data, known by its scale name)."""
    if bytes(attrs.get("NAME", b"")).startswith(b"This is a netCDF dimension but not"):
        return "dimension"
    if h5py.check_string_dtype(dtype):
        return "string"
    return "bool" if dtype == bool else dtype.name


def _parse_tree(block):
    """path -> (unit, type) (None for groups) of a text block of docs/hdf5-layout.md."""
    tree = {}
    for line in block.splitlines():
        path, _, rest = line.partition(" ")
        rest = rest.strip()
        if path.endswith("/"):
            tree[path] = None
            continue
        unit = "see column 'unit'" if rest.startswith("see column") else rest.split()[0]
        tree[path] = (unit, rest[len(unit):].split()[0])
    return tree


def _documented_tree():
    """path -> (unit, type) (None for groups) from the first text block of the layout."""
    return _parse_tree(re.search(r"```text\n(.*?)```", DOCS.read_text(), flags=re.S).group(1))


def _truth_tree():
    """path -> (unit, type) of the `truth` section's text block."""
    section = DOCS.read_text().split("## `truth`", 1)[1].split("\n## ", 1)[0]
    return _parse_tree(re.search(r"```text\n(.*?)```", section, flags=re.S).group(1))


def test_truth_table_is_stored_as_documented(written, tmp_path):
    """A synthetic scene's truth against fit: the `truth` group of the layout's own section,
    read back by read_fit, and absent from files written without it."""
    truth_json = written["recording"].parent / "truth.json"
    table = truth_comparison(truth_json, written["scene_fit"])
    path = tmp_path / "truth.h5"
    write_scene_fit(path, written["scene_fit"], written["impacts"], truth=table)
    datasets = _datasets(path)
    found = {_generic(name): (attrs["units"], _type_name(values.dtype, attrs))
             for name, (values, attrs) in datasets.items() if name.startswith("truth/")}
    documented = _truth_tree()
    assert found == {path: item for path, item in documented.items() if item is not None}
    with h5py.File(path, "r") as source:
        assert list(source["truth"].attrs["columns"]) == [
            p.rsplit("/", 1)[1] for p in documented if not p.endswith("/")]
        assert source["truth"].attrs["model"] == "IIb"
        assert source["truth"].attrs["source"] == "truth.json"
    stored = read_fit(path)["truth"]
    pd.testing.assert_frame_equal(stored, table)
    assert stored.attrs == {"model": "IIb", "source": "truth.json"}
    # The scene's generator (write_scene above): β = 30 1/s, ω0 = 3000 rad/s, v0 = 1.5 m/s.
    truths = stored.set_index("parameter")["truth"]
    assert truths.to_dict() == pytest.approx({"beta": 30, "omega0": 3000, "zeta": 0.01,
                                              "v0": 1.5})
    assert "truth" not in read_fit(written["path"])


def test_every_dataset_has_a_unit(written):
    datasets = _datasets(written["path"])
    assert len(datasets) > 50
    allowed = {"1", "s", "m/s", "rad/s", "1/s", "see column 'unit'"}
    for name, (_, attrs) in datasets.items():
        # CF's attribute name only: nothing reads a second spelling.
        assert "units" in attrs and "unit" not in attrs, name
        assert attrs["units"] in allowed, (name, attrs["units"])
    assert datasets["impacts/time"][1]["units"] == "s"
    assert datasets["bounces/rebound_speed"][1]["units"] == "m/s"
    assert datasets["fits/IIb/predicted/contact_durations"][1]["units"] == "s"
    assert datasets["fits/IIb/eps_curve/speed"][1]["units"] == "m/s"


def test_every_nan_column_says_why_in_a_note(written, tmp_path):
    # An audio recording's table: times, their σ and loudness, no speeds (as the audio reader
    # gives it); the bounce table's last ratio has no next interval.
    impacts = written["impacts"].assign(amplitude=0.5)
    path = tmp_path / "audio.h5"
    write_scene_fit(path, written["scene_fit"], impacts)
    datasets = _datasets(path)
    for name, (values, attrs) in datasets.items():
        if name.split("/")[0] in ("impacts", "bounces") and values.dtype.kind == "f":
            # A note exactly where a column holds NaN.
            assert ("note" in attrs) == bool(np.isnan(values).any()), name
    for column in ("impact_speed", "rebound_speed", "speed_uncertainty"):
        values, attrs = datasets[f"impacts/{column}"]
        assert np.isnan(values).all()
        assert attrs["note"].startswith("all NaN: the recording gives impact times only")
    values, attrs = datasets["bounces/restitution"]
    assert np.isnan(values[-1]) and np.isfinite(values[:-1]).all()
    assert attrs["note"] == ("NaN on the last interval of each run: there is no next "
                             "interval T_{n+1}")
    assert "note" not in datasets["impacts/amplitude"][1]
    assert "note" not in datasets["impacts/time"][1]


def test_tables_read_back_with_plain_h5py_and_pandas(written):
    impacts, scene_fit = written["impacts"], written["scene_fit"]
    with h5py.File(written["path"], "r") as source:
        stored_impacts = _plain_table(source["impacts"])
        bounces = _plain_table(source["bounces"])
        selection = _plain_table(source["selection"])
        used = source["impacts/used_in_fit"][()]
        notes = json.loads(source["impacts"].attrs["notes"])
    pd.testing.assert_frame_equal(stored_impacts, impacts.reset_index(drop=True))
    # Impact times bit for bit.
    assert np.array_equal(stored_impacts["time"].to_numpy().view(np.uint64),
                          impacts["time"].to_numpy().view(np.uint64))
    pd.testing.assert_frame_equal(bounces, scene_fit.data.bounces.reset_index(drop=True))
    pd.testing.assert_frame_equal(selection, scene_fit.selection)
    assert used.dtype == bool and used.all() and used.size == len(impacts)
    assert notes == list(impacts.attrs["notes"])
    # read_table gives the same tables.
    with h5py.File(written["path"], "r") as source:
        pd.testing.assert_frame_equal(read_table(source["selection"]), selection)


def test_fits_read_back(written):
    scene_fit = written["scene_fit"]
    stored = read_fit(written["path"])
    assert set(stored["fits"]) == set(MODELS)
    for model, fit in scene_fit.results.items():
        group = stored["fits"][model]
        assert group["attrs"]["success"] == fit.success
        assert group["attrs"]["message"] == fit.message
        assert group["attrs"]["chisqr"] == fit.chisqr and group["attrs"]["aic"] == fit.aic
        assert json.loads(group["attrs"]["varied"]) == list(fit.varied)
        assert json.loads(group["attrs"]["notes"]) == list(fit.notes)
        parameters = group["parameters"]
        assert list(parameters.index) == list(fit.estimates)
        if fit.estimates:
            assert {"k", "gamma"} <= set(parameters.index)  # the scene gives the mass
        for name, estimate in fit.estimates.items():
            row = parameters.loc[name]
            assert (row["value"], row["stderr"], row["low95"], row["high95"]) == (
                estimate.value, estimate.stderr, estimate.low95, estimate.high95)
            assert (row["unit"], row["status"], row["note"]) == (
                estimate.unit, estimate.status, estimate.note)
        np.testing.assert_array_equal(group["correlation"], fit.correlation)
        np.testing.assert_array_equal(group["residuals"]["time"], fit.time_residuals)
        np.testing.assert_array_equal(group["residuals"]["normalized"],
                                      fit.normalized_residuals)
        assert set(group["predicted"]) == set(fit.predicted)
        for name, values in fit.predicted.items():
            np.testing.assert_array_equal(group["predicted"][name], values)
        for name, values in fit.eps_curve.items():
            np.testing.assert_array_equal(group["eps_curve"][name], values)
    parameters = stored["fits"]["IIb"]["parameters"]
    assert parameters.loc["beta", "unit"] == "1/s" and parameters.loc["k", "unit"] == "N/m"


def test_same_inputs_give_bit_identical_numbers(written):
    first, second = _datasets(written["path"]), _datasets(written["again"])
    assert set(first) == set(second)
    for name, (values, attrs) in first.items():
        other, other_attrs = second[name]
        assert values.dtype == other.dtype and values.shape == other.shape, name
        if values.dtype.kind == "f":
            assert np.array_equal(values.view(np.uint64), other.view(np.uint64)), name
        else:
            assert np.array_equal(values, other), name
        assert attrs.keys() == other_attrs.keys()
        # The dimension-scale bookkeeping holds object references, which differ per file.
        for key in set(attrs) - {"DIMENSION_LIST", "REFERENCE_LIST"}:
            assert np.array_equal(attrs[key], other_attrs[key]), (name, key)
    groups, other_groups = _groups(written["path"]), _groups(written["again"])
    for name, attrs in groups.items():
        keys = set(attrs) - ({"created"} if name == "/" else set())
        assert keys == set(other_groups[name]) - ({"created"} if name == "/" else set())
        for key in keys:
            a, b = np.asarray(attrs[key]), np.asarray(other_groups[name][key])
            if a.dtype.kind == "f":
                assert np.array_equal(a.view(np.uint64), b.view(np.uint64)), (name, key)
            else:
                assert np.array_equal(a, b), (name, key)


def test_failed_write_leaves_no_file_and_keeps_an_old_one(written, tmp_path, monkeypatch):
    scene_fit, impacts = written["scene_fit"], written["impacts"]
    target = tmp_path / "fit.h5"
    real = dashpot.store._write_fit
    seen = []

    def broken(group, fit):
        real(group, fit)
        seen.append(bool(list(tmp_path.glob(".fit.h5.*.partial"))))
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(dashpot.store, "_write_fit", broken)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_scene_fit(target, scene_fit, impacts)
    assert seen == [True]  # it failed midway, with the file open
    assert list(tmp_path.iterdir()) == []
    # An existing output that may be replaced is left exactly as it was.
    target.write_bytes(b"previous result")
    with pytest.raises(RuntimeError):
        write_scene_fit(target, scene_fit, impacts, overwrite=True)
    assert target.read_bytes() == b"previous result"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fit.h5"]
    # Once the fault is gone the old file is replaced by a complete one.
    monkeypatch.setattr(dashpot.store, "_write_fit", real)
    write_scene_fit(target, scene_fit, impacts, overwrite=True)
    assert read_fit(target)["attrs"]["format"] == FORMAT
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fit.h5"]


def test_atomic_path(tmp_path):
    target = tmp_path / "sub" / "out.txt"
    with pytest.raises(KeyError):
        with atomic_path(target) as temporary:
            temporary.write_text("half")
            raise KeyError("stop")
    assert not target.exists() and list((tmp_path / "sub").iterdir()) == []
    with atomic_path(target) as temporary:
        assert temporary.parent == target.parent and temporary != target
        temporary.write_text("whole")
        assert not target.exists()
    assert target.read_text() == "whole" and list((tmp_path / "sub").iterdir()) == [target]


def _failing(monkeypatch, models):
    """Make the fits of `models` fail the way a numerical breakdown does."""
    real = dashpot.fit.model_fit._fit

    def fit(data, model, scene, notes, *args):
        if model in models:
            raise ArithmeticError(f"{model} blew up")
        return real(data, model, scene, notes, *args)

    monkeypatch.setattr(dashpot.fit.model_fit, "_fit", fit)


def test_failed_fit_is_stored_as_failed(written, tmp_path, monkeypatch):
    scene_fit, impacts = written["scene_fit"], written["impacts"]
    _failing(monkeypatch, {"Ib"})
    failed = fit_model(scene_fit.data, "Ib", scene_fit.scene)
    assert not failed.success
    results = {**scene_fit.results, "Ib": failed}
    selection, verdict = selection_table(results)
    mixed = SceneFit(scene=scene_fit.scene, data=scene_fit.data, results=results,
                     selection=selection, verdict=verdict)
    path = tmp_path / "mixed.h5"
    write_scene_fit(path, mixed, impacts)
    stored = read_fit(path)
    attrs = stored["fits"]["Ib"]["attrs"]
    assert not attrs["success"] and attrs["message"] == "fit failed: Ib blew up"
    assert attrs["chisqr"] == np.inf and attrs["nvarys"] == 0
    assert "fit failed: Ib blew up" in json.loads(attrs["notes"])
    assert stored["fits"]["Ib"]["parameters"].empty
    assert stored["fits"]["Ib"]["correlation"].shape == (0, 0)
    # Same layout as a successful fit, with nothing predicted.
    predicted, curve = stored["fits"]["Ib"]["predicted"], stored["fits"]["Ib"]["eps_curve"]
    assert set(predicted) == {"times", "speeds", "restitution", "contact_durations", "at_data"}
    assert all(predicted[name].size == 0 for name in predicted if name != "at_data")
    assert np.isnan(predicted["at_data"]).all()
    assert set(curve) == {"speed", "eps", "captured"} and all(v.size == 0 for v in curve.values())
    assert np.isnan(stored["fits"]["Ib"]["residuals"]["time"]).all()
    row = stored["selection"].set_index("model").loc["Ib"]
    assert not row["success"] and row["aic"] == np.inf and row["rank"] == 0
    assert row["akaike_weight"] == 0
    assert stored["attrs"]["verdict"] == verdict
    with h5py.File(path, "r") as source:
        # The empty parameter table keeps numeric columns numeric, with their units.
        table = source["fits/Ib/parameters"]
        assert table["value"].dtype == np.float64 and table["value"].shape == (0,)
        assert table["value"].attrs["units"] == "see column 'unit'"
        assert h5py.check_string_dtype(table["name"].dtype)


def test_used_in_fit_marks_the_fitted_run_and_spurious_impacts(written, tmp_path, monkeypatch):
    """Two runs side by side, sorted by time, and one false impact in the first run."""
    times = written["impacts"]["time"].to_numpy()[:12]
    first = np.insert(times, 6, times[5] + 0.3 * (times[6] - times[5]))
    impacts = pd.concat([pd.DataFrame({"time": first, "time_uncertainty": 1e-6, "run": 0}),
                         pd.DataFrame({"time": times[:8] + 0.01, "time_uncertainty": 1e-6,
                                       "run": 1})])
    impacts = impacts.sort_values("time", kind="stable").reset_index(drop=True)
    _failing(monkeypatch, {"Ia"})  # no fitting needed to check the bookkeeping
    scene_fit = fit_scene(impacts, Scene(), models=("Ia",))
    assert list(scene_fit.data.excluded) == [6]
    path = tmp_path / "runs.h5"
    write_scene_fit(path, scene_fit, impacts)
    with h5py.File(path, "r") as source:
        used = source["impacts/used_in_fit"][()]
        run = source["impacts/run"][()]
        stored_times = source["impacts/time"][()]
    spurious = stored_times == first[6]
    assert spurious.sum() == 1
    np.testing.assert_array_equal(used, (run == 0) & ~spurious)
    assert used.sum() == len(scene_fit.data.times) == 12
    np.testing.assert_array_equal(stored_times[used], scene_fit.data.times)


def test_write_summary(written, tmp_path):
    summary = summary_table({"ball": written["scene_fit"]})
    write_summary(tmp_path / "summary.h5", tmp_path / "summary.csv", summary)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.csv", "summary.h5"]
    with h5py.File(tmp_path / "summary.h5", "r") as source:
        assert source.attrs["format"] == "dashpot-summary-1"
        table = source["summary"]
        assert all("units" in table[c].attrs for c in table.attrs["columns"])
        assert table["beta"].attrs["units"] == "1/s" and table["k"].attrs["units"] == "N/m"
        pd.testing.assert_frame_equal(_plain_table(table), summary)
    csv = pd.read_csv(tmp_path / "summary.csv")
    # The CSV's headers carry the units; dimensionless and text columns keep bare names.
    expected = {"beta": "beta [1/s]", "beta_stderr": "beta_stderr [1/s]", "k": "k [N/m]",
                "omega0": "omega0 [rad/s]", "v0": "v0 [m/s]", "sigma_j": "sigma_j [s]",
                "zeta": "zeta", "model": "model", "sigma_eps": "sigma_eps"}
    headers = dict(zip(summary.columns, csv.columns))
    assert {column: headers[column] for column in expected} == expected
    assert len(csv.columns) == len(summary.columns) and len(csv) == len(MODELS)
    np.testing.assert_allclose(csv["beta [1/s]"], summary["beta"], rtol=1e-9)


def test_object_columns_are_stored_by_what_they_hold(tmp_path):
    """A column pandas holds as objects is stored as numbers when it holds numbers and None
    (never the text "nan"), as bool when it holds booleans, as text otherwise (missing text
    as the empty string, never "None" or "nan")."""
    table = pd.DataFrame({"scene": ["a", "b", "c"],
                          "beta": pd.Series([None, 2.5, np.nan], dtype=object),
                          "success": pd.Series([True, np.False_, False], dtype=object),
                          "problem": pd.Series(["x", None, np.nan], dtype=object)})
    write_summary(tmp_path / "s.h5", tmp_path / "s.csv", table)
    with h5py.File(tmp_path / "s.h5", "r") as source:
        group = source["summary"]
        assert group["beta"].dtype == np.float64
        assert np.isnan(group["beta"][0]) and group["beta"][1] == 2.5
        assert group["success"].dtype == bool and list(group["success"][()]) == [1, 0, 0]
        assert h5py.check_string_dtype(group["problem"].dtype)
        assert list(group["problem"].asstr()[()]) == ["x", "", ""]  # missing text is empty


def test_documented_example_reads_the_file(written, tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", DOCS.read_text(), flags=re.S)
    assert len(blocks) == 1
    code = blocks[0]
    assert 'h5py.File("fit.h5"' in code and len(code.strip().splitlines()) <= 6
    (tmp_path / "fit.h5").write_bytes(written["path"].read_bytes())
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(code, str(DOCS), "exec"), namespace)
    scene_fit = written["scene_fit"]
    pd.testing.assert_frame_equal(namespace["impacts"], written["impacts"])
    pd.testing.assert_frame_equal(namespace["selection"], scene_fit.selection)
    assert namespace["verdict"] == scene_fit.verdict
    parameters = namespace["parameters"]
    assert set(parameters) == set(MODELS)
    beta = parameters["IIb"].loc["beta", ["value", "stderr", "unit"]]
    assert beta["value"] == scene_fit.results["IIb"].estimates["beta"].value
    assert beta["unit"] == "1/s"
