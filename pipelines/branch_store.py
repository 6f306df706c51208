"""Incremental HDF5 storage of a continuation branch.

A run writes `NAME.partial.h5` point by point (each append is flushed, so an interrupted
run keeps every point computed so far) and `finalize` records the stop reason, marks the
file complete and renames it to `NAME.h5`. A file is complete only if it has the final
name *and* `complete = 1`; `load_branch` refuses anything else unless asked for a partial.

Layout (m points, n unknowns):
  root attrs: the caller's (units, scene, code_version, inputs_hash, ...), plus created,
    n_unknowns, n_points (rows fully written), complete (0/1), status, detail, and once
    complete the datasets' checksums (pipelines.artifacts.verify).
  omega (m,) rad/s; x (m, n) the continuation's unknowns (for the HBM: the scaled
  harmonics alpha x~_r, unit 1); converged (m,) bool; residual_norm (m,) (unit of the
  residual: 1 for the scaled HBM residual); iterations (m,); step (m,) scaled arc length;
  time (m,) s; extras/NAME (m, ...) caller's per-point data, with the units given at create.
Every dataset has a `unit` attribute.
Datasets may be longer than n_points after a crash in the middle of an append; readers
use the first n_points rows only.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import h5py
import numpy as np

from hbm.continuation.branch import Branch, ContinuationPoint
from hbm.continuation.missing import NO_VALUE
from pipelines.artifacts import CHECKSUMS, commit, dataset_checksums, now, open_in_place

_FIELDS = {  # name: (dtype, unit)
    "omega": (np.float64, "rad/s"),
    "x": (np.float64, "1"),
    "converged": (np.bool_, "1"),
    "residual_norm": (np.float64, "1"),
    "iterations": (np.int64, "1"),
    "step": (np.float64, "1"),
    "time": (np.float64, "s"),
}
_RESERVED_ATTRS = {"n_unknowns", "n_points", "complete", "status", "detail", "created", "extras_units", CHECKSUMS}


class StoredBranch(NamedTuple):
    """What `load_branch` returns.

    branch: the points (Branch; status "" for a partial file). extras: name -> (m, ...)
    arrays. attrs: root attributes. complete: finalized under its final name.
    """

    branch: Branch
    extras: dict
    attrs: dict
    complete: bool


def final_path(path: Path | str) -> Path:
    """NAME.h5 for NAME.h5 or NAME.partial.h5."""
    path = Path(path)
    return path.with_name(path.name[: -len(".partial.h5")] + ".h5") if path.name.endswith(".partial.h5") else path


def partial_path(path: Path | str) -> Path:
    """NAME.partial.h5 for NAME.h5 or NAME.partial.h5."""
    path = final_path(path)
    return path.with_name(path.name[: -len(".h5")] + ".partial.h5")


def rank_partial_path(path: Path | str, rank: int) -> Path:
    """The partial file MPI rank `rank` writes for NAME.h5: NAME.partial.h5 for rank 0,
    NAME.rR.partial.h5 for rank R > 0 (one writer per HDF5 file)."""
    part = partial_path(path)
    return part if rank == 0 else part.with_name(f"{part.name[: -len('.partial.h5')]}.r{rank}.partial.h5")


def partial_paths(path: Path | str) -> list:
    """Where the partial files of NAME.h5 go: rank 0's NAME.partial.h5 (on disk or not), then
    every entry named as another MPI rank's (rank_partial_path) that is on disk, whatever it
    is (a folder there is refused before a run, pipelines.runner)."""
    part = partial_path(path)
    return [part, *sorted(part.parent.glob(f"{part.name[: -len('.partial.h5')]}.r[0-9]*.partial.h5"))]


def partial_files(path: Path | str) -> list:
    """The partial files of NAME.h5 on disk: rank 0's (NAME.partial.h5) first, then those
    other MPI ranks wrote (rank_partial_path)."""
    return [p for p in partial_paths(path) if p.is_file()]


def _attr_value(v):
    if isinstance(v, (dict, list, tuple)):
        return json.dumps(v, default=str)
    if v is None:
        return ""
    return v


def _decode(v):
    return v.decode() if isinstance(v, bytes) else v


class BranchStore:
    """Append-only writer of one branch; use `create` or `reopen`, then `append`, `finalize`.

    Used as a context manager it closes the file on exit *without* finalising it, so an
    exception leaves a partial file that `reopen` can continue.
    """

    def __init__(self, h5: h5py.File, path: Path):
        self._h5 = h5
        self.path = final_path(path)
        self.n = int(h5.attrs["n_unknowns"])
        self.n_points = int(h5.attrs["n_points"])
        self._extras = set(h5["extras"].keys())
        self._units = json.loads(_decode(h5.attrs.get("extras_units", "{}")) or "{}")
        self._resumed = False  # set by reopen: its points may predate extras this run records

    @classmethod
    def create(cls, path: Path | str, n: int, *, attrs: dict | None = None,
               units: dict | None = None) -> "BranchStore":
        """Start `NAME.partial.h5` for a branch of n unknowns (path: NAME.h5 or NAME.partial.h5).

        attrs: root attributes (units, scene, code_version, inputs_hash, metadata ...); dicts
        and lists are stored as JSON text. units: {extra name: unit} of the extras that
        `append` will write ("1" for those not named). An older partial file of that name is
        replaced; a finished NAME.h5 is left alone until `finalize` replaces it.
        """
        bad = _RESERVED_ATTRS & set(attrs or {})
        if bad:
            raise ValueError(f"reserved attribute names: {sorted(bad)}")
        part = partial_path(path)
        part.parent.mkdir(parents=True, exist_ok=True)
        h5 = open_in_place(part, "w")
        try:
            for k, v in (attrs or {}).items():
                h5.attrs[k] = _attr_value(v)
            h5.attrs.update({"n_unknowns": int(n), "n_points": 0, "complete": 0, "status": "", "detail": "",
                             "created": now(), "extras_units": json.dumps(units or {})})
            for name, (dtype, unit) in _FIELDS.items():
                shape = (0, n) if name == "x" else (0,)
                ds = h5.create_dataset(name, shape=shape, maxshape=(None,) + shape[1:], dtype=dtype,
                                       chunks=(64,) + shape[1:])
                ds.attrs["unit"] = unit
            h5.create_group("extras")
            h5.flush()
        except Exception:
            h5.close()
            raise
        return cls(h5, part)

    @classmethod
    def reopen(cls, path: Path | str, *, keep: int | None = None, units: dict | None = None) -> "BranchStore":
        """Continue appending to the partial file of an interrupted run.

        keep: truncate to the first `keep` points (e.g. to drop the failed point that a
        resumed continuation will redo); default: all fully written points. units: {extra
        name: unit} of extras this run records that the file may not hold yet (see append).
        A partial file marked complete (a run killed inside `finalize`, between the flag and
        the rename) is not complete (that takes the final name): its flag and checksums are
        cleared and its points kept.
        """
        part = partial_path(path)
        if not part.is_file():
            raise FileNotFoundError(f"no partial branch file {part}")
        h5 = open_in_place(part, "r+")
        try:
            if int(h5.attrs["complete"]):
                h5.attrs["complete"] = 0
                if CHECKSUMS in h5.attrs:
                    del h5.attrs[CHECKSUMS]
            m = int(h5.attrs["n_points"])
            keep = m if keep is None else keep
            if not 0 <= keep <= m:
                raise ValueError(f"keep={keep} outside [0, {m}]")
            for ds in _datasets(h5):
                ds.resize(keep, axis=0)
            h5.attrs["n_points"] = keep
            h5.flush()
        except Exception:
            h5.close()
            raise
        store = cls(h5, part)
        store._resumed = True
        if units:
            store._units = {**units, **store._units}
            h5.attrs["extras_units"] = json.dumps(store._units)
        return store

    def append(self, point: ContinuationPoint, extras: dict | None = None) -> None:
        """Write one point (and its named extra scalars/arrays; text as str) and flush it to disk.

        The set of extras is fixed by the first point: every later point gives the same
        names with the same shapes. A reopened store (a resume) also takes extras that its
        points lack (a run of an earlier version did not record them): their rows before
        are filled with hbm.continuation.missing.NO_VALUE's value for the dtype (text: ""),
        and the dataset's attribute `recorded_from` gives the first row that holds a value.
        """
        extras = {k: np.asarray(v) for k, v in (extras or {}).items()}
        if self._resumed and self._extras and set(extras) > self._extras:
            g = self._h5["extras"]
            for k in sorted(set(extras) - self._extras):
                v = extras[k]
                fill = {} if _is_text(v) else {"fillvalue": NO_VALUE.get(v.dtype.kind, 0)}  # text: ""
                ds = g.create_dataset(k, shape=(self.n_points,) + v.shape, maxshape=(None,) + v.shape,
                                      dtype=_h5_dtype(v), chunks=True, **fill)
                ds.attrs["unit"] = self._units.get(k, "1")
                ds.attrs["recorded_from"] = self.n_points
            self._extras = set(extras)
        x = np.asarray(point.x, dtype=float).reshape(-1)
        if x.size != self.n:
            raise ValueError(f"point has {x.size} unknowns, store has {self.n}")
        if self.n_points == 0 and not self._extras:
            g = self._h5["extras"]
            for k, v in extras.items():
                ds = g.create_dataset(k, shape=(0,) + v.shape, maxshape=(None,) + v.shape, dtype=_h5_dtype(v),
                                      chunks=True)
                ds.attrs["unit"] = self._units.get(k, "1")
            self._extras = set(extras)
        if set(extras) != self._extras:
            raise ValueError(f"extras {sorted(extras)} differ from the store's {sorted(self._extras)}")
        for name, v in extras.items():  # all checks before the first write
            shape = self._h5["extras"][name].shape[1:]
            if shape != v.shape:
                raise ValueError(f"extra '{name}' has shape {v.shape}, store has {shape}")
        m = self.n_points
        values = {"omega": point.omega, "x": x, "converged": point.converged, "residual_norm": point.residual_norm,
                  "iterations": point.iterations, "step": point.step, "time": point.time}
        for name, v in values.items():
            ds = self._h5[name]
            ds.resize(m + 1, axis=0)
            ds[m] = v
        for name, v in extras.items():
            ds = self._h5["extras"][name]
            ds.resize(m + 1, axis=0)
            ds[m] = v.astype(object) if _is_text(v) else v  # h5py writes text from str objects
        self._h5.attrs["n_points"] = m + 1  # last: the row counts only once all of it is written
        self._h5.flush()
        self.n_points = m + 1

    def write_tables(self, tables: dict) -> None:
        """Write (or replace) whole-branch tables {group: {name: (array, unit)}} in the partial
        file and flush them: what a resumed run reads back (read_tables)."""
        write_tables(self._h5, tables)
        self._h5.flush()

    def finalize(self, status: str, detail: str = "", tables: dict | None = None) -> Path:
        """Record why the branch stopped, mark complete, add the datasets' checksums
        (pipelines.artifacts.verify), rename to NAME.h5; returns that path.

        tables: {group: {name: (array, unit)}}, whole-branch data written with it (e.g. the
        bifurcations located along the branch), each dataset with its unit.
        """
        write_tables(self._h5, tables or {})
        self._h5.attrs["status"] = status
        self._h5.attrs["detail"] = detail
        self._h5.attrs["complete"] = 1
        self._h5.flush()
        self._h5.attrs[CHECKSUMS] = json.dumps(dataset_checksums(self._h5), sort_keys=True)
        self._h5.flush()
        self._h5.close()
        return commit(partial_path(self.path), self.path)

    def close(self) -> None:
        """Close without finalising (the file stays NAME.partial.h5)."""
        if self._h5.id.valid:
            self._h5.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _is_text(v: np.ndarray) -> bool:
    """An extra of str (numpy U, or an object array of str): stored as variable-length text."""
    return v.dtype.kind == "U" or (v.dtype == object and all(isinstance(e, str) for e in v.reshape(-1)))


def _h5_dtype(v: np.ndarray):
    return h5py.string_dtype() if _is_text(v) else v.dtype


def write_column(group, name: str, value, unit: str) -> None:
    """A whole per-point dataset `name` of `group` with its unit; text as variable-length strings."""
    v = np.asarray(value)
    group.create_dataset(name, data=v.astype(object) if _is_text(v) else v, dtype=_h5_dtype(v)).attrs["unit"] = unit


def read_column(ds, stop: int | None = None) -> np.ndarray:
    """A per-point dataset's rows up to `stop` (all by default); text as an object array of str."""
    if h5py.check_string_dtype(ds.dtype):
        return np.array(ds.asstr()[:stop], dtype=object)
    return ds[:stop] if ds.ndim else ds[()]


