"""The output folder: usable, held by one run at a time, cleared of what killed runs left.

A run holds an exclusive `flock` on `.bladerub.lock` in its folder for as long as it runs;
the lock file says who holds it (pid, command, start time), so a second run in the same
folder is refused with that line. The kernel drops the lock when its process ends, however
it ends (kill -9 included), so a stale lock file never blocks anyone; a lock file that a
copy made with hard links shares with another folder is replaced by the folder's own.
A run that ends in an error puts the lock file back as it found it (none where there was
none, the last run's record otherwise), and a folder `prepare` made for it that is still
empty is removed (removed_if_unused): a run refused before computing changes nothing.
Temporary files (".NAME.tmpPID", pipelines.artifacts.temp_path) found by the run that holds
the lock were left by a run that died while writing: nothing else can be writing them, and
they are removed.
"""
from __future__ import annotations

import datetime
import errno
import fcntl
import json
import os
import re
import socket
import time
from contextlib import contextmanager
from pathlib import Path

from pipelines.artifacts import TEMP_MARK, atomic_output
from pipelines.errors import FolderBusy, FolderError

LOCK = ".bladerub.lock"


def _why(exc: OSError) -> str:
    return os.strerror(exc.errno) if exc.errno else str(exc)


def prepare(out: Path) -> Path:
    """Create `out` if needed and check that files can be made in it; returns it.

    Raises FolderError (one line) when --out names a file, or the folder cannot be created
    or written (read-only file system, no permission, a path through a file).
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise FolderError(f"--out {out} is a file, not a folder: give a folder (it is created if missing)")
    if out.is_symlink() and not out.exists():  # mkdir would say "File exists"
        raise FolderError(f"--out {out} is a link to {os.readlink(out)}, which does not exist: create that folder, "
                          "or give another")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FolderError(f"cannot create the output folder {out}: {_why(exc)}") from None
    probe = out / f".bladerub-probe{TEMP_MARK}{os.getpid()}"
    try:
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise FolderError(f"cannot write in the output folder {out}: {_why(exc)}") from None
    return out


def missing_folders(out: Path) -> list[Path]:
    """`out` and those of its parents that do not exist (what `prepare` would create),
    deepest first."""
    out = Path(out)
    return [p for p in (out, *out.parents) if not os.path.lexists(p)]


@contextmanager
def removed_if_unused(out: Path):
    """Remove, when the block raises, the folders of `out` that were missing before it and
    are still empty (a run refused before computing leaves no folder behind). A folder that
    holds anything, another run's files included, stays."""
    made = missing_folders(out)
    try:
        yield
    except BaseException:
        for p in made:  # deepest first: a parent empties only once its child is gone
            try:
                p.rmdir()
            except OSError:  # not empty (something was written), or gone already
                break
        raise


def _holder(fd: int, wait_s: float = 1.0) -> str:
    """Who holds the lock, from the lock file. The holder writes itself just after taking the
    lock: a run that lost the race by microseconds reads again for up to wait_s."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            info = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
        except (OSError, ValueError):
            info = {}
        if info or time.monotonic() > deadline:
            break
        time.sleep(0.02)
    if not info:
        return "another process"
    return (f"pid {info.get('pid', '?')} on {info.get('host', '?')} (`{info.get('command', '?')}`, "
            f"started {info.get('started', '?')})")


def holder(out: Path) -> str:
    """Who holds the folder's lock now ("" when no run does), without touching it: read from
    the kernel's table of flock locks (/proc/locks, Linux), not by trying the lock, which for
    an instant would refuse a run starting then."""
    path = Path(out) / LOCK
    try:
        st = os.stat(path)
        table = Path("/proc/locks").read_text()
    except OSError:
        return ""
    me = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    for line in table.splitlines():
        fields = line.split()
        # "1: FLOCK  ADVISORY  WRITE 25458 fe:00:10412076 0 EOF" (blocked waiters read "->")
        if len(fields) >= 6 and fields[1] == "FLOCK" and fields[5] == me:
            return _holder_of(path)
    return ""


def _open_lock(path: Path) -> int:
    try:
        return os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise FolderError(f"cannot create the lock file {path}: {_why(exc)}") from None


def _take(fd: int, path: Path, out: Path, shared: bool = False) -> None:
    """flock fd (exclusive, non-blocking) or raise FolderBusy naming the holder."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
            raise FolderError(f"cannot lock {path}: {_why(exc)}") from None
        where = " (a lock file shared by hard links with another folder: that folder's run, maybe)" if shared else ""
        raise FolderBusy(f"{out} is in use by another run{where}: {_holder_of(path)}; wait for it to end, "
                         "or give another --out") from None


