"""Options of the finite-element stage (scene section [fem])."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FemOptions:
    """n_modes: number of full-model modes computed and stored (>= 6 for the report)."""

    n_modes: int = 12

    def __post_init__(self):
        if self.n_modes < 1:
            raise ValueError(f"n_modes must be >= 1, got {self.n_modes}")
