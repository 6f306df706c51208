"""HDF5 artifacts: exact round trip, provenance attributes, atomic replacement."""
import os
from dataclasses import dataclass, field

import h5py
import numpy as np
import pytest
import scipy.sparse as sp

import pipelines.artifacts as art
from rom.model import RomModel
from support import standin_rom


@dataclass(frozen=True)
class Inner:
    a: np.ndarray = field(metadata={"unit": "m"})
    label: str = "x"


@dataclass(frozen=True)
class Outer:
    K: sp.csr_matrix = field(metadata={"unit": "N/m"})
    big: np.ndarray = field(metadata={"unit": "rad/s"})
    inner: Inner
    scalar: float = field(default=0.0, metadata={"unit": "m^3"})
    optional: np.ndarray | None = None


def _sample():
    rng = np.random.default_rng(1)
    K = sp.random(50, 50, density=0.1, random_state=2, format="csr")
    return Outer(K=K, big=rng.standard_normal((300, 20)), inner=Inner(a=np.arange(6.0).reshape(2, 3), label="tip"),
                 scalar=4.8e-5)


def test_round_trip_is_identical_with_units_and_provenance(tmp_path):
    obj = _sample()
    path = art.write_artifact(tmp_path / "x.h5", obj, stage="test", scene_text="[material]\nE = 1\n",
                              inputs_hash="abc")
    back = art.read_artifact(path, Outer)
    assert (back.K != obj.K).nnz == 0 and back.K.shape == obj.K.shape
    assert np.array_equal(back.big, obj.big) and back.big.dtype == obj.big.dtype
    assert np.array_equal(back.inner.a, obj.inner.a) and back.inner.label == "tip"
    assert back.scalar == obj.scalar and back.optional is None
    attrs = art.read_attrs(path)
    for key in ("units", "scene", "inputs_hash", "code_version", "created", "stage"):
        assert key in attrs, key
    assert attrs["scene"].startswith("[material]") and attrs["inputs_hash"] == "abc"
    with h5py.File(path) as h5:
        assert h5["big"].attrs["unit"] == "rad/s"
        assert h5["K"].attrs["unit"] == "N/m"
        assert h5["inner/a"].attrs["unit"] == "m"
    assert art.is_current(path, "abc") and not art.is_current(path, "abd")


def test_rom_model_round_trip(tmp_path):
    rom = standin_rom()
    back = art.read_artifact(art.write_artifact(tmp_path / "rom.h5", rom, stage="rom"), RomModel)
    for name in ("K", "M", "C", "rho", "theta", "frames", "frequencies"):
        assert np.array_equal(getattr(back, name), getattr(rom, name)), name
    assert back.recovery is None


class Boom(Exception):
    pass


def test_interrupted_write_leaves_previous_good_file(tmp_path, monkeypatch):
    path = tmp_path / "fem.h5"
    art.write_artifact(path, _sample(), stage="test", inputs_hash="good")
    before = path.read_bytes()

    real = art._write_fields

    def explode(group, obj):  # dies half-way through writing the datasets
        group.create_dataset("partial", data=np.zeros(3))
        raise Boom()

    monkeypatch.setattr(art, "_write_fields", explode)
    with pytest.raises(Boom):
        art.write_artifact(path, _sample(), stage="test", inputs_hash="new")
    monkeypatch.setattr(art, "_write_fields", real)
    assert path.read_bytes() == before
    assert art.is_current(path, "good")
    assert [p.name for p in tmp_path.iterdir()] == ["fem.h5"], "temporary file left behind"


