"""Checksums cover attributes and the list of groups and datasets; a rename is synced to the
folder. Small synthetic files only."""
import json
import os
import shutil
import stat
from dataclasses import dataclass, field

import h5py
import numpy as np
import pytest
import scipy.sparse as sp

import pipelines.artifacts as art


@dataclass(frozen=True)
class Branch:
    omega: np.ndarray = field(metadata={"unit": "rad/s"})
    K: sp.csr_matrix = field(metadata={"unit": "N/m"})
    kind: str = "isola"


def _write(path):
    return art.write_artifact(path, Branch(np.linspace(1900.0, 2000.0, 11), sp.eye(4, format="csr") * 3.0,
                                           "isola"), stage="t", inputs_hash="h")


def _replace_bytes(path, old: bytes, new: bytes):
    raw = bytearray(path.read_bytes())
    i = raw.find(old)
    assert i >= 0 and raw.find(old, i + 1) < 0
    raw[i:i + len(old)] = new
    path.write_bytes(bytes(raw))


def _set_attr(path, obj, key, value):
    with h5py.File(path, "r+") as h5:
        (h5[obj] if obj else h5).attrs[key] = value


def _add_dataset(path):
    with h5py.File(path, "r+") as h5:
        h5["omega_extra"] = np.zeros(3)


def _drop_group_attr(path):
    with h5py.File(path, "r+") as h5:
        del h5["K"].attrs["sparse"]


@pytest.mark.parametrize("damage", [
    lambda p: _replace_bytes(p, b"isola", b"isolb"),            # a flipped byte in a string field
    lambda p: _set_attr(p, "K", "shape", np.array([4, 3])),     # a CSR matrix's shape
    lambda p: _set_attr(p, "omega", "unit", "Hz"),              # a unit
    lambda p: _set_attr(p, "", "stage", "u"),                   # a root attribute
    _add_dataset,                                               # a dataset added
    _drop_group_attr,                                           # an attribute removed
])
def test_a_changed_attribute_or_an_added_dataset_is_damage(tmp_path, damage):
    good = _write(tmp_path / "a.h5")
    assert art.verify(good) is None
    bad = tmp_path / "b.h5"
    shutil.copyfile(good, bad)
    damage(bad)
    assert art.verify(bad) == ("damaged: an attribute, or the list of groups and datasets, changed on disk "
                               "(checksum mismatch)")
    assert art.verify(good) is None


def test_a_file_of_an_earlier_version_still_verifies_by_its_datasets(tmp_path):
    path = _write(tmp_path / "a.h5")
    with h5py.File(path, "r+") as h5:  # as written before the layout entry: datasets only
        sums = {k: v for k, v in json.loads(h5.attrs[art.CHECKSUMS]).items() if k in h5}
        h5.attrs[art.CHECKSUMS] = json.dumps(sums, sort_keys=True)
    assert art.verify(path) is None
    with h5py.File(path, "r+") as h5:
        h5["omega"][3] += 1.0
    assert art.verify(path) == "damaged: dataset 'omega' changed on disk (checksum mismatch)"


def test_the_rename_is_synced_to_the_folder(tmp_path, monkeypatch):
    """After os.replace the folder itself is fsynced: else a crash can leave the old name."""
    synced = []
    real = os.fsync

    def spy(fd):
        if stat.S_ISDIR(os.fstat(fd).st_mode):
            synced.append((os.fstat(fd).st_ino, (tmp_path / "x.bin").exists()))
        real(fd)

    monkeypatch.setattr(os, "fsync", spy)
    with art.atomic_output(tmp_path / "x.bin") as tmp:
        tmp.write_bytes(b"done")
    assert synced == [(os.stat(tmp_path).st_ino, True)]


def _rewrite_omega(path, convert):
    """Dataset 'omega' written again as convert(its array), attributes kept: the same bytes
    under another shape or dtype leave the layout (names and attributes) as it was."""
    with h5py.File(path, "r+") as h5:
        old = h5["omega"]
        data, attrs = convert(old[()]), dict(old.attrs)
        del h5["omega"]
        h5["omega"] = data
        h5["omega"].attrs.update(attrs)


@pytest.mark.parametrize("convert", [
    lambda a: a.reshape(-1, 1),   # (11,) -> (11, 1): the same bytes, another shape
    lambda a: a.view(np.int64),   # the same bytes read as integers
])
def test_the_same_bytes_under_another_shape_or_dtype_are_damage(tmp_path, convert):
    path = _write(tmp_path / "a.h5")
    before = np.array(h5py.File(path, "r")["omega"][()]).tobytes()
    _rewrite_omega(path, convert)
    with h5py.File(path, "r") as h5:
        assert np.array(h5["omega"][()]).tobytes() == before  # what the damage keeps
    assert art.verify(path) == "damaged: dataset 'omega' changed on disk (checksum mismatch)"


def _set_checksums(path, text):
    with h5py.File(path, "r+") as h5:
        if text is None:
            del h5.attrs[art.CHECKSUMS]
        else:
            h5.attrs[art.CHECKSUMS] = text


def _two_sums_of_another_algorithm(path):
    with h5py.File(path, "r") as h5:
        sums = json.loads(h5.attrs[art.CHECKSUMS])
    return json.dumps({k: "sha1:" + v.split(":", 1)[1] if k == "omega" else v for k, v in sums.items()})


def _delete(path, *names):
    with h5py.File(path, "r+") as h5:
        for name in names:
            del h5[name]


@pytest.mark.parametrize("damage, verdict", [
    (lambda p: _set_checksums(p, None), "no checksums to verify it by (written by an older version)"),
    (lambda p: _set_checksums(p, "{omega: 1"), "damaged: its checksum list is unreadable"),
    (lambda p: _set_checksums(p, _two_sums_of_another_algorithm(p)),
     "no checksums this version can verify (written by another version)"),
    (lambda p: _delete(p, "omega"), "damaged: dataset 'omega' is missing"),
    (lambda p: _delete(p, "omega", "K/indptr"), "damaged: dataset 'K/indptr' is missing (and 1 more)"),
    (lambda p: p.write_bytes(p.read_bytes()[:400]), "damaged: unreadable ("),
])
def test_each_reason_a_file_cannot_be_trusted_is_its_own(tmp_path, damage, verdict):
    path = _write(tmp_path / "a.h5")
    assert art.verify(path) is None
    damage(path)
    got = art.verify(path)
    # a cut file: HDF5's own words follow in the parenthesis
    assert got.startswith(verdict) if verdict.endswith("(") else got == verdict


def test_two_changed_datasets_are_counted(tmp_path):
    path = _write(tmp_path / "a.h5")
    with h5py.File(path, "r+") as h5:
        h5["omega"][0] += 1.0
        h5["K/data"][0] += 1.0
    assert art.verify(path) == "damaged: dataset 'K/data' changed on disk (checksum mismatch) (and 1 more)"
