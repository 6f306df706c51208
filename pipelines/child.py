"""Run one function in a fresh child process, so that Ctrl-C is answered at once.

Some libraries hold the process in C++ for minutes and take SIGINT over (gmsh 4.8 sets it to
the default action on import: Ctrl-C would kill the run with no word). In a child, the
parent stays in Python: Ctrl-C raises KeyboardInterrupt in the parent at once, which kills
the child and goes on with the run's usual interruption (one line, what was kept). The
child ends silently on SIGINT; its exceptions come back to the parent as they were.
"""
from __future__ import annotations

import multiprocessing
import signal

from hbm.processes import WorkerDied


class ChildDied(WorkerDied):
    """The child process ended without an answer (killed, crashed)."""


def _child(conn, func, args, kwargs):
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # the parent speaks for the run
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    try:
        result = ("ok", func(*args, **kwargs))
    except BaseException as exc:  # noqa: BLE001 - handed to the parent, which re-raises it
        result = ("error", exc)
    try:
        conn.send(result)
    except Exception as exc:  # an exception that does not pickle
        conn.send(("error", RuntimeError(f"{type(result[1]).__name__}: {result[1]} ({exc})")))
    conn.close()


def call_in_child(func, *args, **kwargs):
    """func(*args, **kwargs) in a spawned process (a fresh interpreter: no threads or locks
    of this one); returns its result or raises its exception. The arguments and the result
    must pickle."""
    ctx = multiprocessing.get_context("spawn")
    receive, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, func, args, kwargs), daemon=True)
    # SIGINT stays blocked in the child until it has set its own disposition (the mask is
    # inherited), so a Ctrl-C while it starts cannot print a traceback from it
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        proc.start()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
    send.close()
    try:
        try:
            status, value = receive.recv()
        except EOFError:
            proc.join()
            raise ChildDied(f"{getattr(func, '__name__', func)} ended without an answer "
                            f"(exit code {proc.exitcode})") from None
        proc.join()
    except BaseException:
        if proc.is_alive():
            proc.kill()
            proc.join()
        raise
    finally:
        receive.close()
    if status == "error":
        raise value
    return value
