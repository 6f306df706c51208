"""Isotropic linear-elastic material (scene section [material])."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Material:
    """Isotropic linear elastic material; defaults: Ti-6Al-4V of the reference paper.

    E: Young's modulus, Pa. rho: density, kg/m^3. nu: Poisson's ratio, -.
    """

    E: float = 108e9
    rho: float = 4400.0
    nu: float = 0.34
    name: str = "Ti-6Al-4V"

    def __post_init__(self):
        if not self.E > 0:
            raise ValueError(f"Young's modulus E must be > 0 Pa, got {self.E}")
        if not self.rho > 0:
            raise ValueError(f"density rho must be > 0 kg/m^3, got {self.rho}")
        if not -1.0 < self.nu < 0.5:
            raise ValueError(f"Poisson's ratio nu must lie in (-1, 0.5), got {self.nu}: "
                             "nu >= 0.5 is incompressible, no displacement formulation applies")

    @property
    def lame(self) -> tuple[float, float]:
        """Lame parameters (lambda, mu), Pa."""
        mu = self.E / (2 * (1 + self.nu))
        lmbda = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))
        return lmbda, mu
