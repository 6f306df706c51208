"""Stage orchestration: the only place that knows file names and the order of stages.

Each stage reads the previous stage's artifact (never another stage's objects in
memory), calls its package, and writes its own artifact atomically. A stage whose
artifact was made from exactly the same inputs (scene sections it depends on, the
upstream artifact, the geometry file's content) is skipped.
"""
from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from pipelines import artifacts as art

STAGES = ("mesh", "fem", "rom", "hbm", "ti")


@dataclass(frozen=True)
class Stage:
    """name: stage name. sections: scene sections it depends on. upstream: stage it reads.
    outputs: artifact file names in the output folder. run: (scene, out, inputs_hash) -> None."""

    name: str
    sections: tuple[str, ...]
    upstream: str | None
    outputs: Callable[[object], tuple[str, ...]]
    run: Callable[[object, Path, str], None]


def _file_hash(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def inputs_hash(scene, out: Path, stage: Stage) -> str:
    """Hash of exactly what `stage` depends on."""
    h = hashlib.sha256(scene.section_hash(*stage.sections).encode())
    if stage.name == "mesh":
        geometry = scene.resolve(scene.blade.geometry)
        if not geometry.is_file():
            raise FileNotFoundError(f"geometry file not found: {geometry} (from [blade] geometry in {scene.path})")
        h.update(_file_hash(geometry).encode())
    if stage.upstream:
        up = REGISTRY[stage.upstream]
        for name in up.outputs(scene):
            h.update(art.read_attrs(out / name).get("inputs_hash", "missing").encode())
    return h.hexdigest()


# --- mesh ------------------------------------------------------------------------
def _run_mesh(scene, out: Path, h: str):
    from mesh.blade import mesh_blade

    result = mesh_blade(scene.blade, scene.mesh, scene.resolve(scene.blade.geometry))
    art.write_artifact(out / "mesh.h5", result, stage="mesh", scene_text=scene.text, inputs_hash=h)
    print(f"  {result.n_nodes} nodes, {len(result.cells)} tet10 cells, volume {result.volume:.4e} m^3 "
          f"(section integral {result.reference_volume:.4e} m^3)")


def _read_mesh(out: Path):
    from mesh.model import BladeMesh

    return art.read_artifact(out / "mesh.h5", BladeMesh)


REGISTRY: dict[str, Stage] = {
    "mesh": Stage("mesh", ("blade", "mesh"), None, lambda s: ("mesh.h5",), _run_mesh),
}


def _require_stage(name: str) -> Stage:
    try:
        return REGISTRY[name]
    except KeyError:
        raise NotImplementedError(f"stage '{name}' is not available in this version") from None


def run_scene(scene, out: Path, until: str = "rom", force: bool = False) -> None:
    """Run the scene's stages in order up to `until`, skipping those already up to date."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for name in STAGES[: STAGES.index(until) + 1]:
        stage = _require_stage(name)
        h = inputs_hash(scene, out, stage)
        outputs = stage.outputs(scene)
        if not force and all(art.is_current(out / o, h) for o in outputs):
            print(f"[{name}] up to date ({', '.join(outputs)})")
            continue
        print(f"[{name}] running ...", flush=True)
        t0 = time.perf_counter()
        stage.run(scene, out, h)
        print(f"[{name}] done in {time.perf_counter() - t0:.1f} s -> {', '.join(outputs)}", flush=True)


def render_modes(scene, out: Path, n_modes=None):
    raise NotImplementedError("rendering is being wired")
