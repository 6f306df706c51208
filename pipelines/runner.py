"""Runs a scene's stages in order, skipping what is current, and redraws what is missing.

An output is current when its file carries the inputs hash of exactly what it depends on
(pipelines.stages.base). Otherwise the stage computes it, and the run says why: no
artifact, which inputs changed, or --force. Figures are checked last, against
figures/manifest.json: a figure whose file is missing or whose inputs changed is redrawn
from the artifacts, nothing is recomputed for it.

Under `mpirun -n N` rank 0 decides what is current, talks, draws and writes every file;
the stages marked `distributed` (fem, ti) compute on all ranks, the others on rank 0
while the rest wait (pipelines.parallel).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from pipelines import artifacts as art
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


def inputs_of(scene, out: Path, stage: Stage, output: Output) -> dict:
    """What `output` of `stage` depends on, {component: hash}: scene keys, input files by
    content, the upstream artifacts' own inputs hashes, and the output's key."""
    comp = {f"scene {k}": scene.key_hash(k) for k in stage.depends + output.depends}
    for label, path in stage.files(scene).items():
        comp[f"file {label}"] = file_hash(path)
    for up in stage.upstream:
        for o in REGISTRY[up].outputs(scene):
            comp[f"upstream {o.file}"] = art.read_attrs(out / o.file).get("inputs_hash", "missing")
    if output.key:
        comp["key"] = output.key
    return comp


def _why_stale(path: Path, inputs: dict, h: str) -> str | None:
    """None when `path` is current for these inputs, else the reason to compute it."""
    if not path.exists():
        return "no artifact"
    attrs = art.read_attrs(path)
    if not attrs:
        return "artifact unreadable"
    if attrs.get("inputs_hash") == h:
        return None
    try:
        old = json.loads(attrs.get("inputs", ""))
    except ValueError:
        return "made from other inputs"
    changed = sorted({k.split(" ", 1)[-1] for k in set(old) | set(inputs) if old.get(k) != inputs.get(k)})
    return "inputs changed: " + ", ".join(changed) if changed else "made from other inputs"


def run_scene(scene, out: Path, until: str = STAGES[-1], force: bool = False,
              progress: Progress | None = None) -> Progress:
    """Run the scene's stages in order up to `until`, then bring the figures up to date.

    Returns the Progress, whose `records` hold one StageRecord per stage.
    Under an MPI launcher the call is collective (see the module docstring); the other
    ranks' default Progress is quiet.
    """
    if until not in STAGES:
        raise ValueError(f"unknown stage '{until}'; stages: {', '.join(STAGES)}")
    comm = world()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    progress = progress or Progress(quiet=not is_root(comm))
    ran = []
    for name in STAGES[: STAGES.index(until) + 1]:
        stage = REGISTRY[name]
        ran.append(stage)
        ctx = Context(scene, out, progress)

        def plan(stage=stage, ctx=ctx):
            todo, reasons = [], []
            for o in stage.outputs(scene):
                inputs = inputs_of(scene, out, stage, o)
                h = _digest(inputs)
                why = "forced (--force)" if force else _why_stale(out / o.file, inputs, h)
                ctx.hashes[o.file], ctx.inputs[o.file] = h, inputs
                if why is not None:
                    todo.append(o.file)
                    reasons.append(why if len(stage.outputs(scene)) == 1 else f"{o.file}: {why}")
            return todo, reasons, ctx.hashes, ctx.inputs

        # decided on rank 0 alone (another rank could read a file while rank 0 writes it)
        todo, reasons, ctx.hashes, ctx.inputs = on_root(comm, plan)
        todo = [o for o in stage.outputs(scene) if o.file in todo]
        with progress.stage(name) as record:
            if not todo:
                record.action, record.why = "reused", "up to date"
                progress.log(f"[{name}] up to date ({', '.join(o.file for o in stage.outputs(scene)) or '-'})")
                continue
            record.why = "; ".join(reasons)
            progress.log(f"[{name}] running ({record.why}) ...")
            compute = on_all if stage.distributed else on_root
            compute(comm, lambda stage=stage, ctx=ctx, todo=todo: stage.compute(ctx, tuple(todo)))
            progress.log(f"[{name}] done -> {', '.join(o.file for o in todo)}")
    on_root(comm, lambda: update_figures(scene, out, ran, progress))
    return progress


def figure_hash(scene, out: Path, fig: Figure) -> str:
    comp = {f"scene {k}": scene.key_hash(k) for k in fig.depends}
    for name in fig.inputs(scene):
        comp[f"input {name}"] = art.read_attrs(out / name).get("inputs_hash", "absent")
    return _digest(comp)


def update_figures(scene, out: Path, stages, progress: Progress) -> list[str]:
    """Draw the figures of `stages` that are missing or outdated; returns their names."""
    folder = out / "figures"
    path = folder / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError):
        manifest = {}
    drawn = []
    for stage in stages:
        for fig in stage.figures:
            files = fig.files(scene)
            if not files or not any((out / name).is_file() for name in fig.inputs(scene)):
                continue
            h = figure_hash(scene, out, fig)
            if manifest.get(fig.name) == h and all((folder / f).is_file() for f in files):
                continue
            with progress.stage(f"figure {fig.name}") as record:
                record.why = "missing" if fig.name not in manifest else "inputs changed"
                fig.draw(Context(scene, out, progress))
            manifest[fig.name] = h
            folder.mkdir(parents=True, exist_ok=True)
            with art.atomic_output(path) as tmp:
                tmp.write_text(json.dumps(manifest, indent=1, sort_keys=True))
            drawn.append(fig.name)
    if drawn:
        progress.log(f"[figures] drawn: {', '.join(drawn)} -> {folder}")
    return drawn


def render_modes(scene, out: Path, n_modes: int | None = None, progress: Progress | None = None) -> list:
    """`bladerub render`: the mode-shape pictures of an existing fem.h5 (rank 0 under MPI)."""
    from pipelines.stages.fem import FEM, render_modes as draw
    from pipelines.stages.mesh import MESH

    out = Path(out)

    def render():
        for f in (MESH.file, FEM.file):
            if not (out / f).is_file():
                raise art.ArtifactError(f"{out / f} not found: run `bladerub run {scene.path} --out {out} "
                                        f"--until fem` first")
        return draw(Context(scene, out, progress or Progress()), n_modes)

    return on_root(world(), render)