def test_killed_process_leaves_no_valid_file(tmp_path):
    """A process killed mid-write (no Python cleanup) leaves only a hidden temporary name,
    which carries the writer's pid: the next run's orphan sweep removes it (its writer is
    gone), where a file of a live writer would be kept."""
    import subprocess
    import sys
    code = f"""
import os, numpy as np, sys
sys.path.insert(0, {str(os.getcwd())!r})
import pipelines.artifacts as art
print(os.getpid(), flush=True)
real = art._write_fields
def die(group, obj):
    group.create_dataset('partial', data=np.zeros(10))
    group.file.flush()
    os._exit(9)
art._write_fields = die
from dataclasses import dataclass
@dataclass(frozen=True)
class A:
    x: object
art.write_artifact({str(tmp_path / 'mesh.h5')!r}, A(np.zeros(3)), stage='mesh', inputs_hash='h')
"""
    r = subprocess.run([sys.executable, "-c", code], cwd=os.getcwd(), capture_output=True, text=True)
    assert r.returncode == 9
    assert not (tmp_path / "mesh.h5").exists()
    assert not art.is_current(tmp_path / "mesh.h5", "h")
    from pipelines.folder import remove_orphans

    left = [p.name for p in tmp_path.iterdir()]
    assert left == [f".mesh.h5{art.TEMP_MARK}{int(r.stdout)}"]
    assert [name for name, _ in remove_orphans(tmp_path)] == left and not any(tmp_path.iterdir())


def test_missing_artifact_error_names_path(tmp_path):
    with pytest.raises(art.ArtifactError, match="fem.h5"):
        art.read_artifact(tmp_path / "fem.h5", Outer)


def test_text_datasets_verify_across_reads_and_changes_are_caught(tmp_path):
    # variable-length strings are pointers in memory: the checksum must cover their text
    path = tmp_path / "t.h5"
    with h5py.File(path, "w") as h5:
        h5["kind"] = np.array(["fold", "period doubling", "branch point"], dtype=h5py.string_dtype())
        h5["note"] = "a scalar text"
    art.add_checksums(path)
    assert art.verify(path) is None
    assert art.verify(path) is None  # a second read decodes to other pointers
    with h5py.File(path, "r+") as h5:
        h5["kind"][1] = "neimark-sacker"
    assert "kind" in art.verify(path)


def test_a_file_started_over_in_place_leaves_its_hard_links_alone(tmp_path):
    """open_in_place(path, "w") on a partial file hard-linked into another folder (`cp -al`):
    the run starts its own file over, the other folder's keeps its bytes (h5py's "w" alone
    truncates the shared inode)."""
    import h5py

    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    with h5py.File(tmp_path / "a" / "nfrc.partial.h5", "w") as h5:
        h5["omega"] = np.arange(5.0)
    os.link(tmp_path / "a" / "nfrc.partial.h5", tmp_path / "b" / "nfrc.partial.h5")
    kept = (tmp_path / "a" / "nfrc.partial.h5").read_bytes()
    with art.open_in_place(tmp_path / "b" / "nfrc.partial.h5", "w") as h5:
        h5["omega"] = np.zeros(2)
    assert (tmp_path / "a" / "nfrc.partial.h5").read_bytes() == kept
    with h5py.File(tmp_path / "b" / "nfrc.partial.h5", "r") as h5:
        assert h5["omega"].shape == (2,)


@pytest.mark.parametrize("mode", ["a", "r+"])
def test_a_partial_file_another_program_holds_open_is_appended_to_in_a_copy(tmp_path, mode):
    """A partial file open in another program (a viewer reading the points so far: HDF5 locks
    the file, and h5py then refuses "a" and "r+" with 'unable to lock file'): the run goes on
    in a copy of its content, which replaced it, where the stage used to say it could not be
    read and start over, its points lost. The other program reads on what it had."""
    import subprocess
    import sys

    import h5py

    path = tmp_path / "nfrc_dlft.partial.h5"
    with h5py.File(path, "w") as h5:
        h5.create_dataset("omega", data=np.arange(5.0), maxshape=(None,))
    viewer = subprocess.Popen([sys.executable, "-c", (
        "import sys, h5py; h5 = h5py.File(sys.argv[1], 'r'); print('open', flush=True); sys.stdin.readline(); "
        "print(h5['omega'].shape[0], flush=True)"), str(path)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert viewer.stdout.readline() == "open\n"
        with pytest.raises(BlockingIOError):  # the lock this is about
            h5py.File(path, mode)
        with art.open_in_place(path, mode) as h5:
            h5["omega"].resize((7,))
            h5["omega"][5:] = [5.0, 6.0]
        viewer.stdin.write("\n")
        viewer.stdin.flush()
        assert viewer.stdout.readline() == "5\n"  # its own file, as it was
    finally:
        viewer.kill()
        viewer.wait()
    with h5py.File(path, "r") as h5:
        np.testing.assert_array_equal(h5["omega"][()], np.arange(7.0))
