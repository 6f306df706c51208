"""Runs a scene's stages in order, skipping what is current, and redraws what is missing.

An output is current when its file carries the inputs hash of exactly what it depends on
(pipelines.stages.base) and every dataset still matches the checksum written with it
(pipelines.artifacts.verify). Otherwise the stage computes it, and the run says why: no
artifact, which inputs changed, which dataset is damaged, or --force.

Before anything is computed, the whole run is planned and checked: the folder is usable and
locked for this run (pipelines.folder), temporary files of killed runs are removed, no
artifact path is a folder, the free space holds what the run writes, and each stage to
compute fits this machine's memory (pipelines.guard). A stage's expected inputs hash is known
from the scene alone (its upstream stages' expected hashes, not their files), so the plan
is final: an upstream output recomputed with the same inputs leaves its downstream current.

A stage that can start ahead of its turn (Stage.start: the time-integration sweep, which
needs only the ROM) runs in the background beside the stage before it (the NFRCs), on the
cores that stage leaves free and those its processes free as they end; in its turn it is
waited for and written (_start_beside). A run stopped before then ends it, writing no
artifact (what it finished stays in its partial file, as in its own turn).

Figures are checked last, against figures/manifest.json (inputs hash and file checksums): a
figure whose file is missing, damaged or outdated is redrawn from the artifacts.
Ctrl-C ends the run with pipelines.errors.Interrupted (what was kept, how to resume); a
write that fails ends it with StageFailed; each is one line from the CLI.

Under `mpirun -n N` rank 0 prepares, locks and plans the folder, decides what is current,
talks, draws and writes every file; the stages marked `distributed` (fem, ti) compute on
all ranks, the others on rank 0 while the rest wait (pipelines.parallel).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

from hbm.processes import WorkerDied
from pipelines import artifacts as art
from pipelines import folder
from pipelines.child import ChildDied
from pipelines.errors import Interrupted, Refused, StageFailed, after_ctrl_c
from pipelines.parallel import is_root, on_all, on_root, world
from pipelines.progress import Progress
from pipelines.stages import REGISTRY, STAGES
from pipelines.stages.base import Context, Figure, Output, Stage

MANIFEST = "manifest.json"


def file_hash(path: Path) -> str:
    """sha256 of a file's content."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _digest(components: dict) -> str:
    return hashlib.sha256(json.dumps(components, sort_keys=True).encode()).hexdigest()


#: Scene keys that choose how a result is computed, not what it is: the hashes read them at
#: their defaults, so that changing one leaves the artifacts current and a scene that never
#: sets them keeps its hashes. [fem] solver, ordering, out_of_core: every choice gives the
#: default's frequencies and mode shapes to 1.1e-10 relative (coarse rotor 67 mesh, its ROM's
#: matrices to 5e-13 and frequencies to 3e-11; a 595-node box deck), round-off: tightening
#: [fem] tol from 1e-10 to 1e-12 moves the mode shapes over 100 times more.
HOW_NOT_WHAT = {"fem": ("solver", "ordering", "out_of_core")}


def hashed_scene(scene):
    """The scene as the hashes read it: the keys of HOW_NOT_WHAT at their defaults."""
    def defaulted(section: str, keys) -> object:
        options = getattr(scene, section)
        default = type(options)()
        return dataclasses.replace(options, **{k: getattr(default, k) for k in keys})

    return dataclasses.replace(scene, **{s: defaulted(s, keys) for s, keys in HOW_NOT_WHAT.items()})


def expected_inputs(scene, names) -> dict:
    """{output file: (inputs {component: hash}, inputs hash)} for the outputs of the named
    stages (and those upstream of them): scene keys, input files by content, the upstream
    outputs' expected inputs hashes, and the output's key."""
    last = max(STAGES.index(n) for n in names)
    hashed = hashed_scene(scene)
    memo: dict = {}
    for name in STAGES[: last + 1]:
        stage = REGISTRY[name]
        files = {f"file {label}": file_hash(path) for label, path in stage.files(scene).items()}
        for o in stage.outputs(scene):
            comp = {f"scene {k}": hashed.key_hash(k) for k in stage.depends + o.depends}
            comp.update(files)
            for up in stage.upstream:
                for uo in REGISTRY[up].outputs(scene):
                    comp[f"upstream {uo.file}"] = memo[uo.file][1]
            if o.key:
                comp["key"] = o.key
            memo[o.file] = (comp, _digest(comp))
    return memo


