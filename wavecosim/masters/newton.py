"""`newton`: interface Newton with rollback, the monolithic macro-step (wavecosim/monolithic.py) as a master."""
import numpy as np

from ..monolithic import solve_interface
from .base import StepLog, WaveMaster


class NewtonMaster(WaveMaster):
    """Monolithic macro-step: solve b* = S^n(P b*) to roundoff, then advance with a = P b*."""
    style = ("black", "*")

    def step(self, n, t) -> StepLog:
        self.scene.freeze(n, t)
        b_star, iters, res, _ = solve_interface(self.scene, self.P, self.b, where=f" at step {n} (t = {t:.6g})")
        a_hat = list(np.asarray(self.P) @ b_star)
        self.commit(a_hat)
        return StepLog(iterations=iters, residual=res, reason="converged", a_hat=a_hat)
