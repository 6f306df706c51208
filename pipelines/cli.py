"""Command line: `bladerub run SCENE.toml --out DIR [--until STAGE] [--force] [--yes] [--quiet]
[--dry-run] [--set SECTION.KEY=VALUE ...]`, `bladerub show SCENE.toml [--set ...]` (the resolved scene,
every default written out), `bladerub render SCENE.toml --out DIR [--modes N] [--set ...]`.

Every failure is one line on standard error, and the exit code says which kind:
0 done; 2 nothing was computed (a bad scene, table or artifact, an unusable or busy output
folder, a run refused as too large for the machine or the disk, a stage asked for before the
one it needs); 1 a stage failed while computing (e.g. a write on a full disk; the line says
what was kept); 130 interrupted by Ctrl-C (the line says what was kept and how to go on).

`mpirun -n N bladerub run ...` runs the FEM stage distributed over N ranks and shares the
time-integration sweep's speeds among them; rank 0 does the rest and all the talking
(pipelines.parallel).
"""
from __future__ import annotations

import signal
import sys

if "--multiprocessing-fork" in sys.orig_argv:  # (spawn restores sys.argv to the parent's)
    # A spawned worker of a run (multiprocessing imports __main__ again in it): Ctrl-C ends
    # it without a traceback of its own, from here on; the run reports for it.
    signal.signal(signal.SIGINT, signal.SIG_DFL)

# numba's CPU model and OpenBLAS's kernels are chosen for the host when hbm is imported, and
# OpenBLAS's only before numpy is first imported (hbm.openblas): hence here, before any of it
import hbm  # noqa: E402,F401
import argparse  # noqa: E402
import multiprocessing  # noqa: E402
import os  # noqa: E402
import shlex  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from pipelines.artifacts import ArtifactError  # noqa: E402
from pipelines.errors import Refused, RunError  # noqa: E402
from pipelines.scene import SceneError, load_scene, resolved_toml, scene_warnings  # noqa: E402


def _command(args, *extra: str) -> str:
    """The command line to give again to go on (no --force: what this run finished is kept)."""
    sets = [w for item in getattr(args, "set", []) for w in ("--set", item)]
    words = ["bladerub", args.command, str(args.scene), "--out", str(args.out), *sets, *extra]
    return " ".join(shlex.quote(w) for w in words)


def _repeated_sets(items) -> list[str]:
    """A warning for each key set more than once with --set (the last one is used), once the
    scene took them all (so each item is well formed)."""
    given: dict = {}
    for item in items:
        lhs = item.split("=", 1)[0].strip()
        section, _, key = lhs.rpartition(".")  # a renamed key was refused by load_scene
        given.setdefault((section, key), []).append(item)
    return [f"{f'[{sec}] {key}' if sec else key} is set {len(items)} times on the command line "
            f"({', '.join('--set ' + i for i in items)}): the last, --set {items[-1]}, is used"
            for (sec, key), items in given.items() if len(items) > 1]


def _warn(text: str) -> None:
    print(f"bladerub: warning: {text}", file=sys.stderr, flush=True)


def _cmd_run(args) -> int:
    from contextlib import nullcontext

    from pipelines.folder import removed_if_unused
    from pipelines.progress import Progress
    from pipelines.runner import run_scene
    from pipelines.stages import STAGES

    from pipelines.parallel import is_root, world

    scene = load_scene(args.scene, args.set)
    root = is_root(world())
    progress = Progress(quiet=args.quiet or not root)
    for text in [*_repeated_sets(args.set), *scene_warnings(scene)] if root else ():  # under mpirun, once
        progress.warn(text)
    if args.dry_run:
        from pipelines.runner import dry_run

        for line in dry_run(scene, Path(args.out), until=args.until, force=args.force) if root else ():
            print(line)
        return 0
    extra = ([] if args.until == STAGES[-1] else ["--until", args.until]) + (["--yes"] if args.yes else [])
    try:
        # a run refused before computing leaves no folder behind (rank 0 makes it)
        with removed_if_unused(Path(args.out)) if root else nullcontext():
            run_scene(scene, Path(args.out), until=args.until, force=args.force, progress=progress, yes=args.yes,
                      command=_command(args, *extra))
    finally:
        progress.summary()
    return 0


def _cmd_show(args) -> int:
    scene = load_scene(args.scene, args.set)
    for text in _repeated_sets(args.set):
        _warn(text)
    header = f"# {scene.path} resolved" + "".join(f" --set {o}" for o in args.set)
    print(resolved_toml(scene, header), end="")
    return 0