def _short(value) -> str:
    """A scene value as the reason line shows it: TOML-like (floats in 6 digits where that is
    exact), cut to 40 characters."""
    if value is None:
        text = "unset"
    elif isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, float) and float(f"{value:.6g}") == value:
        text = f"{value:.6g}"
    else:
        text = json.dumps(value, ensure_ascii=False) if isinstance(value, (str, list, dict)) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _recorded_scene(text: str, scene):
    """The scene an artifact was made with, parsed from its recorded text (relative paths
    from the run's scene file), or None where there is none or it cannot be read as one (an
    empty text would parse as the defaults)."""
    from pipelines.scene import SceneError, parse_scene

    if not text.strip():
        return None
    try:
        return parse_scene(text, scene.path)
    except (SceneError, ValueError, TypeError):
        return None


def _changed_keys(key: str, old_scene, scene) -> list[str]:
    """The scene keys behind a changed scene component `key` ("hbm~methods", "contact.mu"),
    with their old and new values ("hbm.n_time 1000 -> 1024"); old_scene: the artifact's
    recorded scene, known to give the component's recorded hash (why_stale)."""
    old, new = old_scene.value(key), scene.value(key)
    if not (isinstance(old, dict) and isinstance(new, dict)):
        return [_change(key, old, new)]
    section = key.split("~")[0]
    return [_change(f"{section}.{f}", old.get(f), new.get(f))
            for f in sorted(set(old) | set(new)) if old.get(f) != new.get(f)]


def _change(name: str, old, new) -> str:
    """"hbm.n_time 1000 -> 1024"; where the cut values would read the same (long lists), the
    first item that differs ("isolas.amplitudes[2] 0.0046 -> 0.005") or the lengths."""
    a, b = _short(old), _short(new)
    if a != b:
        return f"{name} {a} -> {b}"
    if isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            return f"{name} ({len(old)} -> {len(new)} items)"
        i = next(i for i, (u, v) in enumerate(zip(old, new)) if u != v)
        return _change(f"{name}[{i}]", old[i], new[i])
    return f"{name} changed"


def _component_name(component: str) -> str:
    """"scene hbm~methods" -> "hbm except methods", "file mesh" -> "mesh file" (its content),
    "upstream rom.h5" -> "rom.h5"."""
    kind, _, name = component.partition(" ")
    if kind == "file":
        return f"{name} file"
    section, *dropped = (name or kind).split("~")
    return f"{section} except {', '.join(dropped)}" if dropped else section


def why_stale(path: Path, inputs: dict, h: str, verify: bool = True, scene=None) -> str | None:
    """None when `path` is current for these inputs and intact, else the reason to compute it.
    verify: check every dataset against its checksum (else the inputs hash only). scene: the
    run's scene, to name the changed scene keys with their values (else the components)."""
    scene = hashed_scene(scene) if scene is not None else None
    if path.is_symlink() and not path.exists():
        return "broken link"
    if not path.exists():
        return "no artifact"
    if not path.is_file():
        return "not a file"
    if path.stat().st_size == 0:
        return "empty file"
    attrs = art.read_attrs(path)
    if not attrs:
        return "unreadable file"
    if attrs.get("inputs_hash") == h:
        return art.verify(path) if verify else None
    try:
        old = json.loads(attrs.get("inputs", ""))
    except ValueError:
        return "made from other inputs"
    changed, recorded, parsed, regrouped = [], None, False, False
    for k in sorted(set(old) | set(inputs)):
        if old.get(k) == inputs.get(k):
            continue
        keys = []
        if scene is not None and k.startswith("scene "):
            if not parsed:  # once, at the first changed scene key
                recorded, parsed = _recorded_scene(attrs.get("scene", ""), scene), True
                recorded = hashed_scene(recorded) if recorded is not None else None
            key = k.split(" ", 1)[1]
            if k not in inputs or k not in old:
                # the stage read this key then and not now, or the other way round (another kind
                # of output, or an earlier version's keys): what it reads now counts, and only
                # where its value differs from the recorded scene's (the component names it then)
                if k not in inputs or recorded is not None and _same_value(key, recorded, scene):
                    regrouped = True
                    continue
            else:
                # the recorded text read with today's defaults is the old scene only where it
                # gives the recorded hash (not after a default changed: the old value is unknown)
                try:
                    same = recorded is not None and recorded.key_hash(key) == old.get(k)
                except AttributeError:  # a key the recorded scene's version did not have
                    same = False
                if same:
                    keys = _changed_keys(key, recorded, scene)
        name = _component_name(k)
        if not keys and not k.startswith("scene ") and (k not in old or k not in inputs):
            name += " (new)" if k not in old else " (gone)"
        changed.extend(keys or [name])
    changed = list(dict.fromkeys(changed))
    if len(changed) > 4:  # another scene altogether: the first few say enough
        changed = changed[:3] + [f"{len(changed) - 3} more"]
    if changed:
        return "inputs changed: " + ", ".join(changed)
    return "made by an earlier version, which read other scene keys" if regrouped else "made from other inputs"


