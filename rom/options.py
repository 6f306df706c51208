"""Options of the Craig-Bampton stage (scene section [rom])."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RomOptions:
    """n_fixed_modes: fixed-interface modes kept (eta); at most the interior dof count of
        the FEM model (rom.craig_bampton checks it, knowing the model).
    damping_low: modal damping ratio of the ROM's first `n_low_modes` modes (1B, 2B, 1T).
    damping_high: modal damping ratio of all other ROM modes.
    """

    n_fixed_modes: int = 12
    damping_low: float = 1e-3
    damping_high: float = 5e-3
    n_low_modes: int = 3

    def __post_init__(self):
        for k in ("n_fixed_modes", "n_low_modes"):  # counts (numpy integers too: read back from HDF5)
            v = getattr(self, k)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
                raise ValueError(f"{k} must be an integer (a count of modes), got {v!r}")
        if self.n_fixed_modes < 0:
            raise ValueError(f"n_fixed_modes must be >= 0, got {self.n_fixed_modes}")
        if self.n_low_modes < 0:
            raise ValueError(f"n_low_modes must be >= 0 (a count of modes), got {self.n_low_modes}")
        for k in ("damping_low", "damping_high"):
            v = getattr(self, k)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)) \
                    or not 0 <= v < 1:
                raise ValueError(f"{k} must be a damping ratio, a number in [0, 1), got {v!r}")