def _cmd_render(args) -> int:
    from pipelines.progress import Progress
    from pipelines.runner import render_modes

    from pipelines.parallel import is_root, world

    scene = load_scene(args.scene, args.set)
    if args.modes is not None and args.modes > scene.fem.n_modes:
        raise Refused(f"--modes {args.modes}: fem.h5 holds the first [fem] n_modes = {scene.fem.n_modes} modes; "
                      f"ask for at most {scene.fem.n_modes} (or raise [fem] n_modes: the fem stage then "
                      "computes more)")
    if is_root(world()):
        for text in _repeated_sets(args.set):
            _warn(text)
    paths = render_modes(scene, Path(args.out), n_modes=args.modes, progress=Progress(quiet=True),
                         command=_command(args))
    if is_root(world()):
        for p in paths:
            print(p)
    return 0


def _failures() -> tuple:
    """Errors of a stage's own making that the user can act on: one line, exit 1."""
    from hbm.processes import WorkerDied  # pipelines.child.ChildDied too
    from mesh.blade import MeshingError
    from pipelines.render import RenderError

    return MeshingError, WorkerDied, RenderError


#: the main thread's fork in progress (depth of nested before/after hooks), and whether a
#: SIGINT was answered inside it (see _stop_children)
_FORKING = {"depth": 0, "missed": False}
#: delay before a SIGINT missed inside a fork is raised again: long enough for the main
#: thread to leave the fork's last callback, where the new KeyboardInterrupt would be lost too
REDELIVERY_DELAY = 0.05


def _stop_children(signum, frame):
    """SIGINT: end this run's worker processes (a process pool waits for its running tasks
    otherwise), then stop where the run is with KeyboardInterrupt.

    Inside a fork of the main thread (a pool starting a worker) the handler runs in one of
    the fork's callbacks (logging's releases its lock there), where CPython prints an
    exception ("Exception ignored in ...") and drops it: the Ctrl-C was lost, and the run
    went on until the watcher's grace ended it, or finished with exit 0. There it only notes
    the signal, which _fork_ends raises again once the fork is over."""
    for child in multiprocessing.active_children():
        child.terminate()
    if _FORKING["depth"]:
        _FORKING["missed"] = True
        return
    raise KeyboardInterrupt


def _fork_begins():
    if threading.current_thread() is threading.main_thread():
        _FORKING["depth"] += 1


def _fork_ends():
    if threading.current_thread() is not threading.main_thread():
        return
    _FORKING["depth"] -= 1
    if not _FORKING["depth"] and _FORKING["missed"]:
        _FORKING["missed"] = False
        # from another thread, a little later: raised now it would run in this callback
        timer = threading.Timer(REDELIVERY_DELAY, os.kill, (os.getpid(), signal.SIGINT))
        timer.daemon = True
        timer.start()


_FORK_HOOK = False


def _install_fork_hooks() -> None:
    """The at-fork hooks of a run, once per process: SIGINT in a forked child
    (_silent_forked_child) and a SIGINT that lands inside the parent's fork (_stop_children).
    Registered after logging's (imported here first): the before hooks run in reverse order
    and the after ones in order, so _FORKING["depth"] spans every other callback."""
    global _FORK_HOOK
    import logging  # noqa: F401  (its hooks first: see above)

    if not _FORK_HOOK:
        os.register_at_fork(before=_fork_begins, after_in_parent=_fork_ends, after_in_child=_silent_forked_child)
        _FORK_HOOK = True


def _silent_forked_child():
    # A forked worker ends on Ctrl-C without a traceback of its own: the parent reports. A
    # run that ignores SIGINT (a background job of a non-interactive shell) keeps its workers
    # ignoring it too: else a SIGINT to the group would end the workers and not the run,
    # which would then report them dead ("killed, perhaps for lack of memory").
    _FORKING.update(depth=0, missed=False)
    if signal.getsignal(signal.SIGINT) is _stop_children:
        signal.signal(signal.SIGINT, signal.SIG_DFL)


class _CtrlC:
    """Ctrl-C is answered within GRACE seconds, whatever the main thread is doing.

    Python runs its SIGINT handler in the main thread between two bytecodes: not while a C
    library holds it (a sparse factorisation, a mesher), nor when the cleanup after
    KeyboardInterrupt hangs (CPython 3.11's process pool waits forever on a pipe to workers
    that are gone). The signal's wake-up byte (signal.set_wakeup_fd, written by the C-level
    handler at once) wakes this watcher; if the run has not ended GRACE s later, it prints
    the run's interruption line (pipelines.runner.interruption) and ends the process (exit
    130). What it leaves is safe: finished artifacts were renamed into place complete, NFRC
    points are flushed one by one, and the temporary file of a write in progress is removed
    by the next run in that folder.
    """

    GRACE = 3.0

    def __init__(self):
        self.reported = False
        self.finished = False
        self._r, self._w = os.pipe()
        os.set_blocking(self._w, False)
        self._old = signal.set_wakeup_fd(self._w, warn_on_full_buffer=False)
        threading.Thread(target=self._watch, name="bladerub-ctrl-c", daemon=True).start()

    def _watch(self):
        while True:
            try:
                data = os.read(self._r, 64)
            except OSError:
                return
            if not data:
                return
            if signal.SIGINT not in data:
                continue
            time.sleep(self.GRACE)
            if self.finished:
                return
            if not self.reported:
                from pipelines import runner

                os.write(2, f"bladerub: {runner.interruption(detailed=False)}\n".encode())
            os._exit(130)

    def close(self):
        self.finished = True
        signal.set_wakeup_fd(self._old)
        os.close(self._w)  # the watcher reads end-of-file and returns


