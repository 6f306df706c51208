"""Time integration started on an HBM orbit, to see whether it stays on it (the check of a
stability verdict by an independent code: hbm.ti's exact-contact central differences).

The march starts at the instant of the period where the orbit is farthest from the casing
(largest min_j (d_j - r_j)): started inside a contact phase, the first step of the
Lagrange-multiplier scheme removes the HBM orbit's small penetration (DLFT's Gibbs ripple,
RL's penalty) in one step, an impulse of penetration / dt that throws the blade off any
orbit. The casing angle is shifted accordingly (theta_j + s Omega t0, s the sense of
rotation): the same problem started at t0.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from hbm.contact.casing import casing_distance
from hbm.harmonic.fourier import FourierBasis
from hbm.options import CasingOptions
from hbm.ti.march import ModalSystem, Recording, march, rom_modal_system
from hbm.ti.sweep import steps_per_revolution


@dataclass(frozen=True)
class OrbitCheck:
    """How far time integration strays from an HBM orbit, period by period.

    omega: rotation speed Omega, rad/s. period: the orbit's period 2 pi nu / Omega, s.
    t0: start instant within the period, s. dt: time step, s.
    deviation: (n_periods, 2), max over each period of |r_TI - r_HBM| at the LE and TE radial
    dof, relative to the HBM orbit's half peak-to-peak radial displacement there, -.
    initial_margin: min_j (d_j - r_j) at t0, m (> 0: no node in contact at the start).
    """

    omega: float
    period: float
    t0: float
    dt: float
    deviation: np.ndarray

    @property
    def growth(self) -> float:
        """Deviation over the last 10 % of the periods relative to the first 10 %, max over LE/TE."""
        n = max(1, len(self.deviation) // 10)
        return float(np.max(self.deviation[-n:].max(axis=0) / np.maximum(self.deviation[:n].max(axis=0), 1e-300)))


def march_from_orbit(rom, casing: CasingOptions, mu: float, coeffs: np.ndarray, omega: float, *,
                     subharmonic: int = 1, n_periods: int = 100, dt: float = 1e-7,
                     samples_per_period: int = 128) -> OrbitCheck:
    """March n_periods from an HBM orbit and measure its distance to the orbit period by period.

    rom: RomModel (or a hbm.ti.march.ModalSystem). coeffs: full-dof harmonics of the orbit,
    (2 N_h + 1, n), m, eq. (5) order, in the basis of omega / subharmonic (rad/s; omega is
    the rotation speed Omega). dt: largest time step, s (shrunk to divide the period).
    """
    system = rom if isinstance(rom, ModalSystem) else rom_modal_system(rom)
    c = np.asarray(coeffs, dtype=float)
    nh = (c.shape[0] - 1) // 2
    nb = system.n_boundary
    w = omega / subharmonic  # fundamental of the basis, rad/s
    T = 2.0 * np.pi / w
    n_per = steps_per_revolution(w, dt, samples_per_period)
    h = T / n_per
    # start where the orbit is farthest from contact
    fine = FourierBasis(nh, max(4 * samples_per_period, 2 * nh + 2))
    r = fine.to_time(c[:, 0:3 * nb:3])  # (N_t, n_b)
    sense = system.rotation
    d = casing_distance(subharmonic * fine.tau, sense * system.theta, casing)  # node j at s tau + theta_j
    margin = (d - r).min(axis=1)
    i0 = int(np.argmax(margin))
    t0 = fine.tau[i0] / w
    k = np.arange(1, nh + 1)[:, None]
    ph = k * w * t0
    x0 = c[0] + (c[1::2] * np.cos(ph) + c[2::2] * np.sin(ph)).sum(axis=0)
    v0 = (k * w * (-c[1::2] * np.sin(ph) + c[2::2] * np.cos(ph))).sum(axis=0)
    # the march's casing angle tau + s theta_j, started at t0: s theta_j -> s theta_j + Omega t0
    shifted = replace(system, theta=system.theta + sense * omega * t0)
    stride = n_per // samples_per_period
    cols = [0, 3 * (nb - 1)]
    rec = Recording(start=stride, stride=stride, n_samples=n_periods * samples_per_period,
                    dofs=np.array(cols), force_nodes=np.array([0]))
    m = march(shifted, casing, mu, omega, x0, v0, h, n_periods * n_per, rec)
    t = t0 + m.times
    ref = c[0, cols] + sum(np.outer(np.cos(kk * w * t), c[2 * kk - 1, cols]) + np.outer(np.sin(kk * w * t), c[2 * kk, cols])
                           for kk in range(1, nh + 1))
    amp = 0.5 * np.ptp(fine.to_time(c[:, cols]), axis=0)
    dev = np.abs(m.displacement - ref).reshape(n_periods, samples_per_period, 2).max(axis=1) / amp
    return OrbitCheck(omega=float(omega), period=float(T), t0=float(t0), dt=float(h), deviation=dev)
