"""Isotropic linear-elastic material (scene section [material])."""
from __future__ import annotations

from dataclasses import dataclass

# SI ranges of a solid a blade can be made of, wide enough for any alloy, ceramic or
# composite and narrow enough to stop the usual unit slips, which would otherwise shift
# every frequency by a factor of 30 to 3e4 without a word: E in GPa (108) or MPa (1.08e5,
# the mm-N-t system) against 1e6; rho in g/cm^3 (4.4), t/mm^3 (4.4e-9) or lb/in^3 (0.16)
# against 100.
E_RANGE = (1e6, 2e12)  # Pa: soft polymers .. above diamond (1.2e12)
RHO_RANGE = (100.0, 3e4)  # kg/m^3: balsa .. above osmium (22 590)
# Poisson's ratio: the P2 displacement elements lock as nu -> 0.5 (lambda / mu -> inf) and
# as nu -> -1 (mu / bulk modulus -> inf). First bending of a 0.1 x 0.02 x 0.01 m cantilever,
# 20x4x2 tet10 divisions against 40x8x4: +0.23 % at nu = 0.3, +0.35 % at -0.5, +0.9 % at
# 0.45, but +3.1 % at 0.499 and +1.6 % at -0.9 (+3.2 % at -0.99); no blade alloy lies
# outside [-0.5, 0.45].
NU_RANGE = (-0.5, 0.45)


@dataclass(frozen=True)
class Material:
    """Isotropic linear elastic material; defaults: Ti-6Al-4V of the reference paper.

    E: Young's modulus, Pa, in E_RANGE. rho: density, kg/m^3, in RHO_RANGE.
    nu: Poisson's ratio, -, in NU_RANGE (the elements lock beyond it).
    """

    E: float = 108e9
    rho: float = 4400.0
    nu: float = 0.34
    name: str = "Ti-6Al-4V"

    def __post_init__(self):
        if not E_RANGE[0] <= self.E <= E_RANGE[1]:
            raise ValueError(f"Young's modulus E must be in Pa, between {E_RANGE[0]:g} and {E_RANGE[1]:g} "
                             f"(any solid a blade is made of), got {self.E:g}"
                             + (": in GPa or MPa? (Ti-6Al-4V: 108e9 Pa)" if 0 < self.E < E_RANGE[0] else ""))
        if not RHO_RANGE[0] <= self.rho <= RHO_RANGE[1]:
            raise ValueError(f"density rho must be in kg/m^3, between {RHO_RANGE[0]:g} and {RHO_RANGE[1]:g} "
                             f"(any solid a blade is made of), got {self.rho:g}"
                             + (": in g/cm^3 or t/mm^3? (Ti-6Al-4V: 4400 kg/m^3)" if 0 < self.rho < RHO_RANGE[0]
                                else ""))
        if not NU_RANGE[0] <= self.nu <= NU_RANGE[1]:
            if -1.0 < self.nu < 0.5:
                why = (f"the P2 displacement elements lock towards {'0.5' if self.nu > 0 else '-1'} and the "
                       "frequencies come out several % high on usual meshes")
            else:
                why = "a stable isotropic solid has -1 < nu < 0.5 (0.5: incompressible)"
            raise ValueError(f"Poisson's ratio nu must lie in [{NU_RANGE[0]:g}, {NU_RANGE[1]:g}], got {self.nu}: {why}")

    @property
    def lame(self) -> tuple[float, float]:
        """Lame parameters (lambda, mu), Pa."""
        mu = self.E / (2 * (1 + self.nu))
        lmbda = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))
        return lmbda, mu
