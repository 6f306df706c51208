"""Options of the pipeline's own outputs (figures, rendering) and of its size guard."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RenderOptions:
    """Off-screen mode-shape rendering.

    n_modes: how many of the full model's first modes to render (0: none).
    scale: largest displacement drawn, as a fraction of the blade's largest dimension.
    window: image size in pixels (width, height).
    """

    n_modes: int = 6
    scale: float = 0.08
    window: tuple[int, ...] = (1200, 900)

    def __post_init__(self):
        if self.n_modes < 0:
            raise ValueError(f"n_modes must be >= 0, got {self.n_modes}")
        if not self.scale > 0:
            raise ValueError(f"scale must be > 0 (the largest displacement drawn, a fraction of the blade), "
                             f"got {self.scale}")
        if len(self.window) != 2 or min(self.window) < 16:
            raise ValueError(f"window must be [width, height] in pixels, got {list(self.window)}")


@dataclass(frozen=True)
class LimitOptions:
    """What the size guard lets a run do before it refuses (scene section [limits]).

    memory_gb: largest memory one stage may be estimated to need, GB; 0 (the default): this
      machine's physical memory. Raise it (or pass --yes) to run a scene the guard refuses.
    """

    memory_gb: float = 0.0

    def __post_init__(self):
        if self.memory_gb < 0:
            raise ValueError(f"memory_gb must be >= 0 GB (0: this machine's memory), got {self.memory_gb}")
