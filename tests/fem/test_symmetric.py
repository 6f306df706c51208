"""fem.symmetric: the upper-triangle matrix against dense numpy, on disk and back."""
import numpy as np
import pytest
import scipy.sparse as sp

from fem.symmetric import SymmetricMatrix


def _random_symmetric(n=300, density=0.03, seed=1):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=density, random_state=rng, format="csr")
    return (A + A.T + sp.diags(rng.uniform(1.0, 2.0, n))).tocsr()


@pytest.mark.parametrize("shape", [(300,), (300, 1), (300, 7), (300, 40)])
def test_product_equals_dense(shape):
    A = _random_symmetric()
    X = np.random.default_rng(2).standard_normal(shape)
    Y = SymmetricMatrix.from_csr(A) @ X
    assert Y.shape == X.shape
    np.testing.assert_allclose(Y, A.toarray() @ X, rtol=0, atol=1e-12 * np.abs(A).max() * np.abs(X).max() * 300)


def test_spill_and_whole_matrix_with_its_pattern(tmp_path):
    A = _random_symmetric()
    A.sort_indices()
    rows = np.repeat(np.arange(300), np.diff(A.indptr))
    A.data[(rows + A.indices) % 5 == 1] = 0.0  # explicit zeros, at symmetric places
    zeros = int((A.data == 0).sum())
    assert zeros > 0
    S = SymmetricMatrix.from_csr(A)
    assert S.nnz_upper == sp.triu(A).nnz
    X = np.random.default_rng(3).standard_normal((300, 5))
    S.spill(tmp_path)
    assert S.spilled and sorted(p.name for p in tmp_path.iterdir()) == ["data.npy", "indices.npy", "indptr.npy"]
    np.testing.assert_allclose(S @ X, A @ X, rtol=1e-13, atol=1e-12)  # read through the memory map
    whole = S.to_csr()  # the same pattern, explicit zeros included, and the same values
    np.testing.assert_array_equal(whole.indptr, A.indptr)
    np.testing.assert_array_equal(whole.indices, A.indices)
    np.testing.assert_array_equal(whole.data, A.data)
    lean = S.without_zeros()
    assert lean.nnz_upper == S.nnz_upper - int((sp.triu(A).data == 0).sum())
    np.testing.assert_allclose(lean @ X, A @ X, rtol=1e-13, atol=1e-12)


def test_refuses_lower_entries_and_wrong_shapes():
    A = _random_symmetric(50)
    with pytest.raises(ValueError, match="upper triangle only"):
        SymmetricMatrix(A)
    with pytest.raises(ValueError, match="square"):
        SymmetricMatrix(sp.csr_matrix((3, 4)))
    with pytest.raises(ValueError, match="cannot multiply"):
        SymmetricMatrix.from_csr(A) @ np.ones(49)


def test_cholesky_factor_of_the_triangle_solves():
    from fem.cholesky import CholeskyFactor

    A = _random_symmetric() + 20 * sp.identity(300, format="csr")  # diagonally dominant: SPD
    b = np.random.default_rng(4).standard_normal((300, 3))
    f = CholeskyFactor(SymmetricMatrix.from_csr(A))
    try:
        x = f.solve(b)
    finally:
        f.destroy()
    np.testing.assert_allclose(A @ x, b, rtol=0, atol=1e-12)
