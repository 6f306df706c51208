"""What a run tells its user while it works and when it ends.

A live status line (rich, Debian's python3-rich) on every long step: shown only when
standard output is a terminal and the run is not --quiet, so logs and pipes get plain lines.
At the end, a table of the stages: wall time, peak memory, computed or reused and why.
"""
from __future__ import annotations

import resource
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class StageRecord:
    """One row of the run's summary.

    stage: its name. action: "computed", "reused", "interrupted" or "failed". why: the reason (for a computed stage
    which inputs changed; for a reused one "up to date"). wall: s. peak_memory: largest
    resident set of this process or of a child it waited for during the stage, bytes
    (0 when unknown).
    """

    stage: str
    action: str
    why: str
    wall: float
    peak_memory: int


class _PeakMemory:
    """Peak resident memory over a stretch of the run.

    Linux keeps the process's high-water mark (VmHWM) and lets a process reset it
    (/proc/self/clear_refs, "5"), so each stage gets its own peak; children (the rendering
    process, the time-integration workers) count through getrusage once reaped.
    """

    _STATUS = Path("/proc/self/status")

    def __enter__(self):
        from fem.memory import return_freed_memory

        return_freed_memory()  # what earlier stages freed is not this stage's peak (fem.memory)
        try:
            Path("/proc/self/clear_refs").write_text("5")
            self._reset = True
        except OSError:
            self._reset = False
        self._children0 = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        return self

    def __exit__(self, *exc):
        own = 0
        try:
            for line in self._STATUS.read_text().splitlines():
                if line.startswith("VmHWM:"):
                    own = int(line.split()[1]) * 1024
        except (OSError, ValueError, IndexError):
            own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
        children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        child = children * 1024 if children > self._children0 else 0
        self.peak = max(own, child)
        return False


class Progress:
    """Live status lines and the end-of-run summary.

    quiet: print nothing but errors (no live line, no stage lines, no summary).
    live: draw the live line (default: when standard output is a terminal).
    """

    def __init__(self, quiet: bool = False, live: bool | None = None):
        from rich.console import Console

        self.quiet = quiet
        # A terminal only when standard output is one: rich alone would also believe FORCE_COLOR
        # or TTY_COMPATIBLE (set by some CI systems) and draw the live line into a log file.
        self.console = Console(highlight=False, force_terminal=None if _stdout_is_terminal() else False)
        self.live = (not quiet) and (self.console.is_terminal if live is None else live)
        self.records: list[StageRecord] = []
        self._said: set[str] = set()

    def log(self, text: str) -> None:
        """A line of the run's log (suppressed by --quiet)."""
        if not self.quiet:
            print(text, flush=True)

    def log_once(self, text: str) -> None:
        """log(text) unless this run logged it already through log_once: a fact several stages
        depend on (the ROM's friction lock for the scene's mu) is said by the first of them
        the run computes, and by a later one only when that one was reused."""
        if text not in self._said:
            self._said.add(text)
            self.log(text)

    def warn(self, text: str) -> None:
        """A warning: on standard error, --quiet or not (a valid run that may be pointless)."""
        print(f"bladerub: warning: {text}", file=sys.stderr, flush=True)

    @contextmanager
    def step(self, label: str, total: int | None = None):
        """A long step with a live line; yields update(text=None, completed=None).

        total: number of items (e.g. speeds of a sweep): the line then shows a bar, the count
        and the time left. text: what is being done now (e.g. the current Omega and step).
        """
        if not self.live:
            yield lambda text=None, completed=None: None
            return
        from rich.progress import (BarColumn, MofNCompleteColumn, Progress as RichProgress, SpinnerColumn,
                                   TextColumn, TimeElapsedColumn, TimeRemainingColumn)

        columns = [SpinnerColumn(), TextColumn("[bold]{task.fields[label]}"), TextColumn("{task.fields[text]}")]
        if total:
            columns[2:2] = [BarColumn(), MofNCompleteColumn(), TimeRemainingColumn()]
        columns.append(TimeElapsedColumn())
        with RichProgress(*columns, console=self.console, transient=True) as bar:
            task = bar.add_task(label, total=total, label=label, text="")

            def update(text=None, completed=None):
                kw = {}
                if text is not None:
                    kw["text"] = text
                if completed is not None:
                    kw["completed"] = completed
                bar.update(task, **kw)

            yield update

    @contextmanager
    def stage(self, name: str):
        """Time and measure one stage; the caller sets .action and .why on the yielded record."""
        rec, mem = _Pending(), None
        t0 = time.perf_counter()
        try:
            with _PeakMemory() as mem:
                yield rec
        except KeyboardInterrupt:
            rec.action = "interrupted"
            raise
        except BaseException:
            rec.action = "failed"
            raise
        finally:
            self.records.append(StageRecord(name, rec.action, rec.why, time.perf_counter() - t0,
                                            getattr(mem, "peak", 0)))

    def summary(self) -> None:
        """The table of the run's stages."""
        if self.quiet or not self.records:
            return
        from rich.table import Table

        table = Table(title="run summary", title_justify="left")
        for col, just in (("stage", "left"), ("wall", "right"), ("peak memory", "right"), ("", "left")):
            table.add_column(col, justify=just)
        for r in self.records:
            mem = f"{r.peak_memory / 1e9:.2f} GB" if r.peak_memory else "-"  # decimal, as the guard's
            table.add_row(r.stage, _duration(r.wall), mem, f"{r.action}: {r.why}")
        self.console.print(table)


class _Pending:
    action = "computed"
    why = ""


def _stdout_is_terminal() -> bool:
    try:
        return sys.stdout.isatty()
    except (AttributeError, ValueError):  # replaced by an object without it, or closed
        return False


def _duration(seconds: float) -> str:
    """A wall time, s, as the summary shows it: "0.4 s", "1 min 05 s", "26 h 03 min" (hours
    past a day too). Rounded to 0.1 s before the unit is chosen: 59.96 s is "1 min 00 s"."""
    if round(seconds, 1) < 60:
        return f"{seconds:.1f} s"
    m, s = divmod(int(round(seconds)), 60)
    return f"{m} min {s:02d} s" if m < 60 else f"{m // 60} h {m % 60:02d} min"
