"""The stages of a run, in order: the one place that knows file names and stage order.

mesh -> fem -> rom -> hbm -> ti -> isolas -> validation. Each stage module says what it depends on
(scene keys, input files, upstream artifacts), what it writes and its figures; the
engine that runs them is pipelines.runner.
"""
from __future__ import annotations

from pipelines.stages import fem, hbm, isolas, mesh, rom, ti, validation
from pipelines.stages.base import Context, Figure, Output, Stage

REGISTRY: dict[str, Stage] = {s.name: s for s in (mesh.STAGE, fem.STAGE, rom.STAGE, hbm.STAGE, ti.STAGE,
                                                  isolas.STAGE, validation.STAGE)}
STAGES: tuple[str, ...] = tuple(REGISTRY)

__all__ = ["REGISTRY", "STAGES", "Context", "Figure", "Output", "Stage"]
