"""Why a run stops: each failure the user can act on is one of these, printed as one line.

`exit_code` is what `bladerub` returns: 2 when nothing could start (bad scene, unusable
output folder, a refusal before computing), 1 when a started computation failed (a write
that failed, a stage that raised), 130 after Ctrl-C (the shell's code for SIGINT).
"""
from __future__ import annotations

import contextlib
import signal
import threading


def after_ctrl_c(exc: BaseException) -> bool:
    """Whether an exception comes from Ctrl-C: a KeyboardInterrupt, or chained (as cause or
    context) to one. A C extension whose module initialisation Ctrl-C interrupts raises
    "ImportError: initialization failed" from it."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


@contextlib.contextmanager
def deferred_ctrl_c():
    """Hold Ctrl-C until the block ends, then answer it as the handler in place would have.

    For the import of a native library whose module initialisation runs Python code:
    Ctrl-C there raises KeyboardInterrupt halfway through the library's own set-up
    (dolfinx's, which starts MPI and PETSc: the run then ended on "ImportError:
    initialization failed", exit 1, and once in CI on PETSc's SEGV handler, exit 59). The
    block is short (dolfinx: ~0.3 s); the run's watcher (pipelines.cli) still ends a run that
    does not answer within its grace. Outside the main thread it does nothing (signal
    handlers are the main thread's)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list = []
    old = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(frame))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
    if caught:
        if callable(old):
            old(signal.SIGINT, caught[0])
        elif old == signal.SIG_DFL:
            signal.raise_signal(signal.SIGINT)


class RunError(RuntimeError):
    """A run that cannot start or go on; str(self) is the one line shown to the user."""

    exit_code = 1


class FolderError(RunError):
    """The output folder (or a path in it) cannot be used: a file, read-only, busy, full."""

    exit_code = 2


class FolderBusy(FolderError):
    """Another live run holds the output folder's lock."""


class Refused(RunError):
    """A run refused before computing: too large for this machine (size guard), a stage
    asked for before the one it needs, or an argument it cannot honour (`render --modes`
    beyond the modes fem.h5 holds)."""

    exit_code = 2


class StageFailed(RunError):
    """A stage that started and failed (e.g. a write that hit a full disk)."""

    exit_code = 1


class Interrupted(RunError):
    """Ctrl-C: what was kept and how to resume."""

    exit_code = 130
