"""HDF5 artifacts: one file per stage, written atomically, read back as typed objects.

A stage result is a frozen dataclass whose fields are numpy arrays, scipy sparse
matrices, scalars, strings or nested dataclasses. Each field may carry its SI unit in
`dataclasses.field(metadata={"unit": "m"})`; the unit is stored as the dataset's
`unit` attribute. Files are written to a temporary name in the same folder and renamed
only when complete, so an interrupted run never leaves a file that looks valid.

Every file made final carries the checksum of each of its datasets (root attribute
`checksums`, see `add_checksums`), so that bytes changed on disk, a dataset deleted or a
file cut short are found (`verify`) before the file is taken as current.
"""
from __future__ import annotations

import dataclasses
import datetime
import errno
import functools
import hashlib
import json
import os
import mmap
import shutil
import subprocess
import typing
import zlib
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np
import scipy.sparse as sp

UNITS_SI = "{length: m, time: s, mass: kg, force: N, angle: rad, angular_speed: rad/s, frequency: Hz}"


class ArtifactError(RuntimeError):
    """An artifact that is missing, incomplete or unreadable."""


@functools.lru_cache(maxsize=None)
def code_version() -> str:
    """Package version plus the git commit (with '-dirty' if the tree has changes), once a
    process: every file a run writes, and its check of the files it reuses, read it."""
    from importlib import metadata

    try:
        version = metadata.version("bladerub")
    except metadata.PackageNotFoundError:
        version = "0+unknown"
    try:
        here = Path(__file__).resolve().parent
        # --no-optional-locks: `describe --dirty` refreshes the index under .git/index.lock,
        # which a run interrupted there (Ctrl-C reaches the whole process group) left behind,
        # blocking the user's next git command
        rev = subprocess.run(["git", "--no-optional-locks", "describe", "--always", "--dirty"], cwd=here,
                             capture_output=True, text=True, timeout=5).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        rev = ""
    return f"{version}+{rev}" if rev else version


def _write_value(group: h5py.Group, name: str, value, unit: str | None):
    if value is None:
        return
    if dataclasses.is_dataclass(value):
        sub = group.create_group(name)
        sub.attrs["dataclass"] = type(value).__qualname__
        _write_fields(sub, value)
        return
    if sp.issparse(value):
        csr = sp.csr_matrix(value)
        sub = group.create_group(name)
        sub.attrs["sparse"] = "csr"
        sub.attrs["shape"] = np.asarray(csr.shape, dtype=np.int64)
        # each part carries a unit as every array does: the entries the matrix's, the indices counts
        for part, part_unit in (("data", unit), ("indices", "1"), ("indptr", "1")):
            ds = sub.create_dataset(part, data=getattr(csr, part))
            if part_unit:
                ds.attrs["unit"] = part_unit
        if unit:
            sub.attrs["unit"] = unit
        return
    if isinstance(value, str):
        group.attrs[name] = value
        return
    if isinstance(value, dict):
        sub = group.create_group(name)
        sub.attrs["dict"] = 1
        for k, v in value.items():
            _write_value(sub, str(k), v, None)
        return
    arr = np.asarray(value)
    # Integer arrays (connectivity, CSR indices) shrink several-fold with shuffle+gzip;
    # floating-point fields barely compress and would only cost time.
    squeeze = arr.size > 4096 and arr.dtype.kind in "iu"
    ds = group.create_dataset(name, data=arr, **({"compression": "gzip", "compression_opts": 1,
                                                  "shuffle": True} if squeeze else {}))
    if unit:
        ds.attrs["unit"] = unit


def _write_fields(group: h5py.Group, obj):
    for f in dataclasses.fields(obj):
        _write_value(group, f.name, getattr(obj, f.name), f.metadata.get("unit"))


def now() -> str:
    """The `created` attribute: UTC time, ISO 8601."""
    return datetime.datetime.now(datetime.timezone.utc).isoformat()


