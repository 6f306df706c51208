"""Is numba's code for the step loop far from what a C compiler makes of the same work?

    taskset -c 1 .venv/bin/python benchmarks/bench_ti_codegen.py [--steps 5000000] [--repeat 5] \\
        [--cflags "-O3 -march=native -mprefer-vector-width=256 -ffp-contract=fast"]

A step out of contact, on rotor 67's sizes (39 modes padded to 48, 9 tip nodes padded to
12): the prediction (hbm.ti.kernel._predict_fast, the kernel's own, two accumulator sets),
the casing's cheap free test of every node (the lobe coordinate and the bound of
hbm.ti.kernel._find_penetrations) and the radial extremes, on synthetic data with the casing
1 m away (no node ever near it, as in a free step). The same loop in C, written the way C
is usually written (the node accumulators as two arrays of 12, which gcc vectorises), and
again with the kernel's 24 scalar accumulators, is compiled with gcc into a temporary
folder and called through ctypes. Prints ns a step, median of the alternated repeats, for
each, and its ratio to numba's. Needs gcc.
"""
from __future__ import annotations

import argparse
import ctypes
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import hbm  # noqa: E402,F401 - numba's CPU tuning (hbm.jit), as in a run
from numba import njit  # noqa: E402

from hbm.ti.kernel import _FAST, _predict_fast  # noqa: E402

C_SOURCE = r"""
#include <math.h>
#include <string.h>
long run_free(int npad, const double *c1, const double *c2, double *q, double *qm, double *qn,
              const double *prT, int nb, const double *theta, double om, double dt, double clearance,
              double penetration, double n_lobes, double width, double *emax, double *emin, long nsteps) {
    const double period = 2.0 * M_PI / n_lobes, inv_p = n_lobes / (2.0 * M_PI), half = M_PI / n_lobes;
    const double iw = 1.0 / width, cpp = clearance + penetration;
    const double margin = 1e-12 * (fabs(clearance) + fabs(penetration));
    long near_count = 0;
    double *a = q, *b = qm, *c = qn;
    for (long it = 0; it < nsteps; it++) {
        double tau = om * ((it + 1) * dt);
        double r[12] = {0}, u[12] = {0};
        for (int k = 0; k < npad; k += 2) {
            double v = c1[k] * a[k] - c2[k] * b[k];
            double w = c1[k + 1] * a[k + 1] - c2[k + 1] * b[k + 1];
            c[k] = v;
            c[k + 1] = w;
            for (int j = 0; j < 12; j++) {
                r[j] += prT[k * 12 + j] * v;
                u[j] += prT[(k + 1) * 12 + j] * w;
            }
        }
        int near = 0;
        for (int j = 0; j < nb; j++) {
            double rh = r[j] + u[j], x = tau + theta[j];
            double z = (x - period * floor(x * inv_p) - half) * iw, z2 = z * z;
            double f = 1.0 + z2 * (1.0 + 0.5 * z2);
            near |= !((clearance - rh) * f > cpp + margin && cpp >= 0.0);
            emax[j] = fmax(emax[j], rh);
            emin[j] = fmin(emin[j], rh);
        }
        near_count += near;
        double *t = b;
        b = a;
        a = c;
        c = t;
    }
    memcpy(q, a, npad * sizeof(double));
    memcpy(qm, b, npad * sizeof(double));
    return near_count;
}
"""


def _scalar_accumulators(source: str) -> str:
    """The C loop with the node sums in 24 scalar accumulators, as the kernel writes them
    (hbm.ti.kernel._predict_fast), as function run_free_acc."""
    decl = "double " + ", ".join(f"r{j} = 0, u{j} = 0" for j in range(12)) + ";"
    sums = "".join(f"r{j} += P[{j}] * v; u{j} += Q[{j}] * w; " for j in range(12))
    body = (f"        {decl}\n        for (int k = 0; k < npad; k += 2) {{\n"
            "            double v = c1[k] * a[k] - c2[k] * b[k];\n"
            "            double w = c1[k + 1] * a[k + 1] - c2[k + 1] * b[k + 1];\n"
            "            c[k] = v;\n            c[k + 1] = w;\n"
            "            const double *P = prT + k * 12, *Q = prT + (k + 1) * 12;\n"
            f"            {sums}\n        }}\n"
            f"        double r[12] = {{{', '.join(f'r{j}' for j in range(12))}}};\n"
            f"        double u[12] = {{{', '.join(f'u{j}' for j in range(12))}}};\n")
    start = source.index("        double r[12] = {0}, u[12] = {0};")
    end = source.index("        int near = 0;")
    return (source[:start] + body + source[end:]).replace("long run_free(", "long run_free_acc(")