def _datasets(h5: h5py.File):
    yield from (h5[name] for name in _FIELDS)
    yield from h5["extras"].values()


def load_branch(path: Path | str, *, allow_partial: bool = False) -> StoredBranch:
    """Read a branch file: NAME.h5 (complete) or, with allow_partial, NAME.partial.h5.

    Given NAME.h5 that does not exist, allow_partial falls back to NAME.partial.h5.
    Raises FileNotFoundError when there is nothing to read, and ValueError when the file
    is not complete and allow_partial is False: a partial file is never taken as complete.
    """
    path = Path(path)
    if not path.is_file() and allow_partial and partial_path(path).is_file():
        path = partial_path(path)
    if not path.is_file():
        hint = " (an interrupted run left a partial file)" if partial_path(path).is_file() else ""
        raise FileNotFoundError(f"no branch file {path}{hint}")
    with h5py.File(path, "r") as h5:
        attrs = {k: _decode(v) for k, v in h5.attrs.items()}
        m = int(attrs["n_points"])
        complete = bool(int(attrs["complete"])) and not path.name.endswith(".partial.h5")
        if not complete and not allow_partial:
            raise ValueError(f"{path} is not a complete branch file (interrupted run?); "
                             f"pass allow_partial=True to read its points")
        arrays = {name: h5[name][:m] for name in _FIELDS}
        extras = {name: read_column(ds, m) for name, ds in h5["extras"].items()}
    branch = Branch(**arrays, status=attrs["status"], detail=attrs["detail"])
    return StoredBranch(branch, extras, attrs, complete)