def _holder_of(path: Path) -> str:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return "another process"
    try:
        return _holder(fd)
    finally:
        os.close(fd)


def _names(fd: int, path: Path) -> bool:
    """Whether `path` still names the file open as fd."""
    st = os.fstat(fd)
    try:
        cur = os.stat(path)
    except FileNotFoundError:
        return False
    return (st.st_dev, st.st_ino) == (cur.st_dev, cur.st_ino)


@contextmanager
def hold(out: Path, command: str):
    """Hold the folder's lock for the duration of the block, or raise FolderBusy naming the
    process that holds it. command: the command line shown to a second run.

    A folder copied with hard links (`cp -al`, the cheap way to branch a run whose FEM file
    is gigabytes) shares its lock file with the original: the lock is then taken on that
    file, which keeps out a run in either folder, while it is replaced by a private one.

    When the block raises, the lock file is put back as it was found, while the lock is
    still held (a run that opened it meanwhile finds it unlinked or rewritten and opens the
    folder's lock file again): removed if this call made it, its former content otherwise.
    A finished run's lock file stays, naming that run."""
    path = Path(out) / LOCK
    made = not os.path.lexists(path)
    for _ in range(8):
        fd = _open_lock(path)
        shared = os.fstat(fd).st_nlink > 1
        _take(fd, path, out, shared)
        if shared and not _names(fd, path):
            os.close(fd)  # replaced since it was opened (by another run of this folder): again
            continue
        if shared:
            try:
                with atomic_output(path) as tmp:
                    tmp.write_bytes(b"")
            except OSError as exc:
                raise FolderError(f"cannot replace {path}, shared by hard links with another folder: "
                                  f"{_why(exc)}") from None
            finally:
                os.close(fd)
            continue
        if _names(fd, path):
            break
        os.close(fd)  # replaced or removed since it was opened (by the above in another run): again
    else:
        raise FolderError(f"cannot lock {path}: the lock file keeps being replaced")
    try:
        found = os.pread(fd, os.fstat(fd).st_size, 0)
        info = {"pid": os.getpid(), "host": socket.gethostname(), "command": command,
                "started": datetime.datetime.now().astimezone().isoformat(timespec="seconds")}
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(info).encode(), 0)
        yield
    except BaseException:
        _put_back(fd, path, None if made else found)
        raise
    finally:
        os.close(fd)  # releases the lock


def _put_back(fd: int, path: Path, content: bytes | None) -> None:
    """Undo a failed run's lock file, held as fd: unlink it (content None) or write its
    former content back. Best effort: the error that ended the run is the one to report."""
    try:
        if content is None:
            if _names(fd, path):
                path.unlink()
        else:
            os.ftruncate(fd, 0)
            os.pwrite(fd, content, 0)
    except OSError:
        pass


#: ".NAME.tmpPID" (pipelines.artifacts.temp_path), and nothing else: not a user's ".notes.tmp".
_TEMP_NAME = re.compile(r"\..+" + re.escape(TEMP_MARK) + r"([0-9]+)\Z", re.S)


def _alive(pid: int) -> bool:
    """Whether another process `pid` runs (its temporary file may be in the writing: a
    second run's probe of `prepare`, which does not hold the lock)."""
    if pid == os.getpid() or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):  # none, or no pid at all
        return False
    except PermissionError:  # another user's
        return True
    return True


def remove_orphans(out: Path) -> list[tuple[str, int]]:
    """Remove the temporary files that runs killed while writing left in `out` (and figures/);
    call it only while holding the lock. A file whose process still runs is kept.
    Returns [(name, bytes)] of those removed."""
    removed = []
    for folder in (Path(out), Path(out) / "figures"):
        if not folder.is_dir():
            continue
        for p in folder.iterdir():
            m = _TEMP_NAME.match(p.name)
            if m and p.is_file() and not p.is_symlink() and not _alive(int(m.group(1))):
                size = p.stat().st_size
                try:
                    p.unlink()
                except OSError:
                    continue
                removed.append((str(p.relative_to(out)), size))
    return removed


def check_path(path: Path) -> None:
    """Raise FolderError when something that is not a regular file sits where an artifact goes."""
    if path.is_symlink() and not path.exists():
        raise FolderError(f"{path} is a broken symbolic link: remove it, or give another --out")
    if path.exists() and not path.is_file():
        kind = "a folder" if path.is_dir() else "not a regular file"
        raise FolderError(f"{path} is {kind}, where the run writes its artifact: move it away, or give another --out")
