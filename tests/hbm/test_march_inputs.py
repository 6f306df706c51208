"""hbm.ti.march refuses a model or a request it cannot march, by name: a 2-node, 6-dof chain
whose modes are known in closed form (K = k tridiag(-1, 2, -1) per direction, unit masses)."""
import numpy as np
import pytest

from hbm.ti.march import Recording, massless_system, modal_system, scheme_system, step_compliance

K1 = 1e4 * np.array([[2.0, -1.0], [-1.0, 2.0]])  # one direction of the chain: w^2 = 1e4 and 3e4
K = np.kron(K1, np.eye(3))  # dof 3 j + d: node j's r, theta, z
M, C = np.eye(6), np.zeros((6, 6))
RHO, THETA = [0.25, 0.26], [0.0, 0.1]


def test_the_chains_modes_are_the_closed_form_ones():
    s = modal_system(K, M, C, RHO, THETA)
    np.testing.assert_allclose(np.sort(s.omega), np.repeat([100.0, np.sqrt(3e4)], 3), rtol=1e-12)


@pytest.mark.parametrize("K_, rho, theta, message", [
    (K, [0.25, 0.26, 0.27], [0.0, 0.1, 0.2], r"^3 contact nodes need 3 dof each, model has 6 dof$"),
    (K, RHO, [0.0], r"^2 contact nodes need 3 dof each, model has 6 dof$"),
    (K - 1e4 * np.eye(6), RHO, THETA, r"^model must be positive definite \(clamped\); smallest w\^2 = "),
])
def test_a_model_that_cannot_be_marched_is_named(K_, rho, theta, message):
    with pytest.raises(ValueError, match=message):
        modal_system(K_, M, C, rho, theta)


def test_the_massless_model_is_refused_where_it_would_not_be_one():
    full = modal_system(K, M, C, RHO, THETA)
    with pytest.raises(ValueError, match=r"^no mode below the cut-off 50 rad/s \(lowest: 100 rad/s\)$"):
        massless_system(full, 50.0)
    with pytest.raises(ValueError, match=r"^every mode is below the cut-off 200 rad/s \(highest 173.2 rad/s\): "
                                         r"nothing would be massless$"):
        massless_system(full, 200.0)
    # a damper on node 0's r only couples the in-phase (kept) and out-of-phase (dropped) r modes
    coupled = modal_system(K, M, np.diag([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]), RHO, THETA)
    with pytest.raises(ValueError, match=r"^non-modal damping couples the kept and the dropped modes"):
        massless_system(coupled, 150.0)
    cut = massless_system(full, 150.0)
    assert len(cut.omega) == 3
    with pytest.raises(ValueError, match=r"^the system is already massless$"):
        massless_system(cut, 150.0)
    with pytest.raises(ValueError, match=r"^the exponential scheme needs the full modal system, got a massless one$"):
        scheme_system(cut, "exponential", 150.0)
    with pytest.raises(ValueError, match=r"^unknown time-integration scheme 'rk4'; known: "):
        scheme_system(full, "rk4", 150.0)
    with pytest.raises(ValueError, match=r"^step_compliance is the Carpenter scheme's"):
        step_compliance(cut, 1e-6)
    assert scheme_system(cut, "massless", 150.0) is cut and scheme_system(full, "carpenter", 150.0) is full


@pytest.mark.parametrize("kw", [dict(start=0), dict(stride=0), dict(n_samples=-1), dict(section_stride=-1),
                                dict(extreme_stride=-1)])
def test_a_recording_out_of_range_is_refused(kw):
    args = dict(start=1, stride=1, n_samples=10, dofs=np.arange(2), force_nodes=np.arange(2)) | kw
    with pytest.raises(ValueError, match=r"^invalid recording: start "):
        Recording(**args)
