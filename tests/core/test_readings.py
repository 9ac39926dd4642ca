"""wavecosim/core/readings.py: sums and dot products of many rows at once equal, to the last bit, the
reference's sum (linalg.total: left to right, whatever the Python) and numpy's a @ b of each row
(the figures written step by step)."""
import numpy as np
import pytest

from wavecosim.core.readings import row_dots, row_sums
from wavecosim.kernel.linalg import dot, total


@pytest.mark.parametrize("m", [1, 2, 3, 8, 13])
def test_row_dots_are_each_rows_fixed_order_dot(m):
    """Each row's products summed left to right from 0 (linalg.dot), the bits kernel/c/certs.c makes;
    numpy's a @ b agrees only to rounding, since its BLAS kernel and its order of sums depend on the CPU."""
    rng = np.random.default_rng(m)
    A = rng.standard_normal((5000, m)) * 10.0 ** rng.integers(-12, 12, (5000, m))
    B = rng.standard_normal((5000, m)) * 10.0 ** rng.integers(-12, 12, (5000, m))
    A[::7] = 0.0
    B[::11] = -B[::11]
    got = row_dots(A, B)
    assert got.tobytes() == np.array([dot(a, b) for a, b in zip(A.tolist(), B.tolist())]).tobytes()
    scale = np.abs(A * B).sum(axis=1)
    assert np.all(np.abs(got - np.einsum("ij,ij->i", A, B)) <= 1e-14 * scale)


def test_row_sums_are_the_references_sums():
    X = np.random.default_rng(2).standard_normal((2000, 6)) * 1e8
    assert row_sums(X).tolist() == [total(r) for r in X.tolist()]
