"""Permanent sliding Coulomb friction at the blade tip, eqs. (29)-(30).

The casing is fixed; the blade turns at s Omega about z (s = +1 or -1, the sense of
rotation, right-hand rule: RomModel.rotation), so the tip slides on it with relative velocity
(v_theta + s rho Omega, v_z). Friction enters eq. (1) as f_nl = mu lam e (opposing
sliding), with e the unit sliding direction and lam >= 0 the normal force, N.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SlidingDirection:
    """Unit sliding direction and its derivatives, all of the velocity samples' shape.

    s_theta, s_z: components, 1. ds_theta_dvtheta, ds_theta_dvz (= ds_z_dvtheta),
    ds_z_dvz: derivatives w.r.t. the vibration velocities, s/m.
    """

    s_theta: np.ndarray
    s_z: np.ndarray
    ds_theta_dvtheta: np.ndarray
    ds_theta_dvz: np.ndarray
    ds_z_dvz: np.ndarray


def rotation_sense(rotation) -> int:
    """The sense of rotation s as an int, +1 or -1 (right-hand rule about z); raises
    ValueError naming the value otherwise. The one check every nonlinear stage makes of a
    ROM's or a system's `rotation`."""
    # a bool is an int to Python: True would pass as +1, a sense nobody wrote
    if isinstance(rotation, (bool, np.bool_)) or rotation not in (1, -1):
        raise ValueError(f"rotation must be +1 or -1 (right-hand rule about z), got {rotation!r}")
    return int(rotation)


def slide_direction(v_theta: np.ndarray, v_z: np.ndarray, rho: np.ndarray, omega: float,
                    rotation: int) -> SlidingDirection:
    """Sliding direction of eqs. (29)-(30).

    v_theta, v_z: vibration velocities, (..., n_b), m/s. rho: node radii, (n_b,), m.
    omega: rotation speed Omega > 0, rad/s. rotation: s = +1 or -1; the blade speed is
    s rho Omega. The blade speed (~100 m/s) keeps the relative speed far from 0; a floor of
    1e-12 m/s guards the division anyway. The derivatives do not depend on s.
    """
    rotation = rotation_sense(rotation)
    vt = v_theta + rotation * rho * omega
    n2 = vt * vt + v_z * v_z
    n = np.sqrt(np.maximum(n2, 1e-24))
    n3 = n * n * n
    return SlidingDirection(s_theta=vt / n, s_z=v_z / n, ds_theta_dvtheta=v_z * v_z / n3,
                            ds_theta_dvz=-vt * v_z / n3, ds_z_dvz=vt * vt / n3)
