"""A stage's work per contact treatment, one process per treatment at once.

The treatments of a stage (the hbm stage's NFRCs, the validation stage's points) are
independent computations of one core each: on a machine with two cores or more they run at
once, one process each, and the stage takes the longer one's time instead of their sum.
One after the other in the run's own process on one core, or under an MPI launcher (the
stage runs on rank 0 there, and its children would not be MPI ranks).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable

from pipelines.stages.base import Context


@dataclass(frozen=True)
class Reporter:
    """Where one treatment's work speaks: log(text) a line of the run's log, warn(text) a
    warning, update(text) its live line."""

    log: Callable[[str], None]
    warn: Callable[[str], None]
    update: Callable[[str], None]


def treatment_workers(n_treatments: int) -> int:
    """Processes for n treatments: one per core, at most one per treatment; 1 under an MPI
    launcher."""
    from pipelines.parallel import world

    if world() is not None:
        return 1
    return max(1, min(n_treatments, len(os.sched_getaffinity(0))))


def run_treatments(ctx: Context, items: dict, work: Callable, stage: str, noun: str,
                   workers: int | None = None) -> dict:
    """{key: work(ctx, item, Reporter)} for every key: item of `items`, in key order.

    work: a module-level function (a process pickles it) whose result pickles. stage: the
    live line's title ("hbm dlft + rl"); noun: what one process computes, in the message of
    one that dies ("the rl NFRC process ended without an answer"). workers: processes (default
    treatment_workers; 1 runs them one after the other in this process). Each computes on one
    BLAS thread either way. A treatment that fails does not stop the others: every one ends,
    then the first failure in key order is raised.
    """
    from threadpoolctl import threadpool_limits

    workers = min(treatment_workers(len(items)) if workers is None else workers, len(items))
    if workers <= 1:
        ctx.lend_cores(len(os.sched_getaffinity(0)) - 1)  # this process computes on one (Stage.busy_cores)
        out, failed = {}, None
        for key, item in items.items():
            # one BLAS thread, as in a process of its own: the same numbers on any number of cores
            with ctx.progress.step(f"{stage} {key}", None) as update, threadpool_limits(limits=1, user_api="blas"):
                try:
                    out[key] = work(ctx, item, Reporter(ctx.log, ctx.progress.warn, update))
                except Exception as exc:  # the next treatments still run, as in processes of their own; Ctrl-C stops all
                    failed = failed or exc
        if failed is not None:
            raise failed
        return out
    return _run_at_once(ctx, items, work, stage, noun)


def _process(scene, out, hashes: dict, inputs: dict, key, item, work: Callable, messages) -> None:
    """Target of a treatment's process: work as run_treatments calls it in the run's own
    process; every word of it, and its end ("done" with the result, or "error" with the
    exception), goes to the parent through `messages`."""
    import signal

    from threadpoolctl import threadpool_limits

    from pipelines.progress import Progress

    # Ctrl-C reaches the whole process group: the parent speaks for the run, this process
    # just ends (what it keeps on disk is flushed as it goes)
    signal.signal(signal.SIGINT, signal.SIG_DFL)

    def send(kind: str):
        return lambda payload: messages.put((key, kind, payload))

    try:
        ctx = Context(scene, out, Progress(quiet=True), hashes, inputs)
        with threadpool_limits(limits=1, user_api="blas"):  # one process per core
            result = work(ctx, item, Reporter(send("log"), send("warn"), send("update")))
        messages.put((key, "done", result))
    except BaseException as exc:  # noqa: BLE001 - handed to the parent, which raises it
        try:
            messages.put((key, "error", exc))
        except Exception:  # an exception that does not pickle
            messages.put((key, "error", RuntimeError(f"{type(exc).__name__}: {exc}")))


def _run_at_once(ctx: Context, items: dict, work: Callable, stage: str, noun: str) -> dict:
    """Every item's work in a process of its own; the parent shows their live lines and log,
    waits for all of them and then raises the first failure in key order."""
    import queue

    from hbm.processes import process_context
    from pipelines.child import ChildDied

    mp = process_context()
    messages = mp.Queue()
    procs = {key: mp.Process(target=_process, args=(ctx.scene, ctx.out, ctx.hashes, ctx.inputs, key, item, work,
                                                    messages), daemon=True, name=f"{stage} {key}")
             for key, item in items.items()}
    ctx.log(f"  {' and '.join(procs)} at once, one process each")
    for p in procs.values():  # before the live line's thread starts (fork copies one thread)
        p.start()
    # the cores these processes leave free, now that they are forked (Stage.busy_cores)
    ctx.lend_cores(max(0, len(os.sched_getaffinity(0)) - len(procs)))
    lines = {key: "starting" for key in procs}
    ended: dict = {}  # key -> ("done", result) or ("error", exception)

    def line() -> str:
        """Each treatment's last words, then how far the stage started beside this one is."""
        parts = [f"{k}: {'ended' if k in ended else t}" for k, t in lines.items()]
        beside = ctx.beside()
        return "; ".join(parts + ([beside] if beside else []))

    try:
        with ctx.progress.step(stage + " " + " + ".join(procs), None) as update:
            while len(ended) < len(procs):
                try:
                    key, kind, payload = messages.get(timeout=0.5)
                except queue.Empty:
                    for key, p in procs.items():  # killed or crashed without a word
                        if key not in ended and not p.is_alive() and messages.empty():
                            ended[key] = ("error", ChildDied(f"the {key} {noun} process ended without an answer "
                                                             f"(exit code {p.exitcode})"))
                            ctx.lend_cores(1)
                    update(line())  # the stage beside moves between the treatments' words
                    continue
                if kind == "update":
                    lines[key] = payload
                    update(line())
                elif kind == "log":
                    ctx.log(payload)
                elif kind == "warn":
                    ctx.progress.warn(payload)
                else:
                    ended[key] = (kind, payload)
                    ctx.lend_cores(1)  # its core, to the stage started beside this one
                    update(line())
    finally:
        for p in procs.values():
            if p.is_alive() and len(ended) < len(procs):  # interrupted: the others end too
                p.terminate()
            p.join()
    for key in items:
        if ended[key][0] == "error":
            raise ended[key][1]
    return {key: ended[key][1] for key in items}
