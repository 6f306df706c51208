"""The validation stage on the coarse rotor 67 ROM (tests/data), without the FE stack: the
NFRCs are computed by the hbm stage's code when the folder lacks them, then the validation
stage runs and draws its figures. Prints each point's relative differences against time
integration, the drift, and the stage's CPU time.

    nice -n 5 .venv/bin/python benchmarks/bench_validation.py OUT [--set hbm.n_harmonics=20 ...]
"""
from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    from pipelines.progress import Progress
    from pipelines.runner import expected_inputs, update_figures
    from pipelines.scene import load_scene
    from pipelines.stages import REGISTRY
    from pipelines.stages.base import Context

    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67_coarse.toml")
    ap.add_argument("--set", action="append", default=[])
    a = ap.parse_args()
    scene = load_scene(a.scene, a.set)
    a.out.mkdir(parents=True, exist_ok=True)
    if not (a.out / "rom.h5").is_file():
        shutil.copy(ROOT / "tests" / "data" / "rotor67_coarse_rom.h5", a.out / "rom.h5")
    progress = Progress()
    expected = expected_inputs(scene, ("hbm", "validation"))
    for name in ("hbm", "validation"):
        stage = REGISTRY[name]
        ctx = Context(scene, a.out, progress)
        todo = []
        for o in stage.outputs(scene):
            ctx.inputs[o.file], ctx.hashes[o.file] = expected[o.file]
            if name == "validation" or not (a.out / o.file).is_file():
                todo.append(o)
        if todo:
            c0, t0 = time.process_time(), time.perf_counter()
            stage.compute(ctx, tuple(todo))
            print(f"[{name}] {time.process_time() - c0:.1f} s CPU, {time.perf_counter() - t0:.1f} s wall")
    update_figures(scene, a.out, [REGISTRY["validation"]], progress)


if __name__ == "__main__":
    main()
