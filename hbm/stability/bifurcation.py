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

#: How a bifurcation's kind is known (Bifurcation.kind_from):
#: "crossing": one multiplier paired on both sides of the unit circle, classified by its argument;
#: "parity": the signs of det(I + M), det(I - M) (real_parities) say that an odd number of real
#: multipliers went through -1 (a period doubling) or +1 (a fold or branch point), where no
#: multiplier pairs across or the paired ones do not add up to the count change;
#: "guess": neither, the kind of the unstable multiplier nearest the circle (see Bifurcation).
CROSSING, PARITY, GUESS = "crossing", "parity", "guess"
KIND_SOURCES = (CROSSING, PARITY, GUESS)

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
    omega_bracket: (Omega at index, at index + 1), rad/s: the located value is inside,
    except for a fold, whose omega is the vertex of the parabola Omega(s) through the three
    points around the turn (an extremum of Omega, beyond both points' Omegas by O(ds^2));
    the interpolation error is a fraction of this bracket (see `locate`).
    multiplier: the crossing multiplier of the minimal period at the point on its unstable
    side (where a period doubling's is real), -.
    direction: +1 when the orbit loses stability going along the branch, -1 when it gains it,
    0 where that is not known (a fold beside a point whose analysis gave no verdict).
    period_ratio: g, the orbit's minimal period is T / g (T of the HBM basis).
    exponent: the crossing Floquet exponent (centred member, see FloquetSpectrum) there, 1/s.
    mode_omega: fundamental of the basis the mode was computed in (that of the minimal
    period at that point), rad/s.
    eigenvector: the crossing Floquet mode exp(exponent t) p(t) at that point: p's
    coefficients (2 N' + 1, n) complex in the minimal period's basis (N' = N_h / g), all
    ROM dof, eq. (5) order; None for folds.
    kind_from: how the kind is known (KIND_SOURCES). "crossing": one multiplier was found on
    both sides of the circle (crossings), so that kind, multiplier and fraction are
    measured; a fold, located by the turn in Omega, is one too. "parity": the signs of
    det(I + M) and det(I - M) (real_parities) tell the kind where no multiplier pairs across
    the circle (it moved too far between the two analyses, or two real multipliers met on
    the real axis and left it as a complex pair, or the reverse; placed half-way), or where
    the paired crossings do not add up to the count change (a Neimark-Sacker turned into
    the real crossing keeps its place; one more crossing is placed half-way); its
    multiplier is the real unstable one of that sign nearest the circle on either side.
    "guess": no multiplier pairs across and the signs do not tell: kind and multiplier are
    those of the unstable multiplier nearest the circle on the side with more of them
    (leaving out those paired with an unstable one of the other side), placed half-way.
    refine_steps: points solved and analysed between the two stored points to locate it
    (hbm.stability.refinement; 0: interpolated between the stored points, the default).
    located_bracket: (Omega, Omega) rad/s of the two nearest points, stored or solved, on
    either side of the crossing: omega_bracket unless refined. refine_note: why the
    refinement stopped before its tolerance with solves left ("" otherwise).
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
    kind_from: str = CROSSING
    refine_steps: int = 0
    located_bracket: tuple[float, float] | None = None
    refine_note: str = ""

    @property
    def bracket(self) -> tuple[float, float]:
        """(Omega, Omega) rad/s of the nearest points on either side (located_bracket, else
        omega_bracket)."""
        return self.omega_bracket if self.located_bracket is None else self.located_bracket

    @property
    def paired(self) -> bool:
        """Whether the crossing multiplier was paired across the circle (kind, multiplier and
        fraction measured)."""
        return self.kind_from == CROSSING


def classify(mu: complex, fold: bool) -> str:
    """Kind of a crossing by its multiplier's argument (and whether the branch turns there)."""
    a = abs(np.angle(mu))
    if a <= REAL_ARG_TOL:
        return FOLD if fold else BRANCH_POINT
    if a >= np.pi - REAL_ARG_TOL:
        return PERIOD_DOUBLING
    return NEIMARK_SACKER


def upper_half(mu: np.ndarray) -> np.ndarray:
    """(m,) bool: one multiplier of each conjugate pair (Im >= 0) and every real one, also a
    near-real one with Im < 0 (within REAL_ARG_TOL of 0 or pi) whose conjugate is not listed
    (round-off at arg = -pi, or the truncation's move off the axis, see lone_real); a pair
    within that band keeps one member, as it crosses the circle as one. For the pairing
    only: the counts of unstable multipliers (FloquetSpectrum.n_unstable, real_parities, the
    monitor's records) take both members of a pair."""
    mu = np.asarray(mu)
    a = np.angle(mu)
    out = a >= 0.0
    band = ~out & ((a >= -REAL_ARG_TOL) | (a <= REAL_ARG_TOL - np.pi))
    if band.any():
        out[band] = lone_real(mu)[band]
    return out


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


def real_parities(mu: np.ndarray, unstable: np.ndarray, log_limit: float):
    """(n, minus, plus) of one spectrum's unstable multipliers with log|mu| < log_limit: n
    their number (with multiplicity), minus and plus the parities (0 or 1) of the real ones
    among them beyond -1 and beyond +1; None where the signs are not clear.

    minus and plus are the signs of det(I + M) and det(I - M) restricted to those
    multipliers: a complex pair contributes |1 +- mu|^2 > 0, a real one beyond -1 a negative
    factor to the first, one beyond +1 to the second. Between two points they change only
    where an odd number of real multipliers went through -1, or through +1, whatever else
    the multipliers did (two real ones meeting on the real axis and leaving it as a complex
    pair, or the reverse, changes neither) as long as none crossed log_limit. A near-real
    multiplier without its conjugate counts as real (DLFT's truncation moves a real
    multiplier's argument off the axis, by up to 0.03 rad on rotor 67's NFRC, past
    REAL_ARG_TOL). mu: (m,) complex, unstable: (m,) bool.
    """
    mu = np.asarray(mu)
    keep = np.asarray(unstable, bool) & (np.log(np.abs(mu)) < log_limit)
    sel = mu[keep]
    signs = []
    for d in (np.prod(1.0 + sel), np.prod(1.0 - sel)):
        # the product's argument is the sum of the lone near-real ones' small offsets:
        # anywhere near +-pi/2 the sign is not known
        if abs(abs(np.angle(d)) - 0.5 * np.pi) < 0.25 * np.pi:
            return None
        signs.append(int(d.real < 0))
    return int(len(sel)), signs[0], signs[1]


def lone_real(mu: np.ndarray) -> np.ndarray:
    """(m,) bool: the multipliers of mu whose conjugate is not listed with them (real ones,
    and near-real ones whose argument the truncation moved off 0 or pi)."""
    mu = np.asarray(mu)
    out = np.ones(len(mu), bool)
    for i, m in enumerate(mu):
        if m.imag != 0.0:
            others = np.delete(mu, i)
            out[i] = not np.any(np.abs(others - np.conj(m)) <= 1e-6 * abs(m))
    return out


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
    multiplier_imag (k,) -; direction (k,) int (+1 loses stability along the branch, -1 gains it, 0 not known);
    period_ratio (k,) int; kind_from (k,) str (crossing, parity or guess: see Bifurcation);
    refine_steps (k,) int, located_low, located_high (k,) rad/s (Bifurcation.bracket),
    refine_note (k,) str.
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
        "kind_from": (np.array([x.kind_from for x in b], dtype=object), "-"),
        "refine_steps": (np.array([x.refine_steps for x in b], dtype=np.int64), "-"),
        "located_low": (np.array([x.bracket[0] for x in b], dtype=float), "rad/s"),
        "located_high": (np.array([x.bracket[1] for x in b], dtype=float), "rad/s"),
        "refine_note": (np.array([x.refine_note for x in b], dtype=object), "-"),
    }


def bifurcations_from_arrays(table: dict) -> tuple:
    """The Bifurcation tuple of a table read back from a file ({name: array} of the columns
    bifurcation_arrays writes): what a resumed branch starts from. The file holds no
    exponent, mode or eigenvector: those stay at their defaults (kind_sources for the kind's
    source)."""
    n = len(np.asarray(table["omega"]))
    col = {k: np.asarray(v) for k, v in table.items()}
    source = kind_sources(table)

    def text(v) -> str:
        return v.decode() if isinstance(v, bytes) else str(v)

    def refined(i) -> dict:  # a table written before refinement has none of its columns
        if "refine_steps" not in col or int(col["refine_steps"][i]) == 0:
            return {}
        return dict(refine_steps=int(col["refine_steps"][i]), refine_note=text(col["refine_note"][i]),
                    located_bracket=(float(col["located_low"][i]), float(col["located_high"][i])))

    return tuple(Bifurcation(
        kind=str(col["kind"][i]), omega=float(col["omega"][i]), le_amplitude=float(col["le_amplitude"][i]),
        index=int(col["index"][i]), fraction=float(col["fraction"][i]),
        omega_bracket=(float(col["omega_low"][i]), float(col["omega_high"][i])),
        multiplier=complex(float(col["multiplier_real"][i]), float(col["multiplier_imag"][i])),
        direction=int(col["direction"][i]), period_ratio=int(col["period_ratio"][i]),
        kind_from=str(source[i]), **refined(i)) for i in range(n))


def kind_sources(table: dict) -> np.ndarray:
    """(k,) str: the kind_from column of a bifurcation table ({column: array}); a table written
    before it has a bool column paired (False: guess), and one written before that counts
    as measured (crossing)."""
    n = len(np.asarray(table["omega"]))
    if "kind_from" in table:
        return np.array([k.decode() if isinstance(k, bytes) else str(k) for k in np.asarray(table["kind_from"])],
                        dtype=object)
    paired = np.asarray(table.get("paired", np.ones(n, bool)), bool)
    return np.where(paired, CROSSING, GUESS).astype(object)
