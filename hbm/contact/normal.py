"""Normal contact laws evaluated on time samples (sections 1.4 and 1.5).

Convention: lam >= 0 is the compressive normal force magnitude, N; it enters the
equation of motion (1) as f_nl = +lam on the radial dof (the casing pushes the tip
inward). gap g = r - d, m: positive means the tip is beyond the casing (penetration).
"""
from __future__ import annotations

import numpy as np


def correct_dlft(prediction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DLFT correction of the predicted Lagrangian, eq. (15).

    prediction: lam_pre(t_i) = (f_ext - Z x)(t_i) + epsilon g_x(t_i), any shape, N.
    Returns (lam, active): lam = max(0, lam_pre), N, and the contact indicator
    (lam_pre > 0), same shape; d lam / d lam_pre = active.
    """
    active = prediction > 0.0
    return np.where(active, prediction, 0.0), active


def regularised_penalty(gap: np.ndarray, kappa: float, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """Regularised penalty law, eq. (19): lam = kappa g / 2 + sqrt((kappa g / 2)^2 + gamma^2).

    gap: g = r - d, any shape, m. kappa: N/m. gamma: N.
    Returns (lam, dlam_dg): N and N/m, same shape. gamma = 0 gives the penalty law (18).
    """
    h = 0.5 * kappa * np.asarray(gap)
    root = np.sqrt(h * h + gamma * gamma)
    if gamma > 0.0:
        # written to avoid the cancellation h + root for h << 0: lam = gamma^2 / (root - h)
        with np.errstate(divide="ignore"):  # root - h = 0 only where h >= 0 (not selected)
            lam = np.where(h >= 0.0, h + root, gamma * gamma / (root - h))
        dlam = 0.5 * kappa * lam / root  # = kappa/2 (1 + h/root)
    else:
        lam = np.maximum(2.0 * h, 0.0)
        dlam = np.where(h > 0.0, kappa, 0.0)
    return lam, dlam
