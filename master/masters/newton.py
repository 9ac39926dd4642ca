"""Interface Newton with rollback: solves the monolithic interface condition b = S^n(P b) (eqs. 14-15).

This is the monolithic reference of the DR master (the true monolithic discrete-time step, not a
long DR run) and a master in its own right. The Jacobian of the block-diagonal S^n is taken by
forward differences through rollback, perturbing channel j of every subsystem at once.
"""
import numpy as np

from ..errors import NumericalError
from .base import Master, StepLog

TOL = 1e-14
ACCEPT = 1e-9
MAX_ITER = 30


def solve_interface(S, P, b0, max_channels, offsets, sizes, tol=TOL, max_iter=MAX_ITER, where=""):
    """Newton on F(b) = b - S(P b); returns (b*, iterations, |F(b*)|, S-evaluations)."""
    P = np.asarray(P)
    n = P.shape[0]
    b = np.array(b0, float)
    evals = 0
    best = None
    for it in range(max_iter + 1):
        a = P @ b
        s = np.array(S(list(a)))
        evals += 1
        F = b - s
        res = float(np.linalg.norm(F))
        if not np.isfinite(res):
            raise NumericalError(f"interface Newton{where}: non-finite residual")
        if best is None or res < best[1]:
            best = (b.copy(), res)
        if res <= tol * (1.0 + float(np.linalg.norm(b))) or it == max_iter:
            break
        J_S = np.zeros((n, n))
        h = 1e-7 * (1.0 + float(np.abs(a).max()))
        for j in range(max_channels):
            da = np.zeros(n)
            cols = [off + j for off, m in zip(offsets, sizes) if j < m]
            da[cols] = h
            ds = (np.array(S(list(a + da))) - s) / h
            evals += 1
            for off, m in zip(offsets, sizes):
                if j < m:
                    J_S[off:off + m, off + j] = ds[off:off + m]
        step = np.linalg.solve(np.eye(n) - J_S @ P, -F)
        b = b + step
    b, res = best
    if res > ACCEPT * (1.0 + float(np.linalg.norm(b))):
        raise NumericalError(f"interface Newton{where} did not converge: |b - S(Pb)| = {res:.3g}")
    return b, it, res, evals


class NewtonMaster(Master):
    """Monolithic macro-step: solve b* = S^n(P b*) to roundoff, then advance with a = P b*."""
    name = "newton"

    def __init__(self, scene, settings, gamma=None):
        super().__init__(scene, settings)
        coupling = scene.wave_map(gamma)
        self.P = coupling.P
        self.b = [0.0] * scene.n_channels
        self.sizes = [s.m for s in self.subsystems]
        self.calls = 0

    def set_gamma(self, gamma, b):
        """Between macro-steps only: recompile P for a new gamma and take b^n re-scattered to it."""
        self.P = self.scene.wave_map(gamma).P
        self.b = list(b)

    def S(self, u):
        b = []
        for sub, a_i in zip(self.subsystems, self.scene.split(u)):
            b.extend(sub.query(a_i))
        return b

    def solve(self, n, t):
        """b* at the frozen state x^n (the subsystems must be frozen)."""
        return solve_interface(self.S, self.P, self.b, max(self.sizes), self.scene.offsets, self.sizes,
                               where=f" at step {n} (t = {t:.6g})")

    def step(self, n, t) -> StepLog:
        for sub in self.subsystems:
            sub.freeze(n, t)
        b_star, iters, res, _ = self.solve(n, t)
        a_hat = list(self.P @ b_star)
        b_next = []
        for sub, a_i in zip(self.subsystems, self.scene.split(a_hat)):
            b_next.extend(sub.advance(a_i))
        self.b = b_next
        return StepLog(iterations=iters, residual=res, reason="converged", a_hat=a_hat)
