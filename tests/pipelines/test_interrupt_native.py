"""Ctrl-C while a native library initialises: held to the end of its import
(pipelines.errors.deferred_ctrl_c), and an exception chained to a KeyboardInterrupt is an
interruption (exit 130 with the run's interruption line), not a failure.

Found by sending SIGINT 0.27-0.31 s after "[fem] running" on the coarse scene (the subprocess
method of test_interrupt.py, 0.2-1.6 s swept): dolfinx's module initialisation was cut, and
the run ended on "ImportError: initialization failed" (exit 1; once in CI on PETSc's SEGV
handler, exit 59). Those windows are ~0.05 s wide; the tests here put the signal in them on
purpose, in this process.
"""
from __future__ import annotations

import os
import signal
import time

import pytest

from coarse_runs import clone
from pipelines.cli import main
from pipelines.errors import after_ctrl_c, deferred_ctrl_c


@pytest.fixture
def fresh_sigint():
    """SIGINT as an interactive run has it: Python's default handler, not blocked in this
    thread; restored after. A test suite started as a background job of a non-interactive
    shell (`cmd &` in a script) inherits SIGINT ignored, and Python then installs no handler
    of its own: the first test here failed on "DID NOT RAISE" there and nowhere else."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    mask = signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    yield
    signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    signal.signal(signal.SIGINT, old)


def test_ctrl_c_inside_the_block_is_answered_after_it(fresh_sigint):
    done = []
    with pytest.raises(KeyboardInterrupt):  # the test process's handler: Python's default
        with deferred_ctrl_c():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # the handler runs between bytecodes: here, if it were not held
            done.append("the import went on")
    assert done == ["the import went on"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_the_handler_in_place_answers_it_once(fresh_sigint):
    """The run's own handler (pipelines.cli._stop_children: end the workers, then
    KeyboardInterrupt) is the one called, once, after the block."""
    calls = []
    old = signal.signal(signal.SIGINT, lambda signum, frame: calls.append(signum))
    try:
        with deferred_ctrl_c():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            assert calls == []
        assert calls == [signal.SIGINT]
        with deferred_ctrl_c():  # no Ctrl-C: nothing called
            pass
        assert calls == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, old)


def test_chained_exceptions_are_told_apart():
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise ImportError("initialization failed") from exc
    except ImportError as exc:
        assert after_ctrl_c(exc)
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise RuntimeError("during the handling")  # context, not cause
    except RuntimeError as exc:
        assert after_ctrl_c(exc)
    assert not after_ctrl_c(ImportError("no module named dolfinx"))
    loop = ValueError("a cycle")
    loop.__context__ = ValueError("back")
    loop.__context__.__context__ = loop
    assert not after_ctrl_c(loop)


def test_a_stage_whose_import_ctrl_c_cut_is_an_interruption(coarse_run, tmp_path, monkeypatch, capsys):
    """The fem stage raising what a cut import raises: the run reports the interruption (the
    stage, what was kept) and exits 130; fem.h5 is not written."""
    import fem.analysis

    def cut(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise ImportError("initialization failed") from exc

    scene = clone(coarse_run[1], tmp_path, copy=("mesh.h5",))
    for name in ("fem.h5", "rom.h5"):
        (tmp_path / name).unlink(missing_ok=True)
    monkeypatch.setattr(fem.analysis, "analyse_blade", cut)
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "fem", "--quiet"]) == 130
    err = capsys.readouterr().err
    assert "interrupted during stage fem; kept: mesh.h5;" in err and "ImportError" not in err
    assert not (tmp_path / "fem.h5").exists()


def _run_script(script: str, *args: str):
    """script run by this interpreter in a fresh process, the project on its path."""
    import subprocess
    import sys

    from coarse_runs import ROOT

    return subprocess.run([sys.executable, "-c", script, *args], cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)


FORKED = """
import multiprocessing as mp, os, signal, sys
from pipelines import cli
cli._install_fork_hooks()
signal.signal(signal.SIGINT, signal.SIG_IGN if sys.argv[1] == "ignored" else cli._stop_children)
ctx = mp.get_context("fork")
q = ctx.Queue()
names = {signal.SIG_DFL: "default", signal.SIG_IGN: "ignored"}
p = ctx.Process(target=lambda: q.put(names.get(signal.getsignal(signal.SIGINT), "a handler")))
p.start()
print(q.get())
p.join()
"""


@pytest.mark.parametrize("parent, child", [("answered", "default"), ("ignored", "ignored")])
def test_a_forked_worker_ignores_ctrl_c_when_the_run_does(parent, child):
    """A run answering Ctrl-C lets its forked workers die of it (the run reports); a run
    that ignores it (a background job of a non-interactive shell) keeps them ignoring it:
    else a SIGINT to its group ended the workers and not the run, which then failed on "a
    worker process ... ended without an answer (killed, perhaps for lack of memory)"."""
    r = _run_script(FORKED, parent)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == child


IN_FORK = """
import multiprocessing as mp, os, signal, sys, time
import logging
# a SIGINT that lands inside the fork's callbacks (as in logging's, which releases its lock there)
os.register_at_fork(after_in_parent=lambda: os.kill(os.getpid(), signal.SIGINT))
from pipelines import cli
cli._install_fork_hooks()
signal.signal(signal.SIGINT, cli._stop_children)
p = mp.get_context("fork").Process(target=time.sleep, args=(30,))
t = time.perf_counter()
try:
    p.start()
    while time.perf_counter() - t < 5.0:
        time.sleep(0.01)
    print("not interrupted")
except KeyboardInterrupt:
    print(f"interrupted after {time.perf_counter() - t:.2f} s")
p.join(10)
print("worker ended" if p.exitcode is not None else "worker alive")
"""


def test_ctrl_c_inside_a_fork_still_interrupts_the_run():
    """A SIGINT answered inside a fork's callbacks (a pool starting a worker) used to raise
    its KeyboardInterrupt there, where CPython prints and drops it: the run went on until the
    watcher's 3-s grace, or ended with exit 0 before it. It now interrupts the run at once
    (within the re-delivery delay), and the worker being started is ended."""
    r = _run_script(IN_FORK)
    assert r.returncode == 0, r.stderr
    first, second = r.stdout.split("\n")[:2]
    assert first.startswith("interrupted after "), r.stdout + r.stderr
    assert float(first.split()[2]) < 1.0
    assert second == "worker ended"
    assert "Exception ignored" not in r.stderr
