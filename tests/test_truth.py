"""Truth against fit (dashpot.truth): pulls by hand, the notes where a pull means nothing, and
one clear line for a truth.json that cannot be used."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from dashpot.errors import InputError
from dashpot.truth import TRUTH_COLUMNS, pulls, read_truth, truth_comparison, truth_table

GENERATOR = {"model": "IIb", "beta": 40.0, "omega0": 2000.0, "g": 9.80665, "v0": 2.0}


def _estimate(value, stderr):
    return SimpleNamespace(value=value, stderr=stderr, low95=value - 2 * stderr,
                           high95=value + 2 * stderr)


def test_pulls_by_hand_and_empty_where_the_error_is_not_usable():
    assert pulls(43.0, 2.0, 40.0) == pytest.approx(1.5)
    assert pulls([37.0, 40.0], [1.5, 4.0], 40.0) == pytest.approx([-2.0, 0.0])
    for stderr in (math.inf, 0.0, math.nan, -1.0):
        assert math.isnan(pulls(43.0, stderr, 40.0))


def test_truth_table_rows_pulls_and_notes():
    estimates = {"beta": _estimate(44.0, 2.0), "omega0": _estimate(2100.0, math.inf),
                 "zeta": _estimate(0.02, 0.0)}  # no v0: a fit without it
    table = truth_table(GENERATOR, estimates).set_index("parameter")
    assert list(table.reset_index().columns) == list(TRUTH_COLUMNS)
    assert table.loc["zeta", "truth"] == pytest.approx(40.0 / 2000.0)
    assert table.loc["beta", "pull"] == pytest.approx((44.0 - 40.0) / 2.0)
    assert table.loc["beta", "note"] == "" and bool(table.loc["beta", "covered95"])
    assert math.isnan(table.loc["omega0", "pull"]) and "infinite" in table.loc["omega0", "note"]
    assert math.isnan(table.loc["zeta", "pull"]) and "fixed" in table.loc["zeta", "note"]
    assert math.isnan(table.loc["v0", "value"]) and "not fitted" in table.loc["v0", "note"]
    assert not table.loc["v0", "covered95"]
    assert table.attrs["model"] == "IIb"
    assert table["truth"].dtype == np.float64 and table["covered95"].dtype == bool


def test_truth_comparison_uses_the_generating_model(tmp_path):
    path = tmp_path / "truth.json"
    path.write_text(json.dumps({"generator": GENERATOR}))
    fitted = SimpleNamespace(results={"IIb": SimpleNamespace(estimates={
        name: _estimate(value, 0.1 * value) for name, value in
        {"beta": 38.0, "omega0": 1900.0, "zeta": 0.02, "v0": 2.1}.items()})})
    table = truth_comparison(path, fitted)
    assert table.attrs == {"model": "IIb", "source": "truth.json"}
    assert table.set_index("parameter").loc["v0", "pull"] == pytest.approx(0.1 / 0.21)
    other = SimpleNamespace(results={"Ia": fitted.results["IIb"]})
    table = truth_comparison(path, other)
    assert table["value"].isna().all()
    assert (table["note"] == "the scene did not fit the generating model IIb").all()


@pytest.mark.parametrize("content, problem", [
    (None, "cannot be read"),
    ("{not json", "not JSON"),
    ('{"sequence": {}}', "no 'generator' record"),
    ('{"generator": {"model": "IIb", "beta": 1.0, "omega0": 2.0}}', "lacks v0"),
    ('{"generator": {"model": "IIb", "beta": -1.0, "omega0": 2.0, "v0": 1.0}}',
     "beta must be a positive number"),
])
def test_unusable_truth_file_is_one_line_naming_it(tmp_path, content, problem):
    path = tmp_path / "truth.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(InputError) as raised:
        read_truth(path)
    message = str(raised.value)
    assert message.startswith(str(path)) and problem in message and "\n" not in message