def _given(what: str):
    """argparse type of a path argument: an empty one ("" from an unset shell variable) is
    refused, where Path("") would silently be the current folder."""
    def path(text: str) -> Path:
        if not text:
            raise argparse.ArgumentTypeError(f"empty: give {what}")
        return Path(text)
    return path


def _modes(text: str) -> int:
    """argparse type of `render --modes`: a count of modes to draw, at least 1."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{n}: give at least 1 (the number of modes to draw)")
    return n


def main(argv: list[str] | None = None) -> int:
    from pipelines.stages import STAGES

    parser = argparse.ArgumentParser(prog="bladerub", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene's stages in order, skipping those already up to date")
    scene_file = _given("a scene file (TOML)")
    out_folder = _given("a folder (it is created if missing)")
    run.add_argument("scene", type=scene_file, help="scene file (TOML)")
    run.add_argument("--out", type=out_folder, required=True, metavar="DIR",
                     help="output folder for artifacts and figures (created if missing)")
    run.add_argument("--until", default=STAGES[-1], choices=STAGES, help="last stage to run (default: all)")
    run.add_argument("--force", action="store_true", help="recompute stages even if up to date")
    run.add_argument("--yes", action="store_true",
                     help="run even what the size guard or the free-space check refuses")
    run.add_argument("--quiet", action="store_true", help="print errors and warnings only (no live line, no summary)")
    run.add_argument("-n", "--dry-run", action="store_true",
                     help="say what a run would compute and why, and its estimates; compute and write nothing")
    run.set_defaults(func=_cmd_run)
    ren = sub.add_parser("render", help="render mode shapes off-screen to PNG (needs a current fem.h5 in --out)")
    ren.add_argument("scene", type=scene_file, help="scene file (TOML)")
    ren.add_argument("--out", type=_given("a folder holding a current fem.h5"), required=True, metavar="DIR",
                     help="output folder of `bladerub run SCENE --out DIR --until fem`")
    ren.add_argument("--modes", type=_modes, default=None, metavar="N",
                     help="number of modes to draw, 1 to [fem] n_modes (default: [render] n_modes)")
    ren.set_defaults(func=_cmd_render)
    show = sub.add_parser("show", help="print the resolved scene (every key, defaults and --set included) as TOML")
    show.add_argument("scene", type=scene_file, help="scene file (TOML)")
    show.set_defaults(func=_cmd_show)
    for p in (run, show, ren):
        p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                       help="override a scene value (repeatable), validated like the file: "
                            "--set material.E=110e9 --set contact.mu=0.1 --set hbm.methods=dlft")
    args = parser.parse_args(argv)
    if not _FORK_HOOK:
        _install_fork_hooks()
        # After Ctrl-C a spawn-context pool (after dolfinx loaded MPI) may be left to the
        # watcher's exit, and multiprocessing's resource tracker, which then unlinks the pool's
        # semaphores as it should, would also warn about them: its flags come from ours.
        sys.warnoptions.append("ignore::UserWarning:multiprocessing.resource_tracker")
    interactive = (signal.getsignal(signal.SIGINT) is signal.default_int_handler
                   and threading.current_thread() is threading.main_thread())
    ctrl_c = None
    if interactive:
        signal.signal(signal.SIGINT, _stop_children)
        ctrl_c = _CtrlC()
    from pipelines.parallel import RankFailed, is_root, world

    try:
        return args.func(args)
    except RunError as exc:
        if ctrl_c is not None:
            ctrl_c.reported = True
        print(f"bladerub: {'error: ' if exc.exit_code != 130 else ''}{exc}", file=sys.stderr)
        return exc.exit_code
    except (SceneError, ArtifactError, ValueError, FileNotFoundError, RankFailed) as exc:
        if is_root(world()):  # under MPI every rank has the error: rank 0 says it once
            print(f"bladerub: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        if ctrl_c is not None:
            ctrl_c.reported = True
        print("bladerub: interrupted before anything was computed", file=sys.stderr)
        return 130
    except OSError as exc:
        print(f"bladerub: error: {os.strerror(exc.errno) if exc.errno else exc}"
              f"{' ' + str(exc.filename) if exc.filename else ''}", file=sys.stderr)
        return 1
    except RuntimeError as exc:
        if not isinstance(exc, _failures()):
            raise  # a bug: its traceback is what a report needs
        print(f"bladerub: error: {exc}", file=sys.stderr)
        return 1
    finally:
        if interactive:
            ctrl_c.close()
            signal.signal(signal.SIGINT, signal.default_int_handler)


if __name__ == "__main__":
    sys.exit(main())