def commit(tmp: Path | str, path: Path | str) -> Path:
    """Make the complete file `tmp` the file `path`: fsync, then an atomic rename (same folder).

    The one way a finished file gets its final name in this project: a reader sees either
    the previous file or the complete new one, never a partial one.
    """
    with open(tmp, "rb") as fh:
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    _fsync_folder(Path(path).parent)  # the rename itself on disk: else a crash may undo it
    return Path(path)


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError as exc:  # file systems that cannot sync a folder
        if exc.errno not in (errno.EINVAL, errno.EBADF, errno.ENOTSUP, errno.EROFS):
            raise
    finally:
        os.close(fd)


#: Temporary names are ".NAME.tmpPID" beside NAME (pipelines.folder removes those a killed
#: run left behind).
TEMP_MARK = ".tmp"


def temp_path(path: Path | str) -> Path:
    """The temporary name a file is written under before `commit` makes it `path`."""
    path = Path(path)
    return path.with_name(f".{path.name}{TEMP_MARK}{os.getpid()}")


@contextmanager
def atomic_output(path: Path | str):
    """Yield a temporary path next to `path`; on success `commit` it to `path`, on any
    failure (an exception, a full disk, Ctrl-C) remove it and leave a previous `path` untouched."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_path(path)
    try:
        yield tmp
        commit(tmp, path)
    finally:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass


def open_in_place(path: Path | str, mode: str) -> h5py.File:
    """h5py.File(path, mode) for a file written in place (a partial file a run appends to or
    starts over), never through a link into another file (a folder copied with `cp -al`, a
    hard link, or `cp -as`, a symbolic one): "w" removes the old file first (h5py would
    truncate it in place), "r+" and "a" replace a symbolic link, or a file with other hard
    links, by a copy of its content first (what it holds is resumed from, its target left
    as it was); a broken symbolic link is removed (else "a" would create its target). A file
    another program holds open (a viewer: HDF5's lock refuses "r+" and "a") is replaced by a
    copy of its content too, which the run appends to; the other program reads on what it
    had (else the stage would start over and lose the points on disk)."""
    path = Path(path)

    def own_copy():  # its content in a file (inode) of its own, under its name
        with atomic_output(path) as tmp:
            shutil.copyfile(path, tmp)

    if mode == "w" or (path.is_symlink() and not path.exists()):
        path.unlink(missing_ok=True)
    elif path.is_file() and (path.is_symlink() or os.stat(path).st_nlink > 1):
        own_copy()
    try:
        return h5py.File(path, mode)
    except BlockingIOError:  # "unable to lock file": the lock is on the inode, a copy has none
        if mode not in ("r+", "a") or not path.is_file():
            raise
        own_copy()
        return h5py.File(path, mode)


# --- checksums ------------------------------------------------------------------------
#: Root attribute holding {dataset path: checksum} as JSON.
CHECKSUMS = "checksums"
#: A dataset's checksum: the CRC-32 of each 16 MiB block of its bytes, hashed together with
#: its dtype and shape by sha256. The damage looked for is accidental (bytes overwritten, a
#: file cut short, a dataset deleted), which CRC-32 finds as surely as HDF5's, zip's and PNG's
#: own checks do: every burst of up to 32 bits, and other damage to a block with probability
#: 1 - 2^-32. It is the fastest check in the standard library: on the 1.28 GB fem.h5 of the
#: default scene 1.0 s against 1.9 s for sha256 (blake2b: 3x slower than sha256) with the
#: 2-core machine shared (README). Blocks are hashed in threads (zlib and hashlib release the
#: GIL) straight from a read-only memory map of the file (no copy).
_BLOCK = 1 << 24
_ALGORITHM = "crc32x16M"


def _block_digest(buf: memoryview, start: int, size: int, mapping: mmap.mmap | None = None) -> bytes:
    part = buf[start:start + size]
    try:
        return zlib.crc32(part).to_bytes(4, "little") + len(part).to_bytes(8, "little")
    finally:
        part.release()
        if mapping is not None:
            # Out of this process's resident set again (the pages stay in the page cache; a
            # neighbouring block that shares the first page reads it back in): else the
            # whole file counts in the stage's peak memory, +1.3 GB for the fem.h5 of a
            # 590 000-dof blade.
            lo = start - start % mmap.PAGESIZE
            mapping.madvise(mmap.MADV_DONTNEED, lo, start + size - lo)


def _datasets(h5: h5py.File) -> dict:
    found = {}
    h5.visititems(lambda name, obj: found.__setitem__(name, obj) if isinstance(obj, h5py.Dataset) else None)
    return found


def _prefixed(parts) -> bytes:
    """The byte strings `parts` joined, each after its length (8 bytes, little-endian): no
    two different lists give the same bytes."""
    return b"".join(len(b).to_bytes(8, "little") + b for b in parts)


def _content_bytes(ds: h5py.Dataset) -> np.ndarray:
    """The bytes of a decoded dataset, (n,) uint8. Variable-length strings (object arrays)
    are hashed by their text, each item prefixed by its length: the bytes of an object
    array are pointers into this process's memory, different on every read."""
    if not ds.size:
        return np.zeros(0, np.uint8)
    data = ds[()]
    if ds.dtype.kind == "O":
        items = np.asarray(data, dtype=object).reshape(-1)
        return np.frombuffer(_prefixed(item if isinstance(item, bytes) else str(item).encode() for item in items),
                             np.uint8)
    return np.ascontiguousarray(data).reshape(-1).view(np.uint8)


#: Key of `checksums` that covers, beside the datasets, every attribute of every group and
#: dataset (strings of a result are attributes, as are a CSR matrix's shape and the units)
#: and the list of groups and datasets (one added or removed). Files of earlier versions
#: lack it: their datasets alone are verified.
LAYOUT = "/layout"


def _attr_bytes(value) -> bytes:
    if isinstance(value, str):
        return b"s" + value.encode("utf-8", "surrogatepass")
    if isinstance(value, bytes):
        return b"b" + bytes(value)
    if isinstance(value, h5py.Empty):
        return b"e" + str(value.dtype).encode()
    arr = np.asarray(value)
    head = f"{arr.dtype.str}{arr.shape}".encode()
    if arr.dtype.kind == "O":
        return b"o" + head + _prefixed(_attr_bytes(item) for item in arr.reshape(-1))
    return b"a" + head + np.ascontiguousarray(arr).tobytes()


def _layout_checksum(h5: h5py.File) -> str:
    """The hash of the names of every group and dataset and of every attribute (but the
    root's `checksums`), in sorted order."""
    objs = {"": h5}
    h5.visititems(lambda name, obj: objs.__setitem__(name, obj))
    h = hashlib.sha256(b"layout")

    def put(b: bytes):
        h.update(_prefixed([b]))

    for name in sorted(objs):
        obj = objs[name]
        put((b"D" if isinstance(obj, h5py.Dataset) else b"G" if isinstance(obj, h5py.Group) else b"?")
            + name.encode("utf-8", "surrogatepass"))
        for key in sorted(obj.attrs.keys()):
            if name == "" and key == CHECKSUMS:
                continue
            put(key.encode("utf-8", "surrogatepass"))
            put(_attr_bytes(obj.attrs[key]))
    return f"{_ALGORITHM}:{h.hexdigest()}"


def dataset_checksums(h5: h5py.File, names=None) -> dict:
    """{dataset path: checksum} of the datasets of an open file (all, or those named), and
    with all (or when named) the LAYOUT entry: its attributes and list of groups and datasets.

    A checksum covers the dataset's dtype, shape and its bytes in C order. Contiguous
    datasets (the large ones: K, M, modes) are read in place from a memory map of the file,
    without HDF5 decoding; chunked or compressed ones are decoded (they are small here).
    Flush a file open for writing first. Raises KeyError for a name that is not a dataset.
    """
    found = _datasets(h5)
    names = sorted(found) + [LAYOUT] if names is None else list(names)
    layout = {LAYOUT: _layout_checksum(h5)} if LAYOUT in names else {}
    names = [n for n in names if n != LAYOUT]
    with open(h5.filename, "rb") as fh:
        size = os.fstat(fh.fileno()).st_size
        whole = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) if size else None
        views = [memoryview(whole) if whole is not None else memoryview(b"")]
        try:
            jobs = {}
            for name in names:
                if name not in found:
                    raise KeyError(name)
                ds = found[name]
                n = ds.id.get_storage_size()
                offset = ds.id.get_offset() if ds.chunks is None else None
                if offset is not None and ds.dtype.kind != "O" and n == ds.size * ds.dtype.itemsize:
                    buf, start, mapping = views[0], offset, whole
                else:
                    data = _content_bytes(ds)
                    n = data.size
                    buf, start, mapping = memoryview(data).cast("B"), 0, None
                    views.append(buf)
                jobs[name] = [(buf, start + k, min(_BLOCK, n - k), mapping) for k in range(0, n, _BLOCK)]
            with ThreadPoolExecutor(max(1, min(8, len(os.sched_getaffinity(0))))) as pool:
                futures = {name: [pool.submit(_block_digest, *job) for job in blocks] for name, blocks in jobs.items()}
                out = {}
                for name, fs in futures.items():
                    ds = found[name]
                    h = hashlib.sha256(f"{ds.dtype.str}{ds.shape}".encode())
                    for f in fs:
                        h.update(f.result())
                    out[name] = f"{_ALGORITHM}:{h.hexdigest()}"
            out.update(layout)
            return out
        finally:
            for v in views:
                v.release()
            if whole is not None:
                whole.close()


