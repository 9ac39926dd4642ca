"""Energy guard: the total stored energy of a source-free scene never rises above its start value.

Theorem 1 bounds one macro-step at a time; it does not chain across steps, so a small budget can
pump energy in over many steps (docs/energy.md). No passive, losslessly coupled, source-free
system can hold more energy than it started with, and the monolithic step cannot raise H
(eq. 27 summed with a = P b). So a DR step whose committed H exceeds H(0) is undone (x^n restored)
and redone as the monolithic step (interface Newton), which keeps H <= H^n <= H(0).
"""
from ..errors import NumericalError
from ..kernel.linalg import total
from .steplog import StepLog

RTOL = 1e-12


class EnergyGuard:
    """The monolithic guard a DR master owns: it reads H at x^0 when made (the FMUs are there) and
    judges every commit after it (after_commit); the kernel's blocks stop after a step whose H may
    exceed `cap`, which the guard then judges."""

    def __init__(self, master):
        self.master = master
        self.redone, self.extra = 0, 0
        self._reads = [s.reader([s.port.energy])[0] for s in master.scene.subsystems]
        H0 = self.stored_energy()
        self.cap = H0 + RTOL * abs(H0)

    def stored_energy(self):
        """H = sum of H_i read from the FMUs as they are now."""
        return total([read()[0] for read in self._reads])

    def after_commit(self, n, t, log):
        """The StepLog of the step: log if the committed step is kept, else the monolithic redo's."""
        if not self.stored_energy() > self.cap:
            return log
        master = self.master
        calls = master.scene.do_step_calls()
        master._undo_step()
        try:
            a_hat, iters, res = master._interface_solution(n, t, " (energy guard)")
        except NumericalError:
            a_hat, iters, res = [0.0] * len(master.b), 0, float("nan")   # matched loads: each port only dissipates
        master._recommit(a_hat)
        self.redone += 1
        self.extra += master.scene.do_step_calls() - calls
        return StepLog(iterations=iters, residual=res, reason="energy-guard", a_hat=a_hat)

    def summary(self):
        return {"energy_guard_steps": self.redone, "energy_guard_extra_doSteps": self.extra}
