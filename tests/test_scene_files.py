"""The scene files of the workflow's default synthetic scenes as a user opens them: every
dataset of the documented type (numbers as float64, never text), every table a netCDF-style
group that xarray opens with a named dimension, and the truth against the fit with pulls
checked independently (truth from config/config.yaml, fit from the file).

The scenes are built as the workflow's simulate and fit rules build them (the same library
calls), without Snakemake, so this runs in seconds; tests/test_workflow.py checks the files of
a real workflow run.
"""

import json
import re
import warnings
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest
import yaml

from dashpot.analysis import analyze
from dashpot.pipeline import workflow_scene, write_synthetic_scene
from dashpot.store import csv_header, write_scene_fit, write_summary
from dashpot.summary import summary_from_files
from dashpot.truth import truth_comparison

xarray = pytest.importorskip("xarray")
pytest.importorskip("h5netcdf")

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs" / "hdf5-layout.md"
SCENES = yaml.safe_load((REPO / "config" / "config.yaml").read_text(encoding="utf-8"))[
    "synthetic"]
TABLES = ("impacts", "bounces", "selection", "truth")


@pytest.fixture(scope="module")
def scene_files(tmp_path_factory):
    """Every default synthetic scene simulated and fitted into results/<scene>.h5, and the
    summary of them all."""
    results = tmp_path_factory.mktemp("results")
    paths = {}
    for name, spec in SCENES.items():
        folder = results / "synthetic" / name
        scene = workflow_scene(name, scene_file=write_synthetic_scene(folder, spec, name=name))
        impacts, scene_fit = analyze(scene.recording, scene)
        paths[name] = results / f"{name}.h5"
        write_scene_fit(paths[name], scene_fit, impacts, input_path=scene.recording,
                        truth=truth_comparison(folder / "truth.json", scene_fit))
    summary = summary_from_files(list(paths.values()))
    write_summary(results / "summary.h5", results / "summary.csv", summary)
    return {"paths": paths, "summary": summary, "summary_h5": results / "summary.h5",
            "summary_csv": results / "summary.csv"}


def _type_name(dataset):
    """A dataset's type as the layout writes it; `dimension` for a netCDF dimension."""
    if bytes(dataset.attrs.get("NAME", b"")).startswith(b"This is a netCDF dimension but not"):
        return "dimension"
    if h5py.check_string_dtype(dataset.dtype):
        return "string"
    return "bool" if dataset.dtype == bool else dataset.dtype.name


def _documented_types():
    """Generic path -> type of every text block of the layout's dataset listings."""
    types = {}
    for block in re.findall(r"```text\n(.*?)```", DOCS.read_text(encoding="utf-8"), flags=re.S):
        for line in block.splitlines():
            path, _, rest = line.partition(" ")
            if path.endswith("/"):
                continue
            rest = rest.strip()
            unit = "see column 'unit'" if rest.startswith("see column") else rest.split()[0]
            types[path] = rest[len(unit):].split()[0]
    return types


def _generic(name):
    parts = name.split("/")
    if parts[0] == "fits" and len(parts) > 1:
        parts[1] = "<model>"
    if parts[0] == "noise_fits" and len(parts) > 1:
        parts[1] = "<law>"
    # A motion reader's shared speed errors: one column per shared component j.
    parts[-1] = re.sub(r"_speed_shared_\d+$", "_speed_shared_<j>", parts[-1])
    return "/" + "/".join(parts)


def test_every_dataset_has_its_documented_type(scene_files):
    documented = _documented_types()
    assert {"float64", "int64", "bool", "string", "dimension"} >= set(documented.values())
    seen = set()
    for name, path in scene_files["paths"].items():
        with h5py.File(path, "r") as source:
            found = {}
            source.visititems(lambda item, obj: found.update(
                {item: _type_name(obj)} if isinstance(obj, h5py.Dataset) else {}))
        for item, dtype in found.items():
            generic = _generic(item)
            assert generic in documented, f"{name}.h5: {item} is not documented"
            assert dtype == documented[generic], (name, item, dtype, documented[generic])
            seen.add(generic)
    # The audio scene's unmeasured speeds are numbers (NaN), not the text "nan".
    with h5py.File(scene_files["paths"]["light-ball-audio"], "r") as source:
        for column in ("impact_speed", "rebound_speed", "speed_uncertainty"):
            assert source["impacts"][column].dtype == np.float64
            assert np.isnan(source["impacts"][column][()]).all()
    assert "/truth/pull" in seen and "/impacts/impact_speed" in seen


