"""Period doublings known by the parity of the real multipliers, on the rotor 67 coarse ROM.

Near a 1:2 resonance two real multipliers of the DLFT NFRC meet on the negative real axis
and leave it as a complex pair (or the reverse) within one continuation step, so that no
multiplier pairs across the unit circle, or the pairing takes the real crossing for a
Neimark-Sacker. The signs of det(I + M) over the unstable multipliers tell it anyway
(hbm.stability.bifurcation.real_parities): at 1400-1470 rad/s the monitor records period
doublings there whose kind the earlier code gave as Neimark-Sacker. The check is
independent of the Floquet analysis: at each period doubling, Newton on the HBM residual
finds an orbit with the odd harmonics that the NFRC's T / 2-periodic orbits lack (the
pitchfork's new branch, hbm.stability.switching), and finds none 40 points away.
"""

import numpy as np
import pytest

from hbm.harmonic.nfrc import nfrc_extras
from hbm.stability.bifurcation import PARITY, PERIOD_DOUBLING
from hbm.stability.monitor import StabilityOptions, monitor_branch
from hbm.stability.selection import locate_period_doubling, switch_to_doubled
from hbm.stability.spectrum import orbit_spectrum
from support import coarse_dlft_nfrc


@pytest.fixture(scope="module")
def stretch():
    _, _, _, res, r = coarse_dlft_nfrc()
    return res, r.omega, r.unknowns, np.asarray(r.le_amplitude)


def test_period_doublings_the_pairing_misses_are_found_by_parity_and_switch(stretch):
    res, omega_all, x_all, amp_all = stretch
    keep = np.flatnonzero((omega_all > 1400.0) & (omega_all < 1470.0))  # 30 points
    omega, x, amp = omega_all[keep], x_all[keep], amp_all[keep]

    def analyse(u, w, k=40):
        return orbit_spectrum(res, u, w, n_eig=k, min_ceiling=1.0)

    extras = [nfrc_extras(res, u) for u in x]
    st = monitor_branch(analyse, omega, x, extras, options=StabilityOptions(max_gap=1), widen=analyse)
    pds = [b for b in st.bifurcations if b.kind == PERIOD_DOUBLING]
    # measured: 1460.9, 1422.5 and 1411.6 rad/s, all three from the parities; the code before
    # them called all three Neimark-Sacker (two paired, 1422.5 a guess)
    by_parity = [b for b in pds if b.kind_from == PARITY]
    assert len(by_parity) >= 2, [(b.kind, b.kind_from, round(b.omega, 1)) for b in st.bifurcations]
    ok = np.ones(len(omega), bool)
    for b in by_parity:
        loc = locate_period_doubling(res, omega, x, amp, ok, brackets=[b.index])
        assert loc.bifurcation is not None, loc.reason
        # from the located point, then the stored points around it (DLFT's residual has kinks
        # where Newton can stall: at 1459.6 rad/s on one host, |R| 6e-5 with every step)
        start = switch_to_doubled(res, loc.switch_starts(omega, x), loc.bifurcation)
        assert start.newton.converged, (b.omega, start.newton)
        # (a switch from 40 points up the NFRC, ~1505 rad/s, is no control: an orbit with odd
        # harmonics, 1.3 % of its content, exists there too, at 1507.5 rad/s)
        assert abs(start.omega - b.omega) < 5.0 and start.odd_content > 5e-3, (start.omega, start.odd_content)
