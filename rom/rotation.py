"""The sense of rotation of a blade, as the sign s = +1 or -1 the nonlinear stages use.

The blade turns about the rotation axis z at angular speed s Omega (Omega > 0): node j is
at the absolute angle s Omega t + theta_j, and the tip moves at s rho_j Omega along e_theta
(right-hand rule about z). A sign, not a guess: the ROM carries it (RomModel.rotation).
"""
from __future__ import annotations

import numpy as np


def check_sign(rotation) -> int:
    """s as an int, +1 or -1; raises ValueError naming the value otherwise (the ROM's own
    check: rom does not import the nonlinear side, whose hbm.contact.friction.rotation_sense
    makes the same one)."""
    # a bool is an int to Python: True would pass as +1, a sense nobody wrote
    if isinstance(rotation, (bool, np.bool_)) or rotation not in (1, -1):
        raise ValueError(f"rotation must be +1 or -1 (right-hand rule about z), got {rotation!r}")
    return int(rotation)


def rotation_sign(rotation: str | int, theta: np.ndarray) -> int:
    """s = +1 or -1 for a scene's [blade] rotation.

    rotation: "+", "-", "le-leads", or already a sign (+1, -1).
    theta: angles of the contact nodes, LE (first) to TE (last), (n_b,), rad; relative to the
        LE (BladeMesh.boundary_theta) or absolute (atan2's, in (-pi, pi]).
    "le-leads": the sense in which the leading edge leads, i.e. the blade turns towards the
    side where the LE is ahead of the TE: s = -sign(theta_TE - theta_LE) (rotor 67's table:
    theta_TE - theta_LE = +0.33 rad, so s = -1), the difference taken in (-pi, pi] (a blade
    spans far less than half a turn; absolute angles jump by 2 pi where it crosses the -x
    axis). Raises ValueError when the contact nodes span no angle (the sense cannot be
    derived; state "+" or "-").
    """
    if isinstance(rotation, (bool, np.bool_)):
        raise ValueError(f"rotation must be '+', '-', 'le-leads', +1 or -1, got the bool {rotation!r}")
    if isinstance(rotation, (int, np.integer)) and rotation in (1, -1):
        return int(rotation)
    if rotation == "+":
        return 1
    if rotation == "-":
        return -1
    if rotation != "le-leads":
        raise ValueError(f"unknown rotation {rotation!r}; known: '+', '-', 'le-leads'")
    theta = np.asarray(theta, dtype=float)
    span = float(theta[-1] - theta[0]) if len(theta) > 1 else 0.0
    # wrap into (-pi, pi]: LE at +3.0 rad and TE at -3.1 rad are 2 pi - 6.1 = +0.18 rad apart, not -6.1
    span = span - 2.0 * np.pi * np.ceil((span - np.pi) / (2.0 * np.pi))
    if not abs(span) > 1e-9:
        raise ValueError(f"rotation = 'le-leads' needs the contact nodes to span an angle (theta_TE - theta_LE "
                         f"= {span:.3g} rad): write rotation = '+' or '-' in [blade]")
    return -1 if span > 0 else 1
