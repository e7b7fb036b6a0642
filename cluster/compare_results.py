#!/usr/bin/env python3
"""Compare two workflow result trees (e.g. a local run and a SLURM run of the same workflow).

    compare_results.py LOCAL_RESULTS SLURM_RESULTS [--ignore-root-attr NAME ...]

Every file under the two directories is compared, except anything in a directory named
``logs`` or ``benchmarks`` and ``*.log`` files (timings, host names):

- HDF5 (``.h5``, ``.hdf5``): same groups, datasets and links; every dataset equal in dtype,
  shape and values (NaN equals NaN); every attribute of every object equal, except the root
  attributes named by --ignore-root-attr (default: ``created``, the creation time). Object
  references (dimension scales' lists) are compared by the path they point to, not by address.
- plots (PNG, PDF, SVG, EPS, JPEG, ...): only present on both sides (renderers write dates
  and ids into them, so their bytes may differ).
- everything else (CSV, JSON, YAML, text, other binaries): byte for byte.

Prints a short table and exits 0 if the trees are equal, 1 on any difference (including a
file present on one side only, or no files at all), 2 on bad usage.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

IGNORED_DIRS = {"logs", "benchmarks"}
IGNORED_SUFFIXES = {".log"}
HDF5_SUFFIXES = {".h5", ".hdf5"}
PLOT_SUFFIXES = {".png", ".pdf", ".svg", ".svgz", ".eps", ".ps", ".jpg", ".jpeg", ".gif",
                 ".tif", ".tiff", ".webp"}
MAX_ROWS = 40  # above this many files only the differing ones are listed


def collect(root: Path) -> set[str]:
    """Relative paths of the files to compare under root."""
    files = set()
    for path in root.rglob("*"):
        rel = path.relative_to(root)
        if any(part in IGNORED_DIRS for part in rel.parts[:-1]):
            continue
        if path.is_dir() or path.suffix.lower() in IGNORED_SUFFIXES:
            continue
        files.add(rel.as_posix())
    return files


def kind_of(rel: str) -> str:
    suffix = Path(rel).suffix.lower()
    if suffix in HDF5_SUFFIXES:
        return "hdf5"
    if suffix in PLOT_SUFFIXES:
        return "plot"
    return "bytes"


def compare_bytes(a: Path, b: Path) -> str | None:
    da, db = a.read_bytes(), b.read_bytes()
    if da == db:
        return None
    sizes = f"{len(da)} vs {len(db)} bytes"
    la, lb = da.splitlines(), db.splitlines()
    for number, (x, y) in enumerate(zip(la, lb), start=1):
        if x != y:
            return f"line {number} differs ({sizes})"
    return f"{len(la)} vs {len(lb)} lines ({sizes})"


def _equal_values(x, y) -> bool:
    import numpy as np

    x, y = np.asarray(x), np.asarray(y)
    if x.dtype != y.dtype or x.shape != y.shape:
        return False
    if x.dtype.kind in "fc":
        return bool(np.array_equal(x, y, equal_nan=True))
    if x.dtype.kind == "V" and x.dtype.names:  # compound: field by field
        return all(_equal_values(x[name], y[name]) for name in x.dtype.names)
    return bool(np.array_equal(x, y))


def _holds_objects(dtype) -> bool:
    """Whether values of this dtype hold Python objects (references, vlen data, strings)."""
    if dtype.names:
        return any(_holds_objects(dtype[name]) for name in dtype.names)
    return dtype.kind == "O"


def _dereferenced(value, file):
    """Value with every object reference replaced by the path of the object it points to.

    A reference is a file address, and two equal files need not place their objects at equal
    addresses (dimension scales' DIMENSION_LIST and REFERENCE_LIST hold such references), so
    references are compared by what they point to.
    """
    import h5py
    import numpy as np

    if isinstance(value, (h5py.Reference, h5py.RegionReference)):
        return file[value].name if value else None
    if isinstance(value, np.void) and value.dtype.names:
        return tuple(_dereferenced(value[name], file) for name in value.dtype.names)
    if isinstance(value, np.ndarray) and _holds_objects(value.dtype):
        return [_dereferenced(item, file) for item in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def _attrs_diff(where: str, a, b, ignore: set[str]) -> str | None:
    import numpy as np

    keys_a, keys_b = set(a.attrs) - ignore, set(b.attrs) - ignore
    if keys_a != keys_b:
        return f"{where}: attributes {sorted(keys_a ^ keys_b)} on one side only"
    for key in sorted(keys_a):
        value_a, value_b = a.attrs[key], b.attrs[key]
        if isinstance(value_a, np.ndarray) and _holds_objects(value_a.dtype):
            equal = (isinstance(value_b, np.ndarray) and value_a.dtype == value_b.dtype
                     and _dereferenced(value_a, a.file) == _dereferenced(value_b, b.file))
        else:
            equal = _equal_values(value_a, value_b)
        if not equal:
            return f"{where}: attribute {key!r} differs"
    return None


def compare_hdf5(a: Path, b: Path, ignore_root_attrs: set[str]) -> str | None:
    import h5py

    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        return _compare_group(fa, fb, "/", ignore_root_attrs)


def _compare_group(ga, gb, where: str, ignore: set[str]) -> str | None:
    import h5py

    problem = _attrs_diff(where, ga, gb, ignore)
    if problem:
        return problem
    names_a, names_b = set(ga.keys()), set(gb.keys())
    if names_a != names_b:
        return f"{where}: members {sorted(names_a ^ names_b)} on one side only"
    for name in sorted(names_a):
        path = f"{where.rstrip('/')}/{name}"
        link_a, link_b = ga.get(name, getlink=True), gb.get(name, getlink=True)
        if type(link_a) is not type(link_b):
            return f"{path}: link type {type(link_a).__name__} != {type(link_b).__name__}"
        if isinstance(link_a, h5py.SoftLink):
            if link_a.path != link_b.path:
                return f"{path}: soft link target {link_a.path} != {link_b.path}"
            continue
        if isinstance(link_a, h5py.ExternalLink):
            if (link_a.filename, link_a.path) != (link_b.filename, link_b.path):
                return f"{path}: external link target differs"
            continue
        oa, ob = ga[name], gb[name]
        if isinstance(oa, h5py.Group) and isinstance(ob, h5py.Group):
            problem = _compare_group(oa, ob, path, set())
        elif isinstance(oa, h5py.Dataset) and isinstance(ob, h5py.Dataset):
            problem = _compare_dataset(oa, ob, path)
        elif isinstance(oa, h5py.Datatype) and isinstance(ob, h5py.Datatype):
            problem = None if oa.dtype == ob.dtype else f"{path}: named datatype differs"
            problem = problem or _attrs_diff(path, oa, ob, set())
        else:
            problem = f"{path}: {type(oa).__name__} != {type(ob).__name__}"
        if problem:
            return problem
    return None


def _compare_dataset(da, db, path: str) -> str | None:
    if da.dtype != db.dtype:
        return f"{path}: dtype {da.dtype} != {db.dtype}"
    if da.shape != db.shape:
        return f"{path}: shape {da.shape} != {db.shape}"
    if not _equal_values(da[()], db[()]):
        return f"{path}: values differ"
    return _attrs_diff(path, da, db, set())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("local", type=Path, help="results/ of the reference (local) run")
    parser.add_argument("other", type=Path, help="results/ of the run to check (SLURM)")
    parser.add_argument("--names", nargs=2, default=["local", "slurm"], metavar=("A", "B"),
                        help="labels of the two runs in the table")
    parser.add_argument("--ignore-root-attr", action="append", metavar="NAME",
                        help="HDF5 root attribute to ignore (repeatable; default: created)")
    args = parser.parse_args(argv)
    ignore = set(args.ignore_root_attr or ["created"])
    for root in (args.local, args.other):
        if not root.is_dir():
            print(f"compare_results: {root} is not a directory", file=sys.stderr)
            return 2

    files_a, files_b = collect(args.local), collect(args.other)
    rows = []  # (file, kind, result, detail)
    for rel in sorted(files_a | files_b):
        kind = kind_of(rel)
        if rel not in files_b:
            rows.append((rel, kind, "DIFFERENT", f"only in {args.names[0]}"))
            continue
        if rel not in files_a:
            rows.append((rel, kind, "DIFFERENT", f"only in {args.names[1]}"))
            continue
        a, b = args.local / rel, args.other / rel
        try:
            if kind == "hdf5":
                detail = compare_hdf5(a, b, ignore)
            elif kind == "plot":
                detail = None
            else:
                detail = compare_bytes(a, b)
        except Exception as error:  # unreadable file: a difference, with the reason
            detail = f"cannot compare: {type(error).__name__}: {error}"
        rows.append((rel, kind, "DIFFERENT" if detail else "equal",
                     detail or ("present in both" if kind == "plot" else "")))

    if not rows:
        print(f"no result files to compare in {args.local} and {args.other}")
        return 1
    different = [row for row in rows if row[2] != "equal"]
    shown = rows if len(rows) <= MAX_ROWS else different
    width = max([len("file")] + [len(row[0]) for row in shown])
    print(f"{'file':<{width}}  {'kind':<5}  result     detail")
    for rel, kind, result, detail in shown:
        print(f"{rel:<{width}}  {kind:<5}  {result:<9}  {detail}".rstrip())
    if len(shown) < len(rows):
        print(f"... and {len(rows) - len(shown)} more equal files")
    counts = {kind: sum(row[1] == kind for row in rows) for kind in ("bytes", "hdf5", "plot")}
    summary = ", ".join(f"{n} {kind}" for kind, n in counts.items() if n)
    if different:
        print(f"results differ: {len(different)} of {len(rows)} files ({summary})")
        return 1
    print(f"results equal: {len(rows)} files ({summary})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
