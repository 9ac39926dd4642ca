"""Energy guard: the total stored energy of a source-free scene never rises above its start value.

Theorem 1 bounds one macro-step at a time; it does not chain across steps, so a small budget can
pump energy in over many steps (docs/scenes.md). No passive, losslessly coupled, source-free
system can hold more energy than it started with, and the monolithic step cannot raise H
(eq. 27 summed with a = P b). So a DR step whose committed H exceeds H(0) is undone (x^n restored)
and redone as the monolithic step (interface Newton), which keeps H <= H^n <= H(0).
"""
import numpy as np

from .errors import NumericalError
from .masters.base import StepLog
from .masters.newton import solve_interface

RTOL = 1e-12


class EnergyGuard:
    """Wraps the commit of the DR master: `before` keeps b^n, `after` checks H^{n+1}."""

    def __init__(self, scene, master, H0):
        self.scene, self.master = scene, master
        self.cap = H0 + RTOL * abs(H0)
        self.sizes = [s.m for s in scene.subsystems]
        self.redone = 0
        self._b_n = None

    def before(self, n, t):
        """Keep b^n; x^n needs no copy: the DR masters freeze it in each Subsystem before the commit."""
        self._b_n = list(self.master.b)

    def after(self, n, t, H_total):
        """None if the committed step is kept, else the StepLog of the monolithic redo."""
        if not H_total > self.cap:
            return None
        subs = self.scene.subsystems
        for s in subs:
            s.restore_frozen()
        P = np.asarray(self.master.P)

        def S(u):
            b = []
            for s, a_i in zip(subs, self.scene.split(u)):
                b.extend(s.query(a_i))
            return b
        try:
            b_star, iters, res, _ = solve_interface(S, P, self._b_n, max(self.sizes), self.scene.offsets, self.sizes,
                                                    where=f" (energy guard) at step {n} (t = {t:.6g})")
            a_hat = list(P @ b_star)
        except NumericalError:
            a_hat, iters, res = [0.0] * len(self._b_n), 0, float("nan")   # matched loads: each port only dissipates
        b_next = []
        for s, a_i in zip(subs, self.scene.split(a_hat)):
            b_next.extend(s.advance(a_i))
        self.master.b = b_next
        self.redone += 1
        return StepLog(iterations=iters, residual=res, reason="energy-guard", a_hat=a_hat)
