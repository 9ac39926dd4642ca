"""The reference's small dense solves (kernel/linalg.py) have LAPACK's bits where the scenes need
them: the LU solve on 1 x 1 and 2 x 2 systems (the interface Newton of the two-subsystem scenes) and
the one-channel inverse (the wave adapter); a singular matrix gives None or NaN."""
import numpy as np
import pytest

from wavecosim.kernel import linalg
from wavecosim.kernel.linalg import solve


@pytest.mark.parametrize("n", [1, 2])
def test_solve_has_numpys_bits_on_small_systems(n):
    rng = np.random.default_rng(n)
    for k in range(2000):
        A = rng.normal(size=(n, n)) if k % 2 else np.eye(n) - rng.normal(size=(n, n)) * 10.0 ** rng.integers(-8, 1)
        b = rng.normal(size=n)
        assert solve(A, b).tobytes() == np.linalg.solve(A, b).tobytes()


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