def made_by_other_code(out: Path, outputs, noted: set | None = None) -> str:
    """"" when every output in `out` was written by this code version (or records none), else
    a note for the log of a stage found up to date: the versions that wrote them and how to
    recompute. A stage is current by its inputs, not by the code that computed it: an upgrade
    keeps the hours of results it finds, and this note is where the user learns that they
    come from another version. noted: the versions a run has already named with the advice
    (updated here): a later stage of theirs only says "made by bladerub X too", so a folder
    made by one earlier version gives one line of advice, not one per stage."""
    now = art.code_version()
    old = set()
    for o in outputs:
        path = out / o.file
        v = str(art.read_attrs(path).get("code_version", "")) if path.is_file() else ""
        if v and v != now:
            old.add(v)
    if not old:
        return ""
    if noted is not None and old <= noted:
        return f"; made by bladerub {', '.join(sorted(old))} too"
    if noted is not None:
        noted.update(old)
    return (f"; made by bladerub {', '.join(sorted(old))}, not this {now}: delete the "
            f"file{'s' if len(outputs) > 1 else ''} or pass --force to recompute with this version")


def _same_value(key: str, recorded, scene) -> bool:
    """Whether `key` has the same value in the recorded scene and the run's (False where the
    recorded scene's version has no such key)."""
    try:
        return recorded.value(key) == scene.value(key)
    except AttributeError:
        return False


@dataclass
class Step:
    """One stage of a run's plan: its outputs, those to compute (todo) and why."""

    stage: Stage
    outputs: tuple[Output, ...]
    todo: tuple[Output, ...]
    why: str


def plan(scene, out: Path, names, force: bool = False, expected: dict | None = None,
         verify: bool = True) -> list[Step]:
    """What a run of the named stages will compute and why. verify: check the checksums of
    the outputs that are current by their inputs hash (else trust the hash alone)."""
    expected = expected or expected_inputs(scene, names)
    steps = []
    for name in names:
        stage = REGISTRY[name]
        outputs = stage.outputs(scene)
        todo, reasons = [], []
        for o in outputs:
            inputs, h = expected[o.file]
            why = "forced (--force)" if force else why_stale(out / o.file, inputs, h, verify, scene)
            if why is not None:
                todo.append(o)
                reasons.append(why if len(outputs) == 1 else f"{o.file}: {why}")
        steps.append(Step(stage, outputs, tuple(todo), "; ".join(reasons) if todo else "up to date"))
    return steps


#: What a stage's partial file holds, where it is not an NFRC's points.
_PARTS = {"ti.h5": "speeds", "isolas.h5": "branches"}


def _kept(out: Path, steps, done: set, expected: dict, since: float, detailed: bool = True) -> str:
    """The artifacts a stopped run leaves usable (those current before it, those it finished:
    a stage with several outputs, such as the NFRCs, may have finished some), the points of
    interrupted NFRCs, the speeds of an interrupted sweep and the branches of an interrupted
    isola search. detailed: read the files (else names and times only)."""
    from pipelines.branch_store import partial_files

    def finished(o) -> bool:
        p = out / o.file
        if not p.is_file():
            return False
        if detailed:
            return art.read_attrs(p).get("inputs_hash") == expected[o.file][1]
        return p.stat().st_mtime >= since

    kept = [o.file for s in steps for o in s.outputs if o.file in done or (o in s.todo and finished(o))]
    for s in steps:
        for o in s.todo:
            # rank 0's partial file and, after mpirun, the other ranks' (the sweep's)
            files = partial_files(out / o.file) if o.file.endswith(".h5") else []
            names = ", ".join(f.name for f in files)
            if o.file not in kept and files:
                if not detailed:
                    kept.append(f"the {_PARTS.get(o.file, 'points')} of {names}")
                    continue
                held = _resumable(files, expected[o.file][1])
                if held:
                    kept.append(held)
    return ", ".join(kept) if kept else "nothing new"


def _resumable(files, h: str) -> str:
    """What partial files of inputs hash h hold, "N points of NAME" (or branches, speeds);
    "" when none does: a stage starts over from a partial file of other inputs."""
    counts = {f: art.read_attrs(f) for f in files}
    counts = {f: a for f, a in counts.items() if a.get("inputs_hash") == h}
    for what in ("points", "branches", "speeds"):
        n = sum(int(a.get(f"n_{what}", 0)) for a in counts.values())
        if n:
            return f"{n} {what} of {', '.join(f.name for f in counts)}"
    return ""


