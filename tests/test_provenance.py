"""Which code made a result: the digest of the dashpot source (dashpot.provenance), in the
scene and summary files and in the chunk's check of an up-to-date scene."""

import shutil
from pathlib import Path

import h5py
import pandas as pd
import pytest

import dashpot
import dashpot.provenance
from dashpot.batch import scene_fingerprint
from dashpot.provenance import source_files, source_fingerprint
from dashpot.store import write_summary

PACKAGE = Path(dashpot.__file__).resolve().parent


@pytest.fixture
def package_copy(tmp_path):
    """A copy of the running package's source files, without its caches."""
    copy = tmp_path / "copy" / "dashpot"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    return copy


def test_the_digest_covers_every_module_and_the_scene_schema():
    names = {path.relative_to(PACKAGE).as_posix() for path in source_files()}
    assert {"__init__.py", "figures.py", "physics/models.py", "fit/model_fit.py",
            "scene.schema.yaml"} <= names
    assert not any("__pycache__" in name for name in names)
    assert len(source_fingerprint()) == 64 and int(source_fingerprint(), 16) >= 0


def test_the_same_source_gives_the_same_digest_wherever_it_lies(package_copy, tmp_path):
    assert source_fingerprint(package_copy) == source_fingerprint() == source_fingerprint(
        PACKAGE)
    other = tmp_path / "elsewhere" / "dashpot"
    shutil.copytree(package_copy, other)
    # Compiled caches and other kinds of file are not the source.
    (other / "__pycache__").mkdir(exist_ok=True)
    (other / "__pycache__" / "figures.cpython-312.pyc").write_bytes(b"\0compiled")
    (other / "notes.txt").write_text("not code\n")
    assert source_fingerprint(other) == source_fingerprint(package_copy)


@pytest.mark.parametrize("change", ["comment", "schema", "new module", "renamed"])
def test_any_change_to_the_source_changes_the_digest(package_copy, change):
    before = source_fingerprint(package_copy)
    if change == "comment":
        with open(package_copy / "physics" / "models.py", "a", encoding="utf-8") as module:
            module.write("# one more line\n")
    elif change == "schema":
        schema = package_copy / "scene.schema.yaml"
        schema.write_text(schema.read_text(encoding="utf-8") + "\n", encoding="utf-8")
    elif change == "new module":
        (package_copy / "fit" / "extra.py").write_text("")
    else:  # the same bytes under another name
        (package_copy / "plots.py").rename(package_copy / "plots_renamed.py")
    assert source_fingerprint(package_copy) != before


def test_a_changed_source_makes_the_chunk_fit_a_scene_again(monkeypatch):
    task = {"name": "a", "source": "synthetic", "spec": {"kind": "timestamps", "seed": 1},
            "truth": "results/synthetic/a/truth.json", "uncertainty": ["covariance"],
            "noise": False}
    before = scene_fingerprint(task)
    assert scene_fingerprint(task) == before
    monkeypatch.setattr(dashpot.provenance, "source_fingerprint", lambda: "0" * 64)
    assert scene_fingerprint(task) != before


def test_the_summary_file_says_which_code_wrote_it(tmp_path):
    table = pd.DataFrame({"scene": ["a"], "model": ["Ia"], "beta": [1.0]})
    write_summary(tmp_path / "summary.h5", tmp_path / "summary.csv", table)
    with h5py.File(tmp_path / "summary.h5", "r") as source:
        assert source.attrs["dashpot_source_sha256"] == source_fingerprint()
        assert source.attrs["dashpot_version"] == dashpot.__version__
