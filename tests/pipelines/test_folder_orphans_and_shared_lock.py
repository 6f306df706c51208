"""The orphan cleanup keeps what is not a killed run's temporary file; a lock file shared by
hard links with two other folders still lets one run at a time into a folder."""
import os
import subprocess
import sys

import pytest

from pipelines import folder
from pipelines.errors import FolderBusy


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", ""])
    p.wait()
    return p.pid


def test_only_temporary_files_of_dead_processes_are_removed(tmp_path):
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        dead = _dead_pid()
        # the user's, the last one named as a temporary file but for its leading dot
        users = [".notes.tmp", ".tmp", ".bashrc.tmpl", ".draft.tmp12a", ".x.tmp.bak", f"rom.h5.tmp{dead}"]
        for name in users:
            (tmp_path / name).write_text("the user's")
        (tmp_path / f".bladerub-probe.tmp{live.pid}").write_bytes(b"")  # a second run's probe, in flight
        (tmp_path / f".rom.h5.tmp{dead}").write_bytes(b"12345")
        removed = folder.remove_orphans(tmp_path)
        assert removed == [(f".rom.h5.tmp{dead}", 5)]
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted(users + [f".bladerub-probe.tmp{live.pid}"])
        assert all((tmp_path / n).read_text() == "the user's" for n in users)
    finally:
        live.kill()
        live.wait()


def test_a_run_that_opened_a_lock_file_shared_by_three_folders_late_is_refused(tmp_path, monkeypatch):
    """Folder a copied twice with `cp -al` (b, c): run B opened b's lock file (still shared) just
    before run A replaced it with b's own and took that; B must not replace A's lock file."""
    a, b, c = (tmp_path / n for n in "abc")
    for d in (a, b, c):
        d.mkdir()
    (a / folder.LOCK).write_bytes(b"")
    os.link(a / folder.LOCK, b / folder.LOCK)
    os.link(a / folder.LOCK, c / folder.LOCK)
    early = os.open(b / folder.LOCK, os.O_RDWR)  # B's open, before A's replacement
    real = folder._open_lock
    with folder.hold(b, "run A in b"):
        lock_a = os.stat(b / folder.LOCK).st_ino
        first = [early]
        monkeypatch.setattr(folder, "_open_lock", lambda p: first.pop() if first else real(p))
        with pytest.raises(FolderBusy, match="run A in b"):
            with folder.hold(b, "run B in b"):
                pass
        assert os.stat(b / folder.LOCK).st_ino == lock_a
