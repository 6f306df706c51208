"""Why a run stops: each failure the user can act on is one of these, printed as one line.

`exit_code` is what `bladerub` returns: 2 when nothing could start (bad scene, unusable
output folder, a refusal before computing), 1 when a started computation failed (a write
that failed, a stage that raised), 130 after Ctrl-C (the shell's code for SIGINT).
"""
from __future__ import annotations


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
