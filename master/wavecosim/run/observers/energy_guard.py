"""Energy guard: the total stored energy of a source-free scene never rises above its start value.

Theorem 1 bounds one macro-step at a time; it does not chain across steps, so a small budget can
pump energy in over many steps (docs/energy.md). No passive, losslessly coupled, source-free
system can hold more energy than it started with, and the monolithic step cannot raise H
(eq. 27 summed with a = P b). So a DR step whose committed H exceeds H(0) is undone (x^n restored)
and redone as the monolithic step (interface Newton), which keeps H <= H^n <= H(0).
"""
from ...errors import NumericalError
from ...kernel.linalg import total
from ...masters.base import StepLog
from . import Observer

RTOL = 1e-12


class EnergyGuard(Observer):
    """First of the observers: it may redo the step before anyone reads it."""
    redoes = True

    def __init__(self, master):
        self.master = master
        self.redone, self.extra = 0, 0

    def start(self, first):
        H0 = total(first.H)
        self.cap = H0 + RTOL * abs(H0)

    def after_step(self, n, t, log, reading, row):
        """None if the committed step is kept, else the StepLog of the monolithic redo."""
        if not total(reading.H) > self.cap:
            return None
        master = self.master
        calls = master.scene.do_step_calls()
        master.undo_step()
        try:
            a_hat, iters, res = master.interface_solution(n, t, " (energy guard)")
        except NumericalError:
            a_hat, iters, res = [0.0] * len(master.b), 0, float("nan")   # matched loads: each port only dissipates
        master.recommit(a_hat)
        self.redone += 1
        self.extra += master.scene.do_step_calls() - calls
        return StepLog(iterations=iters, residual=res, reason="energy-guard", a_hat=a_hat)

    def summary(self):
        return {"energy_guard_steps": self.redone, "energy_guard_extra_doSteps": self.extra}
