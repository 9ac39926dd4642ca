"""Our Nelder-Mead (core/simplex.py) against scipy.optimize.minimize(method="Nelder-Mead") with the
gamma search's options: the same point, value and number of evaluations to the last bit, on smooth,
kinked, flat-outside-a-box and budget-limited problems (the gammas of every scene depend on it);
and the gamma search runs without importing scipy.optimize (the reason it exists)."""
import subprocess
import sys

import numpy as np
import pytest
from scipy.optimize import minimize

from wavecosim.core.simplex import nelder_mead


def bowl(x):
    A = np.array([[3.0, 1.0, 0.2], [1.0, 2.0, -0.4], [0.2, -0.4, 1.5]])[:len(x), :len(x)]
    d = x - np.linspace(0.3, -0.7, len(x))
    return float(d @ A @ d) + 0.25


def rosenbrock(x):
    return float(sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1.0 - x[:-1]) ** 2))


def kinks(x):
    """The largest of a few linear forms (a spectral radius where eigenvalues cross looks like this)."""
    forms = np.array([[1.0, 0.5], [-0.8, 1.2], [0.3, -1.5], [-1.1, -0.9]])
    return float(np.max(forms @ x + np.array([0.1, -0.2, 0.05, 0.3])))


def boxed(lo, hi):
    """Rosenbrock flat outside a box, as the gamma search's objective: ties in the simplex's values,
    whose order (np.argsort's, not a stable sort's) decides the path."""
    return lambda x: rosenbrock(np.clip(x, lo, hi))


def one_d(x):
    return float(np.abs(np.sin(3.0 * x[0]) + 0.2 * x[0]))


def search_simplex(x0):
    """The initial simplex of the gamma search: x0 and x0 - 0.5 along each axis."""
    x0 = np.asarray(x0, float)
    return np.vstack([x0] + [x0 - 0.5 * np.eye(len(x0))[i] for i in range(len(x0))])


CASES = {
    "bowl 2-D": (bowl, [1.0, 2.0], None),
    "bowl 3-D": (bowl, [1.0, 2.0, -1.0], None),
    "rosenbrock": (rosenbrock, [-1.2, 1.0], None),
    "rosenbrock 3-D": (rosenbrock, [0.5, -0.3, 1.4], None),
    "kinks": (kinks, [0.7, -0.4], None),
    "boxed": (boxed([-0.5, 0.2], [0.4, 0.9]), [0.7, 1.1], None),
    "boxed 3-D": (boxed([-0.36, 0.07, 0.19], [0.16, 0.86, 1.01]), [0.7, 0.54, 0.57], None),
    "out of evaluations": (rosenbrock, [-1.2, 1.0], 37),
    "1-D": (one_d, [2.0], None),
}


@pytest.mark.parametrize("name", CASES)
def test_the_same_bits_as_scipy(name):
    f, x0, maxfev = CASES[name]
    maxfev = maxfev or 300 * len(x0)
    simplex = search_simplex(x0)
    ref = minimize(f, x0, method="Nelder-Mead",
                   options={"xatol": 1e-4, "fatol": 1e-9, "maxfev": maxfev, "initial_simplex": simplex})
    x, fun, nfev = nelder_mead(f, simplex, xatol=1e-4, fatol=1e-9, maxfev=maxfev)
    assert (x.tobytes(), np.float64(fun).tobytes(), nfev) == (ref.x.tobytes(), np.float64(ref.fun).tobytes(), ref.nfev)
    assert (nfev == maxfev) == (name == "out of evaluations")      # the budget cuts only that one short
    if name != "out of evaluations":
        assert fun < f(np.asarray(x0, float))


def test_the_simplex_is_left_alone():
    """The caller's simplex and the points handed to f are copies: f may scribble on its argument."""
    simplex = search_simplex([1.0, 2.0])
    before = simplex.copy()

    def scribbling(x):
        value = bowl(x)
        x[:] = 99.0
        return value
    x, fun, _ = nelder_mead(scribbling, simplex, xatol=1e-4, fatol=1e-9, maxfev=600)
    assert np.array_equal(simplex, before) and fun == pytest.approx(0.25, abs=1e-8)


def test_the_gamma_search_imports_no_scipy_optimize():
    """In a fresh process (this one has imported scipy.optimize): a whole search, then sys.modules."""
    code = ("import sys; from wavecosim.core import gamma; "
            "g, r = gamma._search(lambda g: (g[0] - 1.0) ** 2 + (g[1] - 2.0) ** 2, [0.1, 0.1], [10.0, 10.0], [[0.5, 0.5]]); "
            "assert abs(g[0] - 1.0) < 1e-3 and abs(g[1] - 2.0) < 1e-3, g; "
            "print('scipy.optimize' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"
