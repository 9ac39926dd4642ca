"""The reference's small dense solves (kernel/linalg.py) in this project's own order of operations, so
their bits are the same on every CPU: the LU solve (the interface Newton, the compiled coupling), the
least squares of IQN-ILS and the one-channel inverse (the wave adapter); a singular matrix gives None
or NaN."""
import numpy as np
import pytest

from wavecosim.kernel import linalg
from wavecosim.kernel.linalg import solve


def lu_by_hand(A, b):
    """The LU of linalg.solve's docstring in scalar Python: the first row of largest |pivot|, the
    multiplier as A[r][c] times the pivot's reciprocal, back substitution dividing by the pivots."""
    A, x, n = [list(map(float, row)) for row in A], list(map(float, b)), len(b)
    for c in range(n):
        p = max(range(c, n), key=lambda r: (abs(A[r][c]), -r))
        A[c], A[p], x[c], x[p] = A[p], A[c], x[p], x[c]
        inv = 1.0 / A[c][c]
        for r in range(c + 1, n):
            ell = A[r][c] * inv
            if ell != 0.0:
                A[r] = A[r][:c + 1] + [a - ell * v for a, v in zip(A[r][c + 1:], A[c][c + 1:])]
                x[r] -= ell * x[c]
    for c in range(n - 1, -1, -1):
        x[c] /= A[c][c]
        for r in range(c):
            x[r] -= A[r][c] * x[c]
    return x


@pytest.mark.parametrize("n", [1, 2, 3, 6])
def test_solve_has_the_same_bits_on_every_cpu(n):
    """solve() makes the LU's operations one by one (no BLAS, whose kernel depends on the CPU): the
    scalar transcription's bits, and numpy's LAPACK answer to rounding."""
    rng = np.random.default_rng(n)
    for k in range(2000):
        A = rng.normal(size=(n, n)) if k % 2 else np.eye(n) - rng.normal(size=(n, n)) * 10.0 ** rng.integers(-8, 1)
        b = rng.normal(size=n)
        x = solve(A, b)
        assert x.tolist() == lu_by_hand(A, b)
        np.testing.assert_allclose(A @ x, b, rtol=0, atol=1e-9 * np.linalg.cond(A) * (1 + np.abs(b).max()))


def test_solve_columns_solves_each_column():
    rng = np.random.default_rng(3)
    A, B = rng.normal(size=(4, 4)), rng.normal(size=(4, 3))
    X = linalg.solve_columns(A, B)
    assert all(X[:, j].tolist() == solve(A, B[:, j]).tolist() for j in range(3))
    assert linalg.solve_columns([[1.0, 2.0], [2.0, 4.0]], np.eye(2)) is None


def test_least_squares_is_the_minimum_and_drops_dependent_columns():
    rng = np.random.default_rng(4)
    V, b = rng.normal(size=(9, 4)), rng.normal(size=9)
    np.testing.assert_allclose(linalg.least_squares(V, b), np.linalg.lstsq(V, b, rcond=None)[0], rtol=1e-10)
    W = np.column_stack([V[:, 0], 2.0 * V[:, 0], V[:, 1]])           # the second column adds nothing
    x = linalg.least_squares(W, b)
    assert x[1] == 0.0
    np.testing.assert_allclose(W @ x, W @ np.linalg.lstsq(W, b, rcond=None)[0], rtol=1e-10)


def test_solve_of_a_singular_matrix_is_none():
    assert solve([[1.0, 2.0], [2.0, 4.0]], [1.0, 1.0]) is None
    x = solve([[0.0, 2.0], [3.0, 1.0]], [4.0, 5.0])                  # needs the row swap
    assert x.tolist() == [1.0, 2.0]


def test_the_inverse_is_lapacks_for_one_channel_and_pivots():
    for x in (3.0, -0.1, 7e-300, 1.0 / 3.0):
        assert linalg.inverse([[x]])[0][0] == np.linalg.inv([[x]])[0][0]
    M = [[0.0, 2.0, 1.0], [1.0, 1e-3, 0.0], [4.0, 1.0, 3.0]]           # a zero leading pivot
    np.testing.assert_allclose(linalg.inverse(M), np.linalg.inv(M), rtol=1e-12, atol=1e-14)
    assert all(np.isnan(x) for row in linalg.inverse([[1.0, 2.0], [2.0, 4.0]]) for x in row)


def test_the_sparse_lu_gives_the_dense_solve_numbers():
    """linalg.solve_sparse (the interface Newton's solve, kernel/c/newton.c's lu_sparse) gives solve()'s
    numbers on random sparse systems, row swaps, zero right-hand sides and singular ones included."""
    rng = np.random.default_rng(7)
    for _ in range(500):
        n = int(rng.integers(1, 12))
        mask = rng.random((n, n)) < rng.uniform(0.1, 0.6)
        A = np.where(mask, rng.standard_normal((n, n)) * 10.0 ** rng.integers(-3, 4, (n, n)), 0.0)
        if rng.random() < 0.5:
            A += np.diag(rng.standard_normal(n))
        b = np.where(rng.random(n) < 0.2, 0.0, rng.standard_normal(n))
        dense = solve(A, b)
        sparse = linalg.solve_sparse([{j: v for j, v in enumerate(row) if v != 0.0} for row in A], b)
        assert (dense is None) == (sparse is None)
        if dense is not None:
            assert np.array_equal(dense, sparse)
