"""The result-tree comparator of `make cluster-test` (cluster/compare_results.py).

Its verdict decides whether a SLURM run reproduced the local one, so it must call equal trees
equal (even where HDF5 places objects at different addresses) and find every real difference.
"""

import importlib.util
from pathlib import Path

import h5py
import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "cluster" / "compare_results.py"


@pytest.fixture(scope="module")
def compare():
    spec = importlib.util.spec_from_file_location("compare_results", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


def _write_table(path: Path, scale_of_speed: str = "bounce", padding: int = 0,
                 speed_offset: float = 0.0) -> None:
    """A bounce table with dimension scales, as the store writes one.

    ``padding`` bytes of an unrelated dataset written first move every later object to another
    file address, which changes the raw references but not what they point to.
    """
    with h5py.File(path, "w") as file:
        if padding:
            file.create_dataset("padding", data=np.zeros(padding, dtype=np.uint8))
            del file["padding"]
        table = file.create_group("bounces")
        bounce = table.create_dataset("bounce", data=np.arange(1, 6))
        other = table.create_dataset("run", data=np.ones(5, dtype=int))
        speed = table.create_dataset("impact_speed", data=np.linspace(2.0, 1.0, 5) + speed_offset)
        speed.attrs["units"] = "m s-1"
        bounce.make_scale("bounce")
        other.make_scale("run")
        speed.dims[0].attach_scale(table[scale_of_speed])
        (path.parent / "summary.csv").write_text("scene,beta [1/s]\nball,25.0\n")


def _trees(tmp_path: Path, **other_kwargs) -> tuple[Path, Path]:
    local, slurm = tmp_path / "local", tmp_path / "slurm"
    local.mkdir()
    slurm.mkdir()
    _write_table(local / "ball.h5")
    _write_table(slurm / "ball.h5", **other_kwargs)
    return local, slurm


def test_equal_tables_are_equal_even_at_other_addresses(tmp_path, compare, capsys):
    local, slurm = _trees(tmp_path, padding=4096)
    assert compare([str(local), str(slurm)]) == 0
    assert "results equal: 2 files" in capsys.readouterr().out


def test_a_tree_equals_itself(tmp_path, compare):
    local, _ = _trees(tmp_path)
    assert compare([str(local), str(local)]) == 0


def test_a_scale_attached_to_another_dataset_is_a_difference(tmp_path, compare, capsys):
    local, slurm = _trees(tmp_path, scale_of_speed="run")
    assert compare([str(local), str(slurm)]) == 1
    out = capsys.readouterr().out
    assert "DIMENSION_LIST" in out or "REFERENCE_LIST" in out


def test_different_values_are_a_difference(tmp_path, compare, capsys):
    local, slurm = _trees(tmp_path, speed_offset=1e-12)
    assert compare([str(local), str(slurm)]) == 1
    assert "/bounces/impact_speed: values differ" in capsys.readouterr().out


def test_a_text_file_differing_by_one_byte_is_a_difference(tmp_path, compare, capsys):
    local, slurm = _trees(tmp_path)
    (slurm / "summary.csv").write_text("scene,beta [1/s]\nball,25.1\n")
    assert compare([str(local), str(slurm)]) == 1
    assert "summary.csv" in capsys.readouterr().out
