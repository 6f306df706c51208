"""Options of the pipeline's own outputs (figures, rendering)."""
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
        if len(self.window) != 2 or min(self.window) < 16:
            raise ValueError(f"window must be [width, height] in pixels, got {list(self.window)}")
