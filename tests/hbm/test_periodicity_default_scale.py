"""classify_period (hbm.ti.periodicity) called without `scale`, on signals whose period is known
in closed form: sampled once per casing period T_c = 2 pi / (n_l Omega), a + b cos(n_l Omega t + phi)
repeats at every section (p = 1: omega = n_l Omega), so its sections differ by the round-off of
evaluating it only. The sections' own range is then that round-off, and, taken as the scale,
made it a mismatch of order 1: NONE for the casing's own period. The signal's range (2 b) gives
p = 1, and so must the default."""
import numpy as np
import pytest

from hbm.ti.periodicity import PeriodClass, classify_period

OMEGA = 1000.0  # rad/s


def _sections(n_lobes: int, n_sec: int, omega_ratio: float, offset: float = 0.3) -> np.ndarray:
    """1e-4 (offset + cos(r n_l Omega t + 0.4)) m at t = k T_c, two nodes (the second half the
    first), (n_sec, 2): r = 1 has the casing's period, r = 1 / n_l the revolution's."""
    t = np.arange(n_sec) * 2 * np.pi / (n_lobes * OMEGA)
    y = 1e-4 * (offset + np.cos(omega_ratio * n_lobes * OMEGA * t + 0.4))
    return y[:, None] * np.array([1.0, 0.5])


@pytest.mark.parametrize("n_lobes", [2, 3])
def test_a_response_of_the_casing_s_period_is_p_1_without_a_scale(n_lobes):
    y = _sections(n_lobes, 41, 1.0)
    assert 0.0 < np.ptp(y, axis=0).max() < 1e-12 * np.abs(y).max()  # the sections differ by round-off only
    with_range = classify_period(y, n_lobes=n_lobes, scale=np.array([2e-4, 1e-4]))
    assert (with_range.code, with_range.period) == (PeriodClass.CASING, 1)
    default = classify_period(y, n_lobes=n_lobes)
    assert (default.code, default.period, default.order) == (PeriodClass.CASING, 1, 1.0 / n_lobes)
    assert default.mismatch < 1e-3


def test_the_default_still_sees_a_change_of_the_sections_far_below_their_size():
    """The floor covers round-off only: sections of the casing's period plus noise of 1e-6 of
    their size (1e8 times their round-off) are no period, and the same change alternating from
    section to section is the revolution's period (p = 2 of two lobes)."""
    y = _sections(2, 41, 1.0)
    noise = 1e-6 * np.abs(y).max() * np.random.default_rng(0).uniform(-1.0, 1.0, y.shape)
    assert classify_period(y + noise).code == PeriodClass.NONE
    alternating = 1e-6 * np.abs(y).max() * np.where(np.arange(41) % 2 == 0, 1.0, -1.0)[:, None]
    got = classify_period(y + alternating)
    assert (got.code, got.period) == (PeriodClass.REVOLUTION, 2)


def test_the_revolution_s_period_and_a_constant_are_unchanged():
    """p = 2 of two lobes (cos Omega t: its sections alternate over the whole range) and a
    constant (range 0, or all zero: p = 1 with mismatch 0)."""
    got = classify_period(_sections(2, 41, 0.5))
    assert (got.code, got.period) == (PeriodClass.REVOLUTION, 2) and got.mismatch < 1e-12
    for value in (3.0, 0.0):
        got = classify_period(np.full((10, 2), value))
        assert (got.code, got.period, got.mismatch) == (PeriodClass.CASING, 1, 0.0)
