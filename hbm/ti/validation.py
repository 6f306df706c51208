"""Time integration started on a harmonic-balance solution (section 3.3, Fig. 9).

x(0), x'(0) come from the HBM harmonics; the ROM is marched n_periods periods T = 2 pi / Omega
with exact (Lagrange multiplier) contact, and the last period is compared at the LE and TE
with the HBM signals. Displacements are compared sample by sample. Contact forces are not:
the multiplier method delivers impacts as one-step impulses that no N_h-harmonic signal can
follow, so the TI normal force is first projected on the HBM's own N_h harmonics (the
Fourier coefficients of the force over the period, exact impulses included) and that
truncated signal is compared with the HBM force (DLFT or regularised penalty).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hbm.harmonic.fourier import FourierBasis
from hbm.options import CasingOptions, ContactOptions
from hbm.ti.sweep import steps_per_revolution
from hbm.ti.march import ModalSystem, Recording, march, rom_modal_system


@dataclass(frozen=True)
class ValidationResult:
    """TI against HBM over the last simulated period, at the LE and TE (columns 0, 1).

    omega: Omega = omega, rad/s. n_periods: periods simulated. dt: time step used, s.
    tau: HBM sample angles Omega t mod 2 pi of the last period, (N_t,), rad.
    hbm_displacement, ti_displacement: radial displacement, (N_t, 2), m.
    hbm_force: HBM normal force lam, (N_t, 2), N (nan when not given).
    ti_force: TI normal force truncated to the HBM's N_h harmonics, (N_t, 2), N.
    ti_force_peak: largest TI multiplier in the last period (unfiltered), (2,), N.
    displacement_error: max_t |r_TI - r_HBM| / max_t |r_HBM|, (2,), -.
    force_error: max_t |lam_TI,Nh - lam_HBM| / max_t |lam_HBM|, (2,), - (nan without forces).
    drift: max_t |r(t) - r(t - T)| / max_t |r| over the last period: how far TI is from
    T-periodic, (2,), -. max_penetration: largest r_j - d_j after contact correction, m.
    """

    omega: float = field(metadata={"unit": "rad/s"})
    n_periods: int = field(metadata={"unit": "1"})
    dt: float = field(metadata={"unit": "s"})
    tau: np.ndarray = field(metadata={"unit": "rad"})
    hbm_displacement: np.ndarray = field(metadata={"unit": "m"})
    ti_displacement: np.ndarray = field(metadata={"unit": "m"})
    hbm_force: np.ndarray = field(metadata={"unit": "N"})
    ti_force: np.ndarray = field(metadata={"unit": "N"})
    ti_force_peak: np.ndarray = field(metadata={"unit": "N"})
    displacement_error: np.ndarray = field(metadata={"unit": "1"})
    force_error: np.ndarray = field(metadata={"unit": "1"})
    drift: np.ndarray = field(metadata={"unit": "1"})
    max_penetration: float = field(metadata={"unit": "m"})


def initial_state(coeffs: np.ndarray, omega: float) -> tuple[np.ndarray, np.ndarray]:
    """x(0) and x'(0) of x(t) = c_0 + sum_k a_k cos k w t + b_k sin k w t.

    coeffs: (2 N_h + 1, n) in the order [c_0 = a_0 / 2, a_1, b_1, ..., a_Nh, b_Nh], m.
    omega: w, rad/s. Returns ((n,) m, (n,) m/s).
    """
    c = np.asarray(coeffs, dtype=float)
    k = np.arange(1, (c.shape[0] - 1) // 2 + 1)[:, None]
    return c[0] + c[1::2].sum(axis=0), omega * (k * c[2::2]).sum(axis=0)


def validate_against_hbm(rom, casing: CasingOptions, contact: ContactOptions, coeffs: np.ndarray, omega: float,
                         forces: np.ndarray | None = None, n_periods: int = 100, dt: float = 1e-7,
                         n_time: int | None = None) -> ValidationResult:
    """March n_periods from an HBM solution and compare the last period with it.

    rom: RomModel (or ModalSystem). coeffs: full-dof HBM harmonics, (2 N_h + 1, n), m, eq. (5)
    order, omega = Omega. omega: rad/s. forces: HBM normal forces lam at tau_i = 2 pi i / N_t,
    (N_t, n_b), N (e.g. HarmonicBalanceResidual.signals(...)["lam"]); optional.
    dt: requested step, s (shrunk so that T / dt is a multiple of N_t). n_time: N_t when no
    forces are given (default 1024).
    """
    system = rom if isinstance(rom, ModalSystem) else rom_modal_system(rom)
    c = np.asarray(coeffs, dtype=float)
    if c.ndim != 2 or c.shape[1] != system.n_dof or c.shape[0] % 2 != 1:
        raise ValueError(f"coeffs must be (2 N_h + 1, {system.n_dof}), got {c.shape}")
    if n_periods < 3:
        raise ValueError(f"need n_periods >= 3, got {n_periods}")
    n_h = (c.shape[0] - 1) // 2
    nb = system.n_boundary
    cols = [0, nb - 1]
    if forces is not None:
        forces = np.asarray(forces, dtype=float)
        if forces.ndim != 2 or forces.shape[1] != nb:
            raise ValueError(f"forces must be (N_t, {nb}), got {forces.shape}")
        n_time = forces.shape[0]
    n_time = int(n_time or 1024)
    n_per = steps_per_revolution(omega, dt, n_time)
    dt_eff = 2.0 * np.pi / (omega * n_per)
    x0, v0 = initial_state(c, omega)
    # the last two periods at every step: the last for the comparison, both for the drift
    rec = Recording(start=(n_periods - 2) * n_per, stride=1, n_samples=2 * n_per,
                    dofs=np.array([3 * j for j in cols]), force_nodes=np.array(cols))
    m = march(system, casing, contact.mu, omega, x0, v0, dt_eff, n_periods * n_per, rec)
    x_all, f_all = m.displacement, m.normal_force
    last_x, prev_x = x_all[n_per:], x_all[:n_per]
    last_f = f_all[-n_per:]
    # samples of the last period start at a multiple of T: tau_i = 2 pi i / N_t
    hb = FourierBasis(n_h, n_time)
    hbm_x = hb.to_time(c[:, [3 * j for j in cols]])
    ti_x = last_x[::n_per // n_time]
    scale_x = np.abs(hbm_x).max(axis=0)
    disp_err = np.abs(ti_x - hbm_x).max(axis=0) / scale_x
    ti_f = hb.to_time(FourierBasis(n_h, n_per).to_freq(last_f))
    if forces is not None:
        hbm_f = forces[:, cols]
        force_err = np.abs(ti_f - hbm_f).max(axis=0) / np.abs(hbm_f).max(axis=0)
    else:
        hbm_f = np.full_like(ti_f, np.nan)
        force_err = np.full(2, np.nan)
    drift = np.abs(last_x - prev_x).max(axis=0) / np.abs(last_x).max(axis=0)
    return ValidationResult(omega=float(omega), n_periods=int(n_periods), dt=dt_eff, tau=hb.tau,
                            hbm_displacement=hbm_x, ti_displacement=ti_x, hbm_force=hbm_f, ti_force=ti_f,
                            ti_force_peak=last_f.max(axis=0), displacement_error=disp_err,
                            force_error=force_err, drift=drift, max_penetration=m.max_penetration)
