"""Command line: `bladerub run SCENE.toml --out DIR [--until STAGE]`, `bladerub render ...`.

`mpirun -n N bladerub run ...` runs the FEM stage distributed over N ranks and shares the
time-integration sweep's speeds among them; rank 0 does the rest and all the talking
(pipelines.parallel).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pipelines.artifacts import ArtifactError
from pipelines.scene import SceneError, load_scene


def _cmd_run(args) -> int:
    from pipelines.progress import Progress
    from pipelines.runner import run_scene

    from pipelines.parallel import is_root, world

    scene = load_scene(args.scene)
    progress = Progress(quiet=args.quiet or not is_root(world()))
    try:
        run_scene(scene, Path(args.out), until=args.until, force=args.force, progress=progress)
    finally:
        progress.summary()
    return 0


def _cmd_render(args) -> int:
    from pipelines.progress import Progress
    from pipelines.runner import render_modes

    from pipelines.parallel import is_root, world

    scene = load_scene(args.scene)
    paths = render_modes(scene, Path(args.out), n_modes=args.modes, progress=Progress(quiet=True))
    if is_root(world()):
        for p in paths:
            print(p)
    return 0


def main(argv: list[str] | None = None) -> int:
    from pipelines.stages import STAGES

    parser = argparse.ArgumentParser(prog="bladerub", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene's stages in order, skipping those already up to date")
    run.add_argument("scene", type=Path, help="scene file (TOML)")
    run.add_argument("--out", type=Path, required=True, help="output folder for artifacts and figures")
    run.add_argument("--until", default=STAGES[-1], choices=STAGES, help="last stage to run (default: all)")
    run.add_argument("--force", action="store_true", help="recompute stages even if up to date")
    run.add_argument("--quiet", action="store_true", help="print errors only (no live line, no summary)")
    run.set_defaults(func=_cmd_run)
    ren = sub.add_parser("render", help="render mode shapes off-screen to PNG (needs fem.h5 in --out)")
    ren.add_argument("scene", type=Path)
    ren.add_argument("--out", type=Path, required=True)
    ren.add_argument("--modes", type=int, default=None, help="number of modes (default: the scene's)")
    ren.set_defaults(func=_cmd_render)
    args = parser.parse_args(argv)
    from pipelines.parallel import RankFailed, is_root, world

    try:
        return args.func(args)
    except (SceneError, ArtifactError, ValueError, FileNotFoundError, RankFailed) as exc:
        if is_root(world()):  # under MPI every rank has the error: rank 0 says it once
            print(f"bladerub: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