def dry_run(scene, out: Path, until: str = STAGES[-1], force: bool = False) -> list[str]:
    """What `bladerub run` would do in `out`, as lines, computing and writing nothing.

    Per stage: up to date (naming the code version that wrote it where another one did), or
    the outputs it would compute and why, what it would resume from (the partial files of
    these inputs) and its size estimate (pipelines.guard), with the refusal a run would meet;
    then the figures it would draw; first, the run that holds the folder now, if one does.
    The folder is neither created, locked nor cleaned."""
    from pipelines import guard
    from pipelines.branch_store import partial_files
    from pipelines.errors import RunError

    if until not in STAGES:
        raise ValueError(f"unknown stage '{until}'; stages: {', '.join(STAGES)}")
    names = STAGES[: STAGES.index(until) + 1]
    expected = expected_inputs(scene, names)
    steps = plan(scene, out, names, force, expected)  # a folder not made yet: "no artifact" throughout
    # the size guard's own estimate lines, "[stage] estimate: ...", of every stage (yes: past
    # one a run would be refused at), then the refusal a run would meet
    said, refused = [], ""
    for yes, log in ((True, said.append), (False, lambda text: None)):
        try:
            guard.check_run(scene, out, steps, SimpleNamespace(log=log), yes=yes)
        except RunError as exc:
            refused = f"a run would be refused: {exc}"
        except OSError:
            pass  # the free space of a folder not made yet (the memory is checked before it)
    busy = folder.holder(out)
    lines, computed = ([f"a run holds this folder: {busy}; what it is computing reads as to compute"]
                       if busy else []), set()
    versions = set()  # named with the advice already (made_by_other_code)
    for s in steps:
        if not s.todo:
            lines.append(f"[{s.stage.name}] up to date ({', '.join(o.file for o in s.outputs) or '-'})"
                         + made_by_other_code(out, s.outputs, versions))
            continue
        computed.update(o.file for o in s.todo)
        parts = {o: partial_files(out / o.file) if o.file.endswith(".h5") else [] for o in s.todo}
        resumed = [r for o, files in parts.items() if (r := _resumable(files, expected[o.file][1]))]
        # the partial files a run starts over from: of another scene, or unreadable (the stage says which)
        dropped = [f.name for o, files in parts.items() for f in files
                   if art.read_attrs(f).get("inputs_hash") != expected[o.file][1]]
        lines.append(f"[{s.stage.name}] would compute {', '.join(o.file for o in s.todo)} ({s.why})"
                     + (f", resuming from {', '.join(resumed)}" if resumed else "")
                     + (f", starting over from {', '.join(dropped)} (other inputs, or unreadable)" if dropped else ""))
        head = f"[{s.stage.name}] estimate: "
        lines.extend("  estimate: " + line[len(head):] for line in said if line.startswith(head))
    if refused:
        lines.append(refused)
    drawn = []
    folder_ = out / "figures"
    manifest = _read_manifest(folder_)
    for s in steps:
        for fig in s.stage.figures:
            files, inputs = fig.files(scene), fig.inputs(scene)
            if not files:
                continue
            if computed & set(inputs):
                drawn.append(f"{fig.name} (after {', '.join(sorted(computed & set(inputs)))})")
            elif any((out / name).is_file() for name in inputs):
                comp = figure_components(scene, out, fig)
                why = _figure_why(manifest.get(fig.name), comp, _digest(comp), folder_, files)
                if why:
                    drawn.append(f"{fig.name} ({why})")
    lines.append(f"[figures] would draw: {', '.join(drawn)}" if drawn else "[figures] up to date")
    return lines


#: What an interruption now would say (set while a run executes; pipelines.cli reads it).
_describe = None


def interruption(detailed: bool = True) -> str:
    """The line for a run interrupted now: where, what was kept, how to go on."""
    return _describe(detailed) if _describe is not None else "interrupted"


