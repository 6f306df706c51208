"""Alternating frequency/time transforms (section 1.3) with scipy's real FFT.

Harmonic coefficients follow eq. (5): rows [c_0, a_1, b_1, ..., a_Nh, b_Nh] with
c_0 = a_0 / 2 the mean, so that x(tau) = c_0 + sum_k a_k cos(k tau) + b_k sin(k tau),
tau = omega t sampled at tau_i = 2 pi i / N_t, i = 0 .. N_t - 1.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.fft as sfft  # numpy's irfft along axis 0 is ~5x slower (it copies to the last axis)


def _last_axis(axis: int, ndim: int) -> bool:
    """Whether a transform along `axis` (0 or -1) of an ndim array runs on the last axis."""
    if axis not in (0, -1, ndim - 1):
        raise ValueError(f"axis must be 0 or -1, got {axis}")
    return ndim > 1 and axis != 0


@dataclass(frozen=True)
class FourierBasis:
    """Truncated real Fourier basis of N_h harmonics sampled at N_t instants per period."""

    n_harmonics: int
    n_time: int

    def __post_init__(self):
        for name in ("n_harmonics", "n_time"):
            v = getattr(self, name)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer, float, np.floating)) \
                    or not float(v).is_integer():
                raise ValueError(f"{name} must be an integer, got {v!r}")
            object.__setattr__(self, name, int(v))
        if self.n_harmonics < 0:
            raise ValueError(f"n_harmonics must be >= 0, got {self.n_harmonics}")
        if self.n_time < 2 * self.n_harmonics + 1:
            # N_t samples resolve harmonics strictly below N_t / 2 (rfft bin N_t / 2 of an even
            # N_t has no sine part): N_t >= 2 N_h + 1, i.e. 2 N_h + 1 (odd) or 2 N_h + 2 (even)
            raise ValueError(f"n_time = {self.n_time} too small for {self.n_harmonics} harmonics "
                             f"(aliasing: n_time must be >= 2 n_harmonics + 1 = {2 * self.n_harmonics + 1})")

    def _check_length(self, a: np.ndarray, axis: int, expected: int, what: str) -> None:
        """A clear error for an array whose transformed axis has the wrong length."""
        if a.ndim == 0 or a.shape[axis if _last_axis(axis, a.ndim) else 0] != expected:
            raise ValueError(f"{what} must have {expected} rows along the transformed axis, got shape {a.shape}")

    @property
    def n_coeffs(self) -> int:
        """2 N_h + 1."""
        return 2 * self.n_harmonics + 1

    @cached_property
    def tau(self) -> np.ndarray:
        """Sample angles tau_i = 2 pi i / N_t, (N_t,), rad."""
        return 2.0 * np.pi * np.arange(self.n_time) / self.n_time

    @cached_property
    def orders(self) -> np.ndarray:
        """Harmonic order of each coefficient row, (2 N_h + 1,): [0, 1, 1, 2, 2, ...]."""
        return np.concatenate([[0], np.repeat(np.arange(1, self.n_harmonics + 1), 2)])

    # -- transforms ---------------------------------------------------------------------
    def to_time(self, coeffs: np.ndarray, axis: int = 0) -> np.ndarray:
        """Inverse transform (matrix F~ of eq. 11) along axis 0 (or the last axis, axis=-1).

        coeffs: (2 N_h + 1, ...) in eq. (5) order (axis=-1: (..., 2 N_h + 1)). Returns
        (N_t, ...) (axis=-1: (..., N_t)), same unit. The last-axis layout is ~30 % faster
        (contiguous transforms) where the caller holds many short signals.
        """
        c = np.asarray(coeffs)
        nh, nt = self.n_harmonics, self.n_time
        self._check_length(c, axis, self.n_coeffs, "coeffs (2 n_harmonics + 1)")
        if _last_axis(axis, c.ndim):
            spec = np.zeros(c.shape[:-1] + (nt // 2 + 1,), dtype=complex)
            spec[..., 0] = nt * c[..., 0]
            spec[..., 1:nh + 1] = 0.5 * nt * (c[..., 1::2] - 1j * c[..., 2::2])
            return sfft.irfft(spec, n=nt, axis=-1)
        spec = np.zeros((nt // 2 + 1,) + c.shape[1:], dtype=complex)
        spec[0] = nt * c[0]
        spec[1:nh + 1] = 0.5 * nt * (c[1::2] - 1j * c[2::2])
        return sfft.irfft(spec, n=nt, axis=0)

    def to_freq(self, signal: np.ndarray, axis: int = 0) -> np.ndarray:
        """Forward transform (matrix F of eq. 12) along axis 0 (or the last axis, axis=-1).

        signal: (N_t, ...) (axis=-1: (..., N_t)). Returns (2 N_h + 1, ...) in eq. (5)
        order (axis=-1: (..., 2 N_h + 1)), same unit.
        """
        s = np.asarray(signal)
        nh, nt = self.n_harmonics, self.n_time
        self._check_length(s, axis, nt, "signal (n_time samples)")
        if _last_axis(axis, s.ndim):
            spec = sfft.rfft(s, axis=-1)[..., :nh + 1]
            out = np.empty(s.shape[:-1] + (2 * nh + 1,))
            out[..., 0] = spec[..., 0].real / nt
            out[..., 1::2] = 2.0 / nt * spec[..., 1:].real
            out[..., 2::2] = -2.0 / nt * spec[..., 1:].imag
            return out
        spec = sfft.rfft(s, axis=0)[:nh + 1]
        out = np.empty((2 * nh + 1,) + s.shape[1:])
        out[0] = spec[0].real / nt
        out[1::2] = 2.0 / nt * spec[1:].real
        out[2::2] = -2.0 / nt * spec[1:].imag
        return out

    def derivative(self, coeffs: np.ndarray) -> np.ndarray:
        """Coefficients of d/dtau, (2 N_h + 1, ...): (a_k, b_k) -> (k b_k, -k a_k)."""
        c = np.asarray(coeffs)
        out = np.zeros_like(c, dtype=float)
        k = np.arange(1, self.n_harmonics + 1).reshape((-1,) + (1,) * (c.ndim - 1))
        out[1::2] = k * c[2::2]
        out[2::2] = -k * c[1::2]
        return out

    @cached_property
    def derivative_matrix(self) -> np.ndarray:
        """D with derivative(c) = D @ c, (2 N_h + 1, 2 N_h + 1), 1 per rad."""
        return self.derivative(np.eye(self.n_coeffs))

    def lanczos_sigma(self, nu: int = 1) -> np.ndarray:
        """Lanczos sigma factors of eq. (21) per coefficient row, (2 N_h + 1,).

        sigma_k = sinc(k / (N_h + 1)) with the normalised sinc sin(pi x) / (pi x), for a basis
        of Omega. In a basis of Omega / nu, harmonic k is the frequency k / nu of Omega and
        the filter is that of the basis of Omega with floor(N_h / nu) harmonics at it,
        sinc(k / (nu (floor(N_h / nu) + 1))): an orbit of period 2 pi / Omega is then a
        solution in both bases (a period-doubled branch meets the primary one at its
        bifurcation), whether the doubled basis has 2 N_h or 2 N_h + 1 harmonics.
        """
        return np.sinc(self.orders / (nu * (self.n_harmonics // nu + 1.0)))

    # -- Jacobians through AFT -------------------------------------------------------------
    def weighted_product(self, weights: np.ndarray) -> np.ndarray:
        """T(w) = F diag(w) F~ for time weights w, by one FFT of w.

        weights: (..., N_t). Returns (..., 2 N_h + 1, 2 N_h + 1): the Jacobian of the
        coefficients of f(t) = w(t) x(t) with respect to those of x. Built from
        W_m = (1 / N_t) sum_i w_i exp(-i m tau_i), m = 0 .. 2 N_h, with product-to-sum identities
        (exact for any N_t >= 2 N_h + 1: orders k + l >= N_t / 2 alias as the sampled product does).
        """
        w = np.asarray(weights, dtype=float)
        nh, nt = self.n_harmonics, self.n_time
        self._check_length(w, -1, nt, "weights (n_time samples)")
        if nt // 2 >= 2 * nh:
            W = sfft.rfft(w, axis=-1)[..., :2 * nh + 1] / nt
        else:  # orders k + l beyond N_t / 2 alias: take them from the full FFT
            W = sfft.fft(w, axis=-1)[..., np.arange(2 * nh + 1) % nt] / nt
        k = np.arange(1, nh + 1)
        dif = k[:, None] - k[None, :]
        sm = k[:, None] + k[None, :]
        Wd = np.where(dif >= 0, W[..., np.abs(dif)], np.conj(W[..., np.abs(dif)]))  # W_{k-l}
        Ws = W[..., sm]
        out = np.empty(w.shape[:-1] + (2 * nh + 1, 2 * nh + 1))
        out[..., 0, 0] = W[..., 0].real
        out[..., 0, 1::2] = W[..., 1:nh + 1].real
        out[..., 0, 2::2] = -W[..., 1:nh + 1].imag
        out[..., 1::2, 0] = 2.0 * W[..., 1:nh + 1].real
        out[..., 2::2, 0] = -2.0 * W[..., 1:nh + 1].imag
        out[..., 1::2, 1::2] = Wd.real + Ws.real
        out[..., 2::2, 2::2] = Wd.real - Ws.real
        # row a_k, col b_l: -(Im W_{k+l} - Im W_{k-l}) ; row b_k, col a_l: -(Im W_{k+l} + Im W_{k-l})
        out[..., 1::2, 2::2] = -Ws.imag + Wd.imag
        out[..., 2::2, 1::2] = -Ws.imag - Wd.imag
        return out
