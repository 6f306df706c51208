"""Bifurcations of a branch of periodic orbits: the crossings of the unit circle by Floquet
multipliers between two analysed points, classified with respect to the orbit's minimal
period, and their location.

Kinds (multiplier mu of the minimal period T_min crossing |mu| = 1):
- "fold": mu = +1 where the branch turns back in Omega (a limit point);
- "branch point": mu = +1 without a turn (another branch of the same period crosses);
- "period doubling": mu = -1 (a branch of period 2 T_min is born). On the rotor 67 NFRC,
  whose orbits hold only even harmonics of Omega (T_min = pi / Omega), it shows up in the
  omega = Omega basis as a multiplier +1 with an odd-harmonic eigenvector, a
  symmetry-breaking branch point: classified here on the minimal period, it is what it is
  physically, a period doubling;
- "Neimark-Sacker": a complex pair (quasi-periodic motion is born).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

FOLD = "fold"
BRANCH_POINT = "branch point"
PERIOD_DOUBLING = "period doubling"
NEIMARK_SACKER = "Neimark-Sacker"
UNCLASSIFIED = "unclassified"
KINDS = (FOLD, BRANCH_POINT, PERIOD_DOUBLING, NEIMARK_SACKER, UNCLASSIFIED)

#: a multiplier is real when its argument is within this of 0 or pi, rad: the exponents of
#: real multipliers are exactly real or exactly omega / 2 (mod omega) for Hill's exact
#: problem, but DLFT's truncated one moves them by ~1 1/s (Im lam T ~ 2e-3 rad at
#: Omega = 1300 rad/s, measured on the rotor 67 NFRC); a complex pair within 1 degree of the
#: real axis crossing the unit circle is, in practice, a fold or a period doubling.
REAL_ARG_TOL = 0.02


@dataclass(frozen=True, eq=False)
class Bifurcation:
    """One bifurcation along a branch.

    kind: one of KINDS. omega: Omega at the bifurcation, rad/s. le_amplitude: LE amplitude
    there (half peak-to-peak radial displacement), m. index: the branch point after which it
    lies; fraction: its position between points index and index + 1 in arc length, [0, 1].
    omega_bracket: (Omega at index, at index + 1), rad/s: the located value is inside;
    the interpolation error is a fraction of this bracket (see `locate`).
    multiplier: the crossing multiplier of the minimal period at the point on its unstable
    side (where a period doubling's is real), -.
    direction: +1 when the orbit loses stability going along the branch, -1 when it gains it.
    period_ratio: g, the orbit's minimal period is T / g (T of the HBM basis).
    exponent: the crossing Floquet exponent (centred member, see FloquetSpectrum) there, 1/s.
    mode_omega: fundamental of the basis the mode was computed in (that of the minimal
    period at that point), rad/s.
    eigenvector: the crossing Floquet mode exp(exponent t) p(t) at that point: p's
    coefficients (2 N' + 1, n) complex in the minimal period's basis (N' = N_h / g), all
    ROM dof, eq. (5) order; None for folds.
    paired: whether one multiplier was found on both sides of the circle (crossings), so
    that kind, multiplier and fraction are measured. False where the count of unstable
    multipliers changed with no multiplier pairing across the circle (it moved too far
    between the two analyses, or past the pairing window): kind and multiplier are then
    those of the unstable multiplier nearest the circle on the side with more of them
    (leaving out those paired with an unstable one of the other side), a guess, and the
    bifurcation is placed half-way. A fold is located by the turn in Omega
    (True).
    """

    kind: str
    omega: float
    le_amplitude: float
    index: int
    fraction: float
    omega_bracket: tuple[float, float]
    multiplier: complex
    direction: int
    period_ratio: int = 1
    exponent: complex = 0j
    mode_omega: float = 0.0
    eigenvector: np.ndarray | None = field(default=None, repr=False)
    paired: bool = True


def classify(mu: complex, fold: bool) -> str:
    """Kind of a crossing by its multiplier's argument (and whether the branch turns there)."""
    a = abs(np.angle(mu))
    if a <= REAL_ARG_TOL:
        return FOLD if fold else BRANCH_POINT
    if a >= np.pi - REAL_ARG_TOL:
        return PERIOD_DOUBLING
    return NEIMARK_SACKER


def upper_half(mu: np.ndarray) -> np.ndarray:
    """(m,) bool: one multiplier of each conjugate pair (Im >= 0) and every real one (also a
    real negative one whose round-off put it at arg = -pi)."""
    a = np.angle(np.asarray(mu))
    return (a >= -REAL_ARG_TOL) | (np.abs(a) >= np.pi - REAL_ARG_TOL)


def pair_multipliers(mu_a: np.ndarray, mu_b: np.ndarray, floor: float, window: float = 1.0):
    """Pairs (i, j) of the same multiplier at two nearby points (mu_a[i] ~ mu_b[j]).

    Only multipliers with Im >= 0 (one of each conjugate pair), above floor (the larger
    modulus_floor of the two spectra: below it one may be missing) and with
    |log|mu|| < window are paired, greedily by distance in (log|mu|, |arg mu|).
    """
    def keep(mu):
        mu = np.asarray(mu)
        ok = upper_half(mu) & (np.abs(mu) > floor)
        lm = np.log(np.abs(mu), where=ok, out=np.full(mu.shape, -np.inf))
        return np.flatnonzero(ok & (np.abs(lm) < window))

    ia, ib = keep(mu_a), keep(mu_b)
    if not len(ia) or not len(ib):
        return []

    def coords(mu):
        return np.stack([np.log(np.abs(mu)), np.abs(np.angle(mu))], axis=-1)

    ca, cb = coords(np.asarray(mu_a)[ia]), coords(np.asarray(mu_b)[ib])
    d = np.linalg.norm(ca[:, None] - cb[None], axis=-1)
    pairs, used_a, used_b = [], set(), set()
    for flat in np.argsort(d, axis=None):
        i, j = np.unravel_index(flat, d.shape)
        if i in used_a or j in used_b:
            continue
        used_a.add(i)
        used_b.add(j)
        pairs.append((int(ia[i]), int(ib[j])))
    return pairs


def crossings(mu_a: np.ndarray, mu_b: np.ndarray, floor: float, window: float = 1.0):
    """The pairs of pair_multipliers on opposite sides of the unit circle: the crossings
    between the two points."""
    return [(i, j) for i, j in pair_multipliers(mu_a, mu_b, floor, window)
            if (abs(mu_a[i]) > 1.0) != (abs(mu_b[j]) > 1.0)]


def parabola_vertex(s: np.ndarray, y: np.ndarray, z: np.ndarray | None = None):
    """Vertex of the parabola y(s) through three points, and z(s) on the parabola through
    (s, z) there: (s*, y*, z*). s, y, z: (3,).

    The fit is made in t = (s - s_1) / max |s - s_1| (in [-1, 1]): along a long branch s is
    large and the three points close (arc length ~1e3 apart by 1e-5 near a crawl), where a
    fit in s itself is ill-conditioned (numpy's RankWarning) and loses the vertex."""
    s, y = np.asarray(s, float), np.asarray(y, float)
    scale = float(np.max(np.abs(s - s[1])))
    c = np.polyfit((s - s[1]) / scale, y, 2) if scale > 0.0 else np.zeros(3)
    if c[0] == 0.0:
        k = int(np.argmax(np.abs(y - y.mean())))
        return float(s[k]), float(y[k]), (float(z[k]) if z is not None else None)
    tt = float(np.clip(-c[1] / (2.0 * c[0]), (s.min() - s[1]) / scale, (s.max() - s[1]) / scale))
    zz = float(np.polyval(np.polyfit((s - s[1]) / scale, np.asarray(z, float), 2), tt)) if z is not None else None
    return s[1] + scale * tt, float(np.polyval(c, tt)), zz


def bifurcation_arrays(bifurcations) -> dict:
    """The bifurcation table as arrays for a file (k rows), with units:

    kind (k,) str; omega (k,) rad/s; le_amplitude (k,) m; index (k,) int; fraction (k,) -;
    omega_low, omega_high (k,) rad/s (the bracketing points); multiplier_real,
    multiplier_imag (k,) -; direction (k,) int (+1 loses stability along the branch);
    period_ratio (k,) int; paired (k,) bool (False: the kind is a guess, see Bifurcation).
    Returns {name: (array, unit)}.
    """
    b = list(bifurcations)
    return {
        "kind": (np.array([x.kind for x in b], dtype=object), "-"),
        "omega": (np.array([x.omega for x in b], dtype=float), "rad/s"),
        "le_amplitude": (np.array([x.le_amplitude for x in b], dtype=float), "m"),
        "index": (np.array([x.index for x in b], dtype=np.int64), "-"),
        "fraction": (np.array([x.fraction for x in b], dtype=float), "-"),
        "omega_low": (np.array([x.omega_bracket[0] for x in b], dtype=float), "rad/s"),
        "omega_high": (np.array([x.omega_bracket[1] for x in b], dtype=float), "rad/s"),
        "multiplier_real": (np.array([np.real(x.multiplier) for x in b], dtype=float), "-"),
        "multiplier_imag": (np.array([np.imag(x.multiplier) for x in b], dtype=float), "-"),
        "direction": (np.array([x.direction for x in b], dtype=np.int64), "-"),
        "period_ratio": (np.array([x.period_ratio for x in b], dtype=np.int64), "-"),
        "paired": (np.array([x.paired for x in b], dtype=bool), "-"),
    }


def bifurcations_from_arrays(table: dict) -> tuple:
    """The Bifurcation tuple of a table read back from a file ({name: array} of the columns
    bifurcation_arrays writes): what a resumed branch starts from. The file holds no
    exponent, mode or eigenvector: those stay at their defaults; a file written before the
    paired column reads as paired."""
    n = len(np.asarray(table["omega"]))
    col = {k: np.asarray(v) for k, v in table.items()}
    paired = col.get("paired", np.ones(n, bool))
    return tuple(Bifurcation(
        kind=str(col["kind"][i]), omega=float(col["omega"][i]), le_amplitude=float(col["le_amplitude"][i]),
        index=int(col["index"][i]), fraction=float(col["fraction"][i]),
        omega_bracket=(float(col["omega_low"][i]), float(col["omega_high"][i])),
        multiplier=complex(float(col["multiplier_real"][i]), float(col["multiplier_imag"][i])),
        direction=int(col["direction"][i]), period_ratio=int(col["period_ratio"][i]),
        paired=bool(paired[i])) for i in range(n))