def run_scene(scene, out: Path, until: str = STAGES[-1], force: bool = False,
              progress: Progress | None = None, yes: bool = False, command: str = "") -> Progress:
    """Run the scene's stages in order up to `until`, then bring the figures up to date.

    yes: run even what the size guard or the free-space check would refuse. command: the
    command line, shown to a second run in the same folder and in the resume hint.
    Returns the Progress, whose `records` hold one StageRecord per stage. Raises
    pipelines.errors.RunError subclasses for what the user can act on (one line each).
    Under an MPI launcher the call is collective (module docstring): rank 0 plans and holds
    the folder's lock; the other ranks get the plan and a quiet default Progress.
    """
    from contextlib import ExitStack

    if until not in STAGES:
        raise ValueError(f"unknown stage '{until}'; stages: {', '.join(STAGES)}")
    comm = world()
    names = STAGES[: STAGES.index(until) + 1]
    if comm is not None and "fem" in names:  # before the folder is touched: CHOLMOD is one process only
        from fem.cholesky import resolve_solver

        try:
            resolve_solver(scene.fem.solver, True, scene.fem.out_of_core)
        except ValueError as exc:
            raise ValueError(f"[fem] {exc}") from None
    progress = progress or Progress(quiet=not is_root(comm))
    out = on_root(comm, lambda: folder.prepare(Path(out)))
    command = command or f"bladerub run {scene.path} --out {out} --until {until}"
    expected = expected_inputs(scene, names)
    with ExitStack() as lock:
        def hold() -> None:  # rank 0 holds the folder for the whole run
            lock.enter_context(folder.hold(out, command))

        on_root(comm, hold)
        # stages hold functions (not picklable): rank 0 sends each one's outputs to compute
        todo = on_root(comm, lambda: [(s.why, [o.file for o in s.todo])
                                      for s in _plan_checked(scene, out, names, force, expected, progress, yes)])
        steps = []
        for name, (why, files) in zip(names, todo):
            outputs = REGISTRY[name].outputs(scene)
            steps.append(Step(REGISTRY[name], outputs, tuple(o for o in outputs if o.file in files), why))
        _execute(scene, out, steps, expected, progress, command, comm)
    return progress


def _plan_checked(scene, out: Path, names, force: bool, expected: dict, progress: Progress,
                  yes: bool) -> list[Step]:
    """The run's plan, once the folder, the paths, the memory and the disk are checked."""
    from pipelines import guard

    removed = folder.remove_orphans(out)
    if removed:
        progress.log(f"[folder] removed {len(removed)} temporary file(s) left by a run that was killed: "
                     + ", ".join(f"{n} ({b / 1e6:.1f} MB)" for n, b in removed))
    # first by inputs hash alone (milliseconds): a run too large for the machine is refused
    # before a large artifact is read to verify it; then the checksums, which may add work
    quick = plan(scene, out, names, force, expected, verify=False)
    _check_paths(out, quick)
    disk = guard.check_run(scene, out, quick, progress, yes=yes)
    steps = plan(scene, out, names, force, expected)
    damaged = [Step(s.stage, s.outputs, tuple(o for o in s.todo if o not in q.todo), s.why)
               for s, q in zip(steps, quick) if len(s.todo) > len(q.todo)]
    _check_paths(out, damaged)
    guard.check_run(scene, out, damaged, progress, yes=yes, disk=disk)
    return steps


def _check_paths(out: Path, steps) -> None:
    from pipelines.branch_store import partial_paths

    for s in steps:
        for o in s.todo:
            folder.check_path(out / o.file)
            for p in partial_paths(out / o.file):  # every rank's, after mpirun (the sweep's)
                folder.check_path(p)
    figures = out / "figures"
    if figures.exists() and not figures.is_dir():
        raise folder.FolderError(f"{figures} is not a folder: the run draws its figures there; move it away")


def _context(scene, out: Path, progress: Progress, step: Step, expected: dict) -> Context:
    ctx = Context(scene, out, progress)
    for o in step.outputs:
        ctx.inputs[o.file], ctx.hashes[o.file] = expected[o.file]
    return ctx


def _start_beside(scene, out: Path, steps, i: int, expected: dict, progress: Progress, comm):
    """The stage after steps[i] started in the background beside it (Stage.start), or None.

    It starts when it has a start, outputs to compute and its upstream current before
    steps[i], when steps[i] says how many cores it keeps busy, outside MPI runs, and when the
    two stages' estimated memory fits together. It takes the cores steps[i] leaves free and
    those its processes free as they end (ctx.lend_cores of steps[i]): on the default scene
    the sweep marches on the core of the shorter NFRC while the longer one runs.
    """
    from pipelines import guard

    if comm is not None or i + 1 >= len(steps):
        return None
    s, n = steps[i], steps[i + 1]
    if n.stage.start is None or not n.todo or s.stage.busy_cores is None:
        return None
    if not set(n.stage.upstream) <= {t.stage.name for t in steps[:i]}:
        return None
    cores = len(os.sched_getaffinity(0))
    if cores < 2:
        return None
    memory = sum(e.memory for e in (s.stage.estimate(scene, out, s.todo), n.stage.estimate(scene, out, n.todo))
                 if e is not None)
    if memory > guard.memory_limit(scene):
        progress.log(f"[{n.stage.name}] waits for {s.stage.name}: the two at once would need ~{guard.gb(memory)} "
                     "of memory")
        return None
    free = max(0, cores - s.stage.busy_cores(scene, s.todo))
    try:  # on no core: steps[i] lends them (Stage.busy_cores)
        started = n.stage.start(_context(scene, out, progress, n, expected), n.todo, 0)
    except Exception as exc:  # noqa: BLE001 - it computes in its turn instead, and raises there if it must
        progress.log(f"[{n.stage.name}] not started beside {s.stage.name} ({art.first_line(exc)}): it runs in its turn")
        return None
    progress.log(f"[{n.stage.name}] running ({n.why}) beside {s.stage.name}: on {free} of {cores} cores once "
                 f"{s.stage.name}'s processes are started, the others as they end ...")
    return started


