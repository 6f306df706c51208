"""The RomModel contract (rom.model): inconsistent, non-finite or non-symmetric data and a
mass matrix that is not positive definite are refused with a message naming the field and
the expected shape; a negative eigenvalue of (K, M) beyond round-off is an error, checked on
2 x 2 pencils whose eigenvalues are known by hand."""
import dataclasses
import re

import h5py
import numpy as np
import pytest

from rom.model import eigenfrequencies, load_rom, modal_damping
from support import COARSE_ROM, coarse_rom

ROM = coarse_rom()  # read only: each case builds a new model with dataclasses.replace
N, NB = 39, 9  # the coarse ROM: 3 x 9 boundary dof + 12 fixed-interface modes


def _with(field, index, value):
    a = np.array(getattr(ROM, field), dtype=float)
    a[index] = value
    return a


def _asymmetric(field, relative):
    a = np.array(getattr(ROM, field))
    a[0, 1] += relative * np.abs(a).max()
    return a


def _flipped_e_theta(nodes):
    f = np.array(ROM.frames)
    f[nodes, 1] *= -1.0
    return f


def _lock(**changes):
    return dataclasses.replace(ROM.friction_lock, **changes)


BAD = {
    "nan in K": (dict(K=_with("K", (5, 5), np.nan)), r"K has 1 NaN or inf entries, the first at index \(5, 5\)"),
    "inf in M": (dict(M=_with("M", (0, 3), np.inf)), r"M has 1 NaN or inf entries, the first at index \(0, 3\)"),
    "nan in C": (dict(C=_with("C", (2, 1), np.nan)), r"C has 1 NaN or inf entries"),
    "K not square": (dict(K=ROM.K[:, :38]), r"K must be a square \(n, n\) matrix.*got shape \(39, 38\)"),
    "M of another size": (dict(M=ROM.M[:38, :38]), r"M must have shape \(39, 39\).*got \(38, 38\)"),
    "C of another size": (dict(C=ROM.C[:38, :38]), r"C must have shape \(39, 39\).*got \(38, 38\)"),
    "K not symmetric": (dict(K=_asymmetric("K", 1e-6)), r"K is not symmetric: max \|K - K\^T\| = "),
    "C not symmetric": (dict(C=_asymmetric("C", 1e-6)), r"C is not symmetric"),
    # e_0^T M e_0 = M_00 < 0: not a mass matrix
    "M indefinite": (dict(M=_with("M", (0, 0), -ROM.M[0, 0])), r"M is not positive definite"),
    "theta short": (dict(theta=ROM.theta[:8]),
                    r"theta must have shape \(9,\) \(n_b = 9 boundary nodes, from rho\), got \(8,\)"),
    "rho short": (dict(rho=ROM.rho[:8]), r"theta must have shape \(8,\) \(n_b = 8 .*got \(9,\)"),
    "rho too long for K": (dict(rho=np.full(14, 0.24)),
                           r"n_b = 14 boundary nodes, 3 n_b = 42 dof, but K has only n = 39"),
    "rho zero": (dict(rho=_with("rho", 3, 0.0)), r"rho must hold n_b >= 1 radii > 0 m"),
    "rho nan": (dict(rho=_with("rho", 3, np.nan)), r"rho has 1 NaN or inf entries, the first at index \(3,\)"),
    "xyz 2-d points": (dict(xyz=ROM.xyz[:, :2]), r"xyz must have shape \(9, 3\).*got \(9, 2\)"),
    "frames scaled": (dict(frames=2.0 * ROM.frames), r"frames must be orthonormal"),
    "frames short": (dict(frames=ROM.frames[:8]), r"frames must have shape \(9, 3, 3\)"),
    # orthonormal, but e_theta flipped at nodes 2 and 6 (det -1): friction would act backwards there
    "frames left-handed": (dict(frames=_flipped_e_theta([2, 6])),
                           r"frames must be right-handed .* boundary nodes \[2, 6\] are left-handed"),
    "node_index float": (dict(node_index=ROM.node_index.astype(float)), r"node_index must hold integer"),
    "node_index negative": (dict(node_index=np.arange(-1, NB)[:NB]),
                            r"node_index must be >= 0, got -1 at index \(0,\)"),
    "fixed-interface count": (dict(fixed_interface_frequencies=ROM.fixed_interface_frequencies[:11]),
                              r"fixed_interface_frequencies must have shape \(12,\) \(eta = n - 3 n_b = 39 - 3 x 9\)"),
    "frequencies count": (dict(frequencies=ROM.frequencies[:38]), r"frequencies must have shape \(39,\)"),
    "frequencies nan": (dict(frequencies=_with("frequencies", 4, np.nan)), r"frequencies has 1 NaN"),
    "damping negative": (dict(damping_ratios=_with("damping_ratios", 7, -1e-3)),
                         r"damping_ratios must be >= 0.0, got -0.001 at index \(7,\)"),
    "full frequencies 2-d": (dict(full_frequencies=ROM.full_frequencies.reshape(3, 4)),
                             r"full_frequencies must have shape \(12,\)"),
    "recovery columns": (dict(recovery=np.zeros((30, 38))),
                         r"recovery must have shape \(3 n_nodes, n = 39\), got \(30, 38\)"),
    "lock of other nodes": (dict(friction_lock=_lock(compliance_rr=ROM.friction_lock.compliance_rr[:8, :8])),
                            r"friction_lock.compliance_rr must have shape \(9, 9\)"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_rom_with_bad_data_is_refused_naming_the_field(case):
    changes, message = BAD[case]
    with pytest.raises(ValueError, match=message):
        dataclasses.replace(ROM, **changes)


def test_round_off_asymmetry_is_accepted():
    # 1e-14 of max |K| is below the condensation's symmetry tolerance (1e-12 of max |K|)
    rom = dataclasses.replace(ROM, K=_asymmetric("K", 1e-14), M=_asymmetric("M", 1e-14))
    assert rom.n_dof == N and rom.n_boundary == NB


def _write(path, rom):
    from pipelines.artifacts import write_artifact

    return write_artifact(path, rom, stage="rom")


def test_a_good_rom_round_trips_through_its_file(tmp_path):
    back = load_rom(_write(tmp_path / "rom.h5", ROM))
    for f in dataclasses.fields(ROM):
        a, b = getattr(ROM, f.name), getattr(back, f.name)
        if f.name == "friction_lock":
            assert np.array_equal(a.compliance_rr, b.compliance_rr) and a.mu_set == b.mu_set
        elif isinstance(a, np.ndarray):
            assert a.dtype == b.dtype and np.array_equal(a, b), f.name
        else:
            assert a == b, f.name


@pytest.mark.parametrize("dataset, value, message", [
    ("K", lambda K: np.where(np.eye(N, dtype=bool), np.nan, K), "K has 39 NaN or inf entries"),
    ("rho", lambda rho: rho[:8], r"theta must have shape \(8,\)"),
], ids=["nan-diagonal-K", "short-rho"])
def test_a_corrupt_rom_file_names_itself_and_the_field(tmp_path, dataset, value, message):
    path = _write(tmp_path / "rom.h5", ROM)
    with h5py.File(path, "a") as h5:
        data = value(h5[dataset][()])
        del h5[dataset]
        h5[dataset] = data
    with pytest.raises(ValueError, match=re.escape(str(path)) + ": " + message):
        load_rom(path)
    assert COARSE_ROM.is_file()  # the shared file is untouched: it was copied


# Negative eigenvalues: K = diag(-d, k2), M = diag(1, m2) has the eigenvalues -d and k2 / m2,
# and the round-off bound n eps cond(M) max|w^2| = 2 eps max(1, m2)/min(1, m2) (k2 / m2) by hand.
EPS = np.finfo(float).eps


@pytest.mark.parametrize("frequencies", [lambda K, M: modal_damping(K, M, 0.01)[1], eigenfrequencies],
                         ids=["modal_damping", "eigenfrequencies"])
@pytest.mark.parametrize("m2, bound", [(1.0, 2 * EPS), (1e-6, 2 * EPS * 1e6)])
def test_a_negative_eigenvalue_is_round_off_below_the_bound_and_an_error_above(frequencies, m2, bound):
    k2 = m2  # second eigenvalue 1 rad^2/s^2: max|w^2| = 1
    M = np.diag([1.0, m2])
    w = frequencies(np.diag([-0.5 * bound, k2]), M)
    np.testing.assert_allclose(w, [0.0, 1.0], rtol=1e-12)
    d = 2.0 * bound
    with pytest.raises(ValueError, match=re.escape(f"eigenvalue w^2 = {-d:.6g} rad^2/s^2, below the round-off "
                                                   f"bound -{bound:.3g}") + ".*not a clamped, stable structure"):
        frequencies(np.diag([-d, k2]), M)


@pytest.mark.parametrize("frequencies", [lambda K, M: modal_damping(K, M, 0.01)[1], eigenfrequencies],
                         ids=["modal_damping", "eigenfrequencies"])
def test_an_indefinite_stiffness_is_refused(frequencies):
    # [[1, 2], [2, 1]] has the eigenvalues 1 - 2 = -1 and 1 + 2 = 3; the clip gave w = (0, sqrt 3)
    with pytest.raises(ValueError, match=r"not positive semi-definite: .*w\^2 = -1 rad\^2/s\^2"):
        frequencies(np.array([[1.0, 2.0], [2.0, 1.0]]), np.eye(2))
    # [[1, 1], [1, 1]] is singular (eigenvalues 0 and 2): its zero is round-off, kept
    np.testing.assert_allclose(frequencies(np.ones((2, 2)), np.eye(2)), [0.0, np.sqrt(2.0)], atol=1e-7)