def _open(path, group):
    """xarray's dataset of one group, failing on any warning (e.g. invented dimensions)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return xarray.open_dataset(path, engine="h5netcdf", group=group).load()


def test_every_table_opens_in_xarray_with_a_named_dimension(scene_files):
    scales = {"impacts": "time", "bounces": "bounce", "selection": "model", "truth": "parameter",
              "parameters": "name", "intervals": "method"}
    for name, path in scene_files["paths"].items():
        with h5py.File(path, "r") as source:
            # Every model's tables in the audio scene, the generating model's elsewhere (each
            # opening costs a tenth of a second).
            models = list(source["fits"]) if name == "light-ball-audio" else [
                SCENES[name]["model"]]
            groups = [*TABLES, *(f"fits/{m}/{t}" for m in models
                                 for t in ("parameters", "intervals"))]
            tables = {group: (list(source[group].attrs["columns"]),
                              len(source[group][source[group].attrs["columns"][0]]))
                      for group in groups}
        for group, (columns, rows) in tables.items():
            dimension = scales[group.rsplit("/", 1)[-1]]
            dataset = _open(path, group)
            assert dict(dataset.sizes) == {dimension: rows}, (name, group)
            extra = {"used_in_fit"} if group == "impacts" else set()
            assert set(dataset.variables) == set(columns) | extra, (name, group)
            assert all(dataset[c].dims == (dimension,) for c in [*columns, *extra]), group
            for column in columns:
                if dataset[column].dtype.kind == "f":
                    assert dataset[column].attrs["units"], (name, group, column)
        impacts = _open(path, "impacts")
        assert impacts["time"].attrs["units"] == "s"
        assert impacts["impact_speed"].dtype == np.float64
        correlation = _open(path, "fits/Ia")["correlation"]
        assert correlation.dims == ("varied", "varied_with")
        assert list(correlation["varied"].values) == list(correlation["varied_with"].values)
    # The whole file is a netCDF-4 tree: no group needs invented dimensions.
    path = scene_files["paths"]["light-ball-audio"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tree = xarray.open_datatree(path, engine="h5netcdf")
    residuals = tree["fits/IIb/residuals"].to_dataset(inherit=False)
    assert residuals["time"].dims == ("fitted_impact",)
    assert residuals["normalized"].dims == ("residual",)
    predicted = tree["fits/IIb/predicted"].to_dataset(inherit=False)
    assert predicted["speeds"].dims == ("impact",) and predicted["at_data"].dims == (
        "fitted_impact",)
    assert predicted.sizes["fitted_impact"] == residuals.sizes["fitted_impact"]
    curve = tree["fits/IIb/eps_curve"].to_dataset(inherit=False)
    assert curve["eps"].dims == ("speed",) and curve["speed"].attrs["units"] == "m/s"
    tree.close()
    summary = _open(scene_files["summary_h5"], "summary")
    assert dict(summary.sizes) == {"scene": len(scene_files["summary"])}
    assert summary["beta"].attrs["units"] == "1/s"


def test_noise_tables_open_in_xarray_too(scene_files, tmp_path):
    """A scene fitted under the noise model as well: its noise selection and every noise
    fit's parameter table open with their named dimensions, of the documented types."""
    name = "timestamp-table"
    scene = workflow_scene(name, scene_file=scene_files["paths"][name].parent / "synthetic" /
                           name / "scene.yaml")
    impacts, scene_fit = analyze(scene.recording, scene, models=("Ia",), noise=True)
    path = tmp_path / "noise.h5"
    write_scene_fit(path, scene_fit, impacts)
    documented = _documented_types()
    with h5py.File(path, "r") as source:
        laws = list(source["noise_fits"])
        found = {}
        source.visititems(lambda item, obj: found.update(
            {item: _type_name(obj)} if isinstance(obj, h5py.Dataset) else {}))
    assert len(laws) >= 2
    assert {item: dtype for item, dtype in found.items()} == {
        item: documented[_generic(item)] for item in found}
    selection = _open(path, "noise_selection")
    assert dict(selection.sizes) == {"model": len(laws)}
    assert selection["sigma_j"].attrs["units"] == "s" and selection["kept"].dtype == bool
    # The drag rung's k_d corrects the bounce table: its added columns are documented above
    # and open on the table's dimension like the others.
    assert "constant+drag" in laws
    bounces = _open(path, "bounces")
    for column in ("landing_speed", "restitution_corrected",
                   "restitution_corrected_uncertainty", "restitution_corrected_drag_uncertainty"):
        assert bounces[column].dims == ("bounce",) and bounces[column].dtype == np.float64
    assert bounces["landing_speed"].attrs["units"] == "m/s"
    assert bounces.attrs["drag_source"] in laws
    for law in laws:
        parameters = _open(path, f"noise_fits/{law}/parameters")
        assert list(parameters.sizes) == ["name"] and "sigma_j" in parameters["name"].values
        fit = _open(path, f"noise_fits/{law}")
        assert _open(path, f"noise_fits/{law}/residuals")["normalized"].dims == ("residual",)
        assert fit["correlation"].dims == ("varied", "varied_with")
        assert fit["timing_sigma"].attrs["units"] == "s"