def _execute(scene, out: Path, steps, expected: dict, progress: Progress, command: str, comm=None) -> None:
    global _describe
    done = {o.file for s in steps for o in s.outputs if o not in s.todo}
    where, since = "planning", time.time()
    ahead: dict = {}  # stage name: its Background, started beside the stage before it

    def kept(detailed: bool = True) -> str:
        return _kept(out, steps, done, expected, since, detailed)

    def resumable(detailed: bool = True) -> str:  # the stages resume from what their partial files keep
        return f"kept: {kept(detailed)}; run `{command}` again to go on from there"

    def describe(detailed: bool = True) -> str:
        return f"interrupted during {where}; {resumable(detailed)}"

    def computed() -> bool:
        """Whether this run wrote an artifact or a partial file (the CLI's exit 2 says it did not)."""
        from pipelines.branch_store import partial_files

        files = [out / o.file for s in steps for o in s.outputs]
        files += [f for p in files if p.suffix == ".h5" for f in partial_files(p)]
        return any(f.is_file() and f.stat().st_mtime >= since for f in files)

    _describe = describe
    versions = set()  # named with the advice already (made_by_other_code)
    try:
        for i, s in enumerate(steps):
            where = f"stage {s.stage.name}"
            ctx = _context(scene, out, progress, s, expected)
            with progress.stage(s.stage.name) as record:
                if not s.todo:
                    record.action, record.why = "reused", "up to date"
                    progress.log(f"[{s.stage.name}] up to date ({', '.join(o.file for o in s.outputs) or '-'})"
                                 + made_by_other_code(out, s.outputs, versions))
                    continue
                record.why = s.why
                if s.stage.name in ahead:
                    record.why += f" (started beside {steps[i - 1].stage.name})"
                    ahead[s.stage.name].finish()
                    del ahead[s.stage.name]
                else:
                    progress.log(f"[{s.stage.name}] running ({s.why}) ...")
                    started = _start_beside(scene, out, steps, i, expected, progress, comm)
                    if started is not None:
                        ahead[steps[i + 1].stage.name] = started
                        ctx.lend_cores, ctx.beside = started.lend, started.status
                    compute = on_all if s.stage.distributed else on_root
                    compute(comm, lambda s=s, ctx=ctx: s.stage.compute(ctx, s.todo))
                done.update(o.file for o in s.todo)
                progress.log(f"[{s.stage.name}] done -> {', '.join(o.file for o in s.todo)}")
        where = "the figures"
        on_root(comm, lambda: update_figures(scene, out, [s.stage for s in steps], progress))
    except KeyboardInterrupt:
        raise Interrupted(describe()) from None
    except _FigureFailed as exc:  # after the stages: not "nothing was computed" (a ValueError's exit 2)
        def left(stale):  # a ParaView series is a .pvd and one file per instant: the first few
            return ", ".join(stale) if len(stale) <= 3 else f"{', '.join(stale[:2])} and {len(stale) - 2} more"

        said = "; ".join(f"figure {name} failed: {art.first_line(why)}"
                         + (f" (its last drawing stays, from other inputs: {left(stale)})" if stale else "")
                         for name, why, stale in exc.failures)
        raise StageFailed(f"{said}; kept: {kept()}") from exc.failures[0][1]
    except ChildDied as exc:  # a stage's own process that ended without a word (killed): a rerun resumes
        raise StageFailed(f"{where} failed: {exc}; {resumable()}") from exc
    except WorkerDied as exc:  # a pool's worker killed (OOM): the speeds or branches its pool ended are on disk
        raise StageFailed(f"{where} failed: {exc}; {resumable()}") from exc
    except ValueError as exc:  # bad input found late (a step past the ROM's limit) or a numerical failure
        if where == "planning" or not computed():
            raise  # nothing computed: the CLI's exit 2
        raise StageFailed(f"{where} failed: {art.first_line(exc)}; kept: {kept()}") from exc
    except SystemExit as exc:  # a child's sys.exit(), re-raised here (pipelines.child): never the run's own code
        code = exc.code if exc.code is None or isinstance(exc.code, int) else repr(exc.code)
        raise StageFailed(f"{where} failed: a process of it exited (code {0 if code is None else code}) "
                          f"without an answer; {resumable()}") from None
    except OSError as exc:
        text = os.strerror(exc.errno) if exc.errno else art.first_line(exc)
        name = f" {exc.filename}" if getattr(exc, "filename", None) else ""
        raise StageFailed(f"{where} failed: {text}{name}; kept: {kept()}") from exc
    except Exception as exc:
        if after_ctrl_c(exc):  # a native library's import cut by Ctrl-C (pipelines.errors.deferred_ctrl_c)
            raise Interrupted(describe()) from None
        raise
    finally:
        for started in ahead.values():  # the run stopped before their turn
            started.cancel()
        _describe = None