def write_tables(parent, tables: dict) -> None:
    """Whole-branch tables {group: {name: (array, unit)}} as groups of `parent` (an h5py
    group), each dataset with its unit; text columns (object arrays, e.g. a bifurcation's
    kind) as variable-length strings. A group already there is replaced."""
    for group, arrays in tables.items():
        if group in parent:
            del parent[group]
        g = parent.create_group(group)
        for name, (value, unit) in arrays.items():
            value = np.asarray(value)
            if value.dtype == object:
                value = np.array([str(v) for v in value], dtype=h5py.string_dtype())
            g.create_dataset(name, data=value).attrs["unit"] = unit


def read_tables(path: Path | str) -> dict:
    """{group: {name: array}} of the whole-branch tables in a branch file, complete or partial
    (those BranchStore.write_tables or finalize wrote)."""
    with h5py.File(path, "r") as h5:
        return {name: {k: v for k, (v, _) in read_table(g).items()} for name, g in h5.items()
                if isinstance(g, h5py.Group) and name != "extras"}


def read_table(group) -> dict:
    """{name: (array, unit)} of a group written by write_tables (text columns as object arrays of str)."""
    out = {}
    for name, d in group.items():
        v = d[()]
        if v.dtype.kind in "OS":
            v = np.array([x.decode() if isinstance(x, bytes) else str(x) for x in np.asarray(v).reshape(-1)],
                         dtype=object)
        unit = d.attrs.get("unit", "-")
        out[name] = (v, unit.decode() if isinstance(unit, bytes) else str(unit))
    return out
