"""Options of the pipeline's own outputs (figures, rendering) and of its size guard."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RenderOptions:
    """Off-screen mode-shape rendering and the ParaView (VTU) output.

    n_modes: how many of the full model's first modes to render, as PNGs and as the point
      vectors of figures/modes.vtu (0: none).
    scale: largest displacement drawn, as a fraction of the blade's largest dimension.
    window: image size in pixels (width, height).
    hbm_instants: instants over one period of an HBM solution written as full-field
      displacements (figures/hbm_METHOD.pvd and its VTU files; 0: none). 16 resolves the
      2-lobe casing's 2 Omega response with 8 frames per cycle.
    hbm_omega: the NFRC point written: the converged point of the first [hbm] method nearest
      to this Omega, rad/s; unset: the converged point of largest LE amplitude.
    """

    n_modes: int = 6
    scale: float = 0.08
    window: tuple[int, ...] = (1200, 900)
    hbm_instants: int = 16
    hbm_omega: float | None = None

    def __post_init__(self):
        if self.n_modes < 0:
            raise ValueError(f"n_modes must be >= 0, got {self.n_modes}")
        if not self.scale > 0:
            raise ValueError(f"scale must be > 0 (the largest displacement drawn, a fraction of the blade), "
                             f"got {self.scale}")
        if self.hbm_instants < 0:
            raise ValueError(f"hbm_instants must be >= 0, got {self.hbm_instants}")
        if self.hbm_omega is not None and not self.hbm_omega > 0:
            raise ValueError(f"hbm_omega must be > 0 rad/s, got {self.hbm_omega}")
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