class _FigureFailed(ValueError):
    """Figures whose drawing failed (update_figures); failures: [(name, the exception, the
    files under figures/ its last drawing left, which now stand for other inputs)]."""

    def __init__(self, failures: list):
        super().__init__(f"figure(s) {', '.join(name for name, *_ in failures)} failed")
        self.failures = failures


def figure_components(scene, out: Path, fig: Figure) -> dict:
    """What a figure is drawn from: its scene keys, and each input artifact's inputs and the
    instant it was written (an artifact computed again from the same inputs, after --force or
    a deleted file, is a new result whose figures must be redrawn)."""
    comp = {f"scene {k}": hashed_scene(scene).key_hash(k) for k in fig.depends}
    for name in fig.inputs(scene):
        attrs = art.read_attrs(out / name)
        comp[f"input {name}"] = f"{attrs.get('inputs_hash', 'absent')} {attrs.get('created', '')}"
    return comp


def figure_hash(scene, out: Path, fig: Figure) -> str:
    """The digest of figure_components: what the figure manifest records."""
    return _digest(figure_components(scene, out, fig))


def _figure_changes(old: dict, new: dict) -> str:
    """What differs between a figure's recorded components and today's: "hbm.n_time",
    "ti.h5 (new)", "nfrc_rl.h5 (recomputed)", "ti.h5 (gone)"; "" when nothing can be named."""
    changed = []
    for k in sorted(set(old) | set(new)):
        if old.get(k) == new.get(k):
            continue
        kind, _, name = k.partition(" ")
        if kind != "input":
            changed.append(_component_name(k))
        elif str(old.get(k, "absent")).startswith("absent"):
            changed.append(f"{name} (new)")
        elif str(new.get(k, "absent")).startswith("absent"):
            changed.append(f"{name} (gone)")
        else:
            changed.append(f"{name} (recomputed)")
    return ", ".join(changed)


def _figure_current(entry, h: str, folder_: Path, files) -> bool:
    """A manifest entry is current when made from these inputs and its files have the
    checksums recorded when they were drawn (an older manifest's bare hash never is)."""
    if not isinstance(entry, dict) or entry.get("inputs") != h:
        return False
    sums = entry.get("files", {})
    return all((folder_ / f).is_file() and sums.get(f) == file_hash(folder_ / f) for f in files)


def _read_manifest(folder_: Path) -> dict:
    """figures/manifest.json as a dict ({} when missing or unreadable: every figure is drawn)."""
    try:
        manifest = json.loads((folder_ / MANIFEST).read_text())
    except (OSError, ValueError):
        return {}
    return manifest if isinstance(manifest, dict) else {}


def _figure_why(entry, comp: dict, h: str, folder_: Path, files) -> str:
    """Why a figure with manifest entry `entry`, components `comp` (figure_components) and
    their digest h is drawn: "missing", "inputs changed: ...", "file missing or damaged"; ""
    when current."""
    if _figure_current(entry, h, folder_, files):
        return ""
    if entry is None:
        return "missing"
    if not isinstance(entry, dict) or entry.get("inputs") != h:
        recorded = entry.get("components") if isinstance(entry, dict) else None
        named = _figure_changes(recorded, comp) if isinstance(recorded, dict) else ""
        return f"inputs changed: {named}" if named else "inputs changed"
    return "file missing or damaged"


