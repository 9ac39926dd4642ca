"""wavecosim/core/readings.py: sums and dot products of many rows at once equal, to the last bit, the
reference's sum (linalg.total: left to right, whatever the Python) and numpy's a @ b of each row
(the figures written step by step)."""
import numpy as np
import pytest

from wavecosim.core.readings import DOT_EXACT, row_dots, row_sums
from wavecosim.kernel.linalg import total


@pytest.mark.parametrize("m", [1, 2, 3, DOT_EXACT, DOT_EXACT + 5])
def test_row_dots_are_each_rows_dot_product(m):
    rng = np.random.default_rng(m)
    A = rng.standard_normal((5000, m)) * 10.0 ** rng.integers(-12, 12, (5000, m))
    B = rng.standard_normal((5000, m)) * 10.0 ** rng.integers(-12, 12, (5000, m))
    A[::7] = 0.0
    B[::11] = -B[::11]
    expected = np.array([float(a @ b) for a, b in zip(A, B)])
    assert row_dots(A, B).tobytes() == expected.tobytes()


def test_row_sums_are_the_references_sums():
    X = np.random.default_rng(2).standard_normal((2000, 6)) * 1e8
    assert row_sums(X).tolist() == [total(r) for r in X.tolist()]
