"""The monolithic macro-step: solve the interface condition b = S^n(P b) (eqs. 14-15) by Newton.

This is the monolithic reference of the DR master (the true monolithic discrete-time step, not a
long DR run), the Newton master's step and the energy guard's redo. The Jacobian of the
block-diagonal S^n is taken by forward differences through rollback, perturbing channel j of
every subsystem at once.
"""
import numpy as np

from .errors import NumericalError

TOL = 1e-14
ACCEPT = 1e-9
MAX_ITER = 30


def _jacobian(scene, a, s, h):
    """dS/da of the block-diagonal frozen map by forward differences, one query per channel index."""
    n, J_S = len(a), np.zeros((len(a), len(a)))
    for j in range(max(scene.sizes)):
        da = np.zeros(n)
        da[[off + j for off, m in zip(scene.offsets, scene.sizes) if j < m]] = h
        ds = (np.array(scene.S(list(a + da))) - s) / h
        for off, m in zip(scene.offsets, scene.sizes):
            if j < m:
                J_S[off:off + m, off + j] = ds[off:off + m]
    return J_S


def solve_interface(scene, P, b0, tol=TOL, max_iter=MAX_ITER, where=""):
    """Newton on F(b) = b - S^n(P b) at the frozen x^n; returns (b*, iterations, |F(b*)|, S-evaluations)."""
    P = np.asarray(P)
    b = np.array(b0, float)
    evals, best = 0, None
    for it in range(max_iter + 1):
        a = P @ b
        s = np.array(scene.S(list(a)))
        evals += 1
        F = b - s
        res = float(np.linalg.norm(F))
        if not np.isfinite(res):
            raise NumericalError(f"interface Newton{where}: non-finite residual")
        if best is None or res < best[1]:
            best = (b.copy(), res)
        if res <= tol * (1.0 + float(np.linalg.norm(b))) or it == max_iter:
            break
        J_S = _jacobian(scene, a, s, 1e-7 * (1.0 + float(np.abs(a).max())))
        evals += max(scene.sizes)
        b = b + np.linalg.solve(np.eye(len(b)) - J_S @ P, -F)
    b, res = best
    if res > ACCEPT * (1.0 + float(np.linalg.norm(b))):
        raise NumericalError(f"interface Newton{where} did not converge: |b - S(Pb)| = {res:.3g}")
    return b, it, res, evals