def _pull(value, stderr, truth):
    return (value - truth) / stderr if np.isfinite(stderr) and stderr > 0 else np.nan


def test_pulls_are_computed_against_the_truth_of_the_config(scene_files):
    """Truth from config/config.yaml (not truth.json), fit from the file's parameters table."""
    summary = scene_files["summary"].set_index(["scene", "model"])
    for name, spec in SCENES.items():
        truth = {"beta": spec["beta"], "omega0": spec["omega0"],
                 "zeta": spec["beta"] / spec["omega0"], "v0": spec["v0"]}
        model = spec.get("model", "hybrid")
        with h5py.File(scene_files["paths"][name], "r") as source:
            group = source["truth"]
            assert group.attrs["model"] == model and group.attrs["source"] == "truth.json"
            table = pd.DataFrame({c: group[c].asstr()[()] if h5py.check_string_dtype(
                group[c].dtype) else group[c][()] for c in group.attrs["columns"]})
            names = source[f"fits/{model}/parameters/name"].asstr()[()]
            fits = {m: pd.DataFrame({c: source[f"fits/{m}/parameters/{c}"][()] for c in
                                     ("value", "stderr", "low95", "high95")},
                                    index=source[f"fits/{m}/parameters/name"].asstr()[()])
                    for m in source["fits"]}
        assert "beta" in names
        table = table.set_index("parameter")
        assert list(table.index) == list(truth)
        for parameter, true_value in truth.items():
            row, fit = table.loc[parameter], fits[model].loc[parameter]
            assert row["truth"] == pytest.approx(true_value, rel=1e-12)
            assert (row["value"], row["stderr"]) == (fit["value"], fit["stderr"])
            expected = _pull(fit["value"], fit["stderr"], true_value)
            if np.isnan(expected):
                assert np.isnan(row["pull"]) and row["note"], (name, parameter)
            else:
                assert row["pull"] == pytest.approx(expected, rel=1e-9), (name, parameter)
                assert row["note"] == ""
            assert row["covered95"] == (fit["low95"] <= true_value <= fit["high95"])
            # The summary gives every model's pull against the same truth.
            for other, estimates in fits.items():
                line = summary.loc[(name, other)]
                assert line[f"{parameter}_truth"] == pytest.approx(true_value, rel=1e-12)
                other_pull = _pull(estimates.loc[parameter, "value"],
                                   estimates.loc[parameter, "stderr"], true_value)
                assert line[f"{parameter}_pull"] == pytest.approx(other_pull, rel=1e-9,
                                                                  nan_ok=True)
    # A pull is a number of σ: the generating fits' determined pulls are not all tiny (the
    # truth is not the fit's own value) and none is absurd.
    determined = [summary.loc[(n, s.get("model", "hybrid")), "beta_pull"]
                  for n, s in SCENES.items()]
    assert np.nanmax(np.abs(determined)) < 10


def test_summary_csv_headers_carry_units(scene_files):
    table = pd.read_csv(scene_files["summary_csv"])
    for column in ("beta [1/s]", "beta_stderr [1/s]", "k [N/m]", "omega0 [rad/s]", "v0 [m/s]",
                   "sigma_j [s]", "beta_truth [1/s]", "omega0_truth [rad/s]", "v0_truth [m/s]",
                   "zeta", "zeta_truth", "beta_pull", "model", "scene"):
        assert column in table.columns, column
    assert list(table.columns) == [csv_header(c) for c in scene_files["summary"].columns]
    np.testing.assert_allclose(table["beta [1/s]"], scene_files["summary"]["beta"], rtol=1e-12)


def test_truth_json_and_config_agree(scene_files):
    """The fitted files' truth tables come from truth.json; that file holds the config's
    generator (so the independent check above reads the same numbers)."""
    for name, spec in SCENES.items():
        truth = json.loads((scene_files["paths"][name].parent / "synthetic" / name /
                            "truth.json").read_text())["generator"]
        assert {k: truth[k] for k in ("beta", "omega0", "v0")} == {
            k: spec[k] for k in ("beta", "omega0", "v0")}