def _remove_recorded(folder_: Path, entry: dict, keep) -> None:
    """Remove the files a manifest entry recorded (names the figure declared when it was
    drawn) that are not in `keep`, and the subfolders this leaves empty. A name that is not a
    plain relative path inside the folder (a hand-edited manifest) is left alone."""
    recorded = entry.get("files", {})
    for name in set(recorded if isinstance(recorded, dict) else ()) - set(keep):
        rel = Path(str(name))
        if rel.is_absolute() or ".." in rel.parts or not (folder_ / rel).is_file():
            continue
        (folder_ / rel).unlink()
        for parent in (folder_ / rel).parents:
            if parent == folder_ or any(parent.iterdir()):
                break
            parent.rmdir()


def update_figures(scene, out: Path, stages, progress: Progress) -> list[str]:
    """Draw the figures of `stages` that are missing, damaged or outdated; returns their names.

    A figure whose drawing fails on its data (ValueError: an NFRC without a converged point),
    on an input it finds unusable (ArtifactError: a ROM without its recovery matrix) or on the
    machine (no off-screen OpenGL for the mode pictures: RenderError) keeps its previous files
    (named in the error) and no manifest entry of this drawing; the others are drawn all the
    same (the NFRC plots need no OpenGL), and _FigureFailed names every failed one at the end."""
    from pipelines.render import RenderError

    folder_ = out / "figures"
    path = folder_ / MANIFEST
    manifest = _read_manifest(folder_)
    drawn, failed = [], []
    for stage in stages:
        for fig in stage.figures:
            files = fig.files(scene)
            if not files and isinstance(manifest.get(fig.name), dict):
                # none declared now (render.n_modes = 0, hbm_instants = 0): the last drawing's
                # files would read as this scene's
                _remove_recorded(folder_, manifest.pop(fig.name), ())
                with art.atomic_output(path) as tmp:
                    tmp.write_text(json.dumps(manifest, indent=1, sort_keys=True))
            if not files or not any((out / name).is_file() for name in fig.inputs(scene)):
                continue
            comp = figure_components(scene, out, fig)
            h = _digest(comp)
            entry = manifest.get(fig.name)
            why = _figure_why(entry, comp, h, folder_, files)
            if not why:
                continue
            with progress.stage(f"figure {fig.name}") as record:
                record.why = why
                try:
                    fig.draw(Context(scene, out, progress))
                except (ValueError, RenderError, art.ArtifactError) as exc:
                    record.action = "failed"
                    recorded = entry.get("files", {}) if isinstance(entry, dict) else {}
                    stale = sorted(f"figures/{f}" for f in recorded if isinstance(f, str) and (folder_ / f).is_file())
                    failed.append((fig.name, exc, stale))
                    continue
            if isinstance(entry, dict):  # e.g. another stem (the first of hbm.methods changed)
                _remove_recorded(folder_, entry, files)
            manifest[fig.name] = {"inputs": h, "components": comp,
                                  "files": {f: file_hash(folder_ / f) for f in files if (folder_ / f).is_file()}}
            folder_.mkdir(parents=True, exist_ok=True)
            with art.atomic_output(path) as tmp:
                tmp.write_text(json.dumps(manifest, indent=1, sort_keys=True))
            drawn.append(fig.name)
    if drawn:
        progress.log(f"[figures] drawn: {', '.join(drawn)} -> {folder_}")
    if failed:
        raise _FigureFailed(failed)
    return drawn


def render_modes(scene, out: Path, n_modes: int | None = None, progress: Progress | None = None,
                 command: str = "") -> list:
    """`bladerub render`: the mode-shape pictures of an existing, current fem.h5 (rank 0
    under MPI)."""
    return on_root(world(), lambda: _render(scene, Path(out), n_modes, progress, command))


def _render(scene, out: Path, n_modes, progress, command: str) -> list:
    from pipelines.stages.fem import render_modes as draw

    if not out.exists():
        raise Refused(f"no output folder {out}: run `bladerub run {scene.path} --out {out} --until fem` first")
    out = folder.prepare(out)
    with folder.hold(out, command or f"bladerub render {scene.path} --out {out}"):
        for s in plan(scene, out, ("mesh", "fem")):
            if s.todo:
                o = s.todo[0]
                state = "is missing" if s.why == "no artifact" else f"is not usable for this scene ({s.why})"
                raise Refused(f"{out / o.file} {state}: run `bladerub run {scene.path} --out {out} --until fem` "
                              "first")
        try:
            return draw(Context(scene, out, progress or Progress()), n_modes)
        except KeyboardInterrupt:
            raise Interrupted("interrupted while rendering; the artifacts are untouched") from None