def add_checksums(path: Path | str) -> None:
    """Write the checksums of every dataset of the closed file `path` into its root attribute."""
    with h5py.File(path, "r") as h5:
        sums = dataset_checksums(h5)
    with h5py.File(path, "r+") as h5:
        h5.attrs[CHECKSUMS] = json.dumps(sums, sort_keys=True)


def verify(path: Path | str) -> str | None:
    """None when every dataset that `path` records a checksum for is there with those bytes;
    else why the file cannot be trusted, in words (no checksums, a dataset missing or
    changed, unreadable)."""
    path = Path(path)
    try:
        with h5py.File(path, "r") as h5:
            text = h5.attrs.get(CHECKSUMS)
            if text is None:
                return "no checksums to verify it by (written by an older version)"
            try:
                sums = json.loads(text)
            except ValueError:
                return "damaged: its checksum list is unreadable"
            if any(not str(v).startswith(f"{_ALGORITHM}:") for v in sums.values()):
                return "no checksums this version can verify (written by another version)"
            found = _datasets(h5)
            missing = sorted(set(sums) - set(found) - {LAYOUT})
            if missing:
                more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
                return f"damaged: dataset '{missing[0]}' is missing{more}"
            now = dataset_checksums(h5, sums)
    except (OSError, RuntimeError, ValueError, KeyError) as exc:
        return f"damaged: unreadable ({first_line(exc)})"
    bad = [name for name in sorted(sums) if name != LAYOUT and now[name] != sums[name]]
    if not bad and LAYOUT in sums and now[LAYOUT] != sums[LAYOUT]:
        return ("damaged: an attribute, or the list of groups and datasets, changed on disk "
                "(checksum mismatch)")
    if bad:
        more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
        return f"damaged: dataset '{bad[0]}' changed on disk (checksum mismatch){more}"
    return None


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (HDF5's run over many lines)."""
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def write_artifact(path: Path | str, result, *, stage: str, scene_text: str = "",
                   inputs_hash: str = "", extra_attrs: dict | None = None) -> Path:
    """Write a dataclass `result` to `path` atomically (see atomic_output).

    Root attributes: stage, units, scene, inputs_hash, code_version, created, checksums
    (see add_checksums), and extra_attrs.
    """
    path = Path(path)
    with atomic_output(path) as tmp:
        with h5py.File(tmp, "w") as h5:
            h5.attrs["stage"] = stage
            h5.attrs["units"] = UNITS_SI
            h5.attrs["scene"] = scene_text
            h5.attrs["inputs_hash"] = inputs_hash
            h5.attrs["code_version"] = code_version()
            h5.attrs["created"] = now()
            h5.attrs["dataclass"] = type(result).__qualname__
            for k, v in (extra_attrs or {}).items():
                h5.attrs[k] = v
            _write_fields(h5, result)
        add_checksums(tmp)
    return path


def _read_value(node, hint):
    if isinstance(node, h5py.Group):
        if node.attrs.get("sparse") == "csr":
            shape = tuple(int(s) for s in node.attrs["shape"])
            return sp.csr_matrix((node["data"][()], node["indices"][()], node["indptr"][()]), shape=shape)
        if node.attrs.get("dict"):
            out = {k: _read_value(node[k], None) for k in node}
            out.update({k: (v.decode() if isinstance(v, bytes) else v)
                        for k, v in node.attrs.items() if k != "dict"})
            return out
        cls = _dataclass_of(hint)
        if cls is None:
            raise ArtifactError(f"group {node.name} has no known type to read into")
        return _read_fields(node, cls)
    val = node[()]
    if isinstance(val, np.ndarray):
        return val
    return val.item() if isinstance(val, np.generic) else val


def _dataclass_of(hint):
    if hint is None:
        return None
    if dataclasses.is_dataclass(hint):
        return hint
    for a in typing.get_args(hint):
        if dataclasses.is_dataclass(a):
            return a
    return None


def _read_fields(group: h5py.Group, cls):
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name in group:
            kwargs[f.name] = _read_value(group[f.name], hints.get(f.name))
        elif f.name in group.attrs:
            v = group.attrs[f.name]
            kwargs[f.name] = v.decode() if isinstance(v, bytes) else v
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ArtifactError(f"{group.file.filename}: field '{f.name}' of {cls.__name__} is missing "
                                f"(in {group.name}); the file is incomplete or from another version")
    return cls(**kwargs)


def read_artifact(path: Path | str, cls):
    """Read a file written by `write_artifact` back into an instance of `cls`.

    Raises ArtifactError when the file is missing, unreadable, or lacks a field of `cls`
    that has no default.
    """
    path = Path(path)
    if not path.is_file():
        raise ArtifactError(f"artifact not found: {path}")
    try:
        with h5py.File(path, "r") as h5:
            return _read_fields(h5, cls)
    except OSError as exc:
        raise ArtifactError(f"cannot read artifact {path}: {exc}") from exc


def _root_attrs(path: Path | str) -> tuple[dict, str]:
    """(root attributes, "") of an HDF5 file; ({}, why) where HDF5 cannot read it (not HDF5,
    damaged, cut short); ({}, "") where there is no such file."""
    try:
        with h5py.File(path, "r") as h5:
            return {k: (v.decode() if isinstance(v, bytes) else v) for k, v in h5.attrs.items()}, ""
    except FileNotFoundError:
        return {}, ""
    except (OSError, RuntimeError, ValueError, KeyError) as exc:
        return {}, first_line(exc)


def read_attrs(path: Path | str) -> dict:
    """Root attributes of an artifact (empty dict if the file is missing or unreadable)."""
    return _root_attrs(path)[0]


def read_failure(path: Path | str) -> str:
    """Why HDF5 cannot open `path` ("" when it can, or when there is no such file): a partial
    file that a run killed while writing it left cut, which the stage then starts over from
    scratch (read_attrs alone reads it as a file of other inputs, without a word)."""
    return _root_attrs(path)[1]


def is_current(path: Path | str, inputs_hash: str) -> bool:
    """True if `path` is a complete artifact made from exactly these inputs."""
    return Path(path).is_file() and read_attrs(path).get("inputs_hash") == inputs_hash