@njit(fastmath=_FAST)
def _run_free(c1, c2, q, qm, qn, prT, theta, om, dt, clearance, penetration, n_lobes, width, emax, emin, nsteps):
    """The C loop's work in numba, with the kernel's own prediction."""
    period = 2.0 * math.pi / n_lobes
    inv_p = n_lobes / (2.0 * math.pi)
    half = math.pi / n_lobes
    iw = 1.0 / width
    cpp = clearance + penetration
    margin = 1e-12 * (abs(clearance) + abs(penetration))
    rh = np.zeros(12)
    near_count = 0
    a, b, c = q, qm, qn
    for it in range(nsteps):
        tau = om * ((it + 1) * dt)
        _predict_fast(c1, c2, a, b, c, prT, rh)
        near = False
        for j in range(theta.shape[0]):
            x = tau + theta[j]
            z = (x - period * np.floor(x * inv_p) - half) * iw
            z2 = z * z
            f = 1.0 + z2 * (1.0 + 0.5 * z2)
            near = near or not ((clearance - rh[j]) * f > cpp + margin and cpp >= 0.0)
            emax[j] = max(emax[j], rh[j])
            emin[j] = min(emin[j], rh[j])
        near_count += near
        t = b
        b = a
        a = c
        c = t
    return near_count


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cflags", default="-O3 -march=native -mprefer-vector-width=256 -ffp-contract=fast")
    a = ap.parse_args()

    rng = np.random.default_rng(0)
    n, npad, nb, dt = 39, 48, 9, 1e-7
    omega_j = np.sort(rng.uniform(300.0, 2.6e6, n))  # rad/s, below the step's limit 2 / dt
    c1, c2 = np.zeros(npad), np.zeros(npad)
    c1[:n], c2[:n] = 2.0 - (omega_j * dt) ** 2, 1.0
    prT = np.zeros((npad, 12))
    prT[:n, :nb] = 1e-2 * rng.standard_normal((n, nb))
    q = np.zeros(npad)
    q[:n] = 1e-6 * rng.standard_normal(n)
    qm = 0.999 * q
    theta = np.linspace(-0.05, 0.05, nb)
    casing = (650.0, dt, 1.0, 0.0, 2.0, 0.25)  # Omega, dt, clearance 1 m (never near), p, lobes, width

    with tempfile.TemporaryDirectory() as tmp:
        src, lib_path = Path(tmp) / "free.c", Path(tmp) / "libfree.so"
        src.write_text(C_SOURCE + _scalar_accumulators(C_SOURCE))
        subprocess.run(["gcc", *a.cflags.split(), "-shared", "-fPIC", "-o", str(lib_path), str(src), "-lm"],
                       check=True)
        lib = ctypes.CDLL(str(lib_path))
    lib.run_free.restype = lib.run_free_acc.restype = ctypes.c_long
    dbl = ctypes.POINTER(ctypes.c_double)

    def ptr(x):
        return x.ctypes.data_as(dbl)

    def run_c(steps, fn=lib.run_free):
        qq, qqm, qqn = q.copy(), qm.copy(), np.zeros(npad)
        ext = (np.full(nb, -np.inf), np.full(nb, np.inf))
        return fn(npad, ptr(c1), ptr(c2), ptr(qq), ptr(qqm), ptr(qqn), ptr(prT), nb, ptr(theta),
                            *(ctypes.c_double(v) for v in casing), ptr(ext[0]), ptr(ext[1]), ctypes.c_long(steps))

    def run_numba(steps):
        return _run_free(c1, c2, q.copy(), qm.copy(), np.zeros(npad), prT, theta, *casing,
                         np.full(nb, -np.inf), np.full(nb, np.inf), steps)

    def run_c_acc(steps):
        return run_c(steps, lib.run_free_acc)

    loops = {"numba": run_numba, "gcc": run_c, "gcc, scalar accumulators": run_c_acc}
    if len({f(1000) for f in loops.values()}) != 1:
        raise SystemExit("the loops disagree on the near-casing count")
    times = {k: [] for k in loops}
    for _ in range(a.repeat):
        for name, f in loops.items():
            t0 = time.process_time()
            f(a.steps)
            times[name].append((time.process_time() - t0) / a.steps * 1e9)
    med = {k: float(np.median(v)) for k, v in times.items()}
    print(f"free step, {a.steps} steps, median of {a.repeat} alternated; gcc flags: {a.cflags}")
    for name, t in med.items():
        print(f"  {name}: {t:.1f} ns a step, {t / med['numba']:.2f} of numba's time")


if __name__ == "__main__":
    main()
