"""Fixed-point iteration on the physical interface variables with rollback (as in MasterSim, PyFMI).

Per macro-step: freeze x^n; y^0 = y^n; y^{k+1} = S^n(G y^k) by queries (a Jacobi or Gauss-Seidel
pass), stopped by the budget K, the tolerance |y^{k+1} - y^k| <= eps, or the deadline; then commit
with inputs G y^K. K = 0 is the explicit master of the same ordering. With `master.fast` (auto, as
for DR) the whole macro-step runs in C (wavecosim/kernel/classical.py), one call per step or blocks
of steps (masters/kernel_route.py), to the last bit the same.
"""
import time

from ..kernel.drkernel import REASONS
from ..kernel.linalg import distance
from .base import StepLog
from .kernel_route import KernelRoute
from .physical import RollbackPhysicalMaster


class JacobiIterMaster(KernelRoute, RollbackPhysicalMaster):
    """Fixed-point (Picard) iteration, all subsystems queried with the previous iterate."""
    budgets = (1, 2, 3, 4, 5, 6, 8, 10, 15)
    style = ("tab:purple", "s")

    def __init__(self, scene, settings):
        super().__init__(scene, settings)
        self.K, self.eps = settings.K, settings.eps
        self.attach_kernel(scene, settings, type(self).update is JacobiIterMaster.update)   # blocks: Picard only

    def make_step(self, n, t) -> StepLog:
        if self.kernel is not None and self.blocks:
            return self._kernel_step(n, t)
        if self.kernel is not None:
            return self.planned(lambda measure: self._passes(n, t, measure))[0]
        return self._iterate(n, t, lambda y: self.sweep(y, lambda sub, inputs: sub.query(inputs)), self._commit)

    def _passes(self, n, t, measure):
        """The macro-step with its passes in C (classical.h, cl_pass) and the update here: (its StepLog,)."""
        passes = []

        def query(y):
            passes.append(1)
            return self.kernel.one_pass(n, t, y, first=len(passes) == 1, measure=measure)[0]

        def commit(y):
            self.y_step_start = self.y
            self.y, self.u = self.kernel.one_pass(n, t, y, commit=True, first=not passes, measure=measure)

        log = self._iterate(n, t, query, commit, freeze=False)
        self.book_kernel(n, t)
        return (log,)

    def _iterate(self, n, t, query, commit, freeze=True):
        """Freeze x^n, iterate y -> update(y, query(y)) within the budget, tolerance and deadline,
        then commit(y^K)."""
        self.step_started = time.perf_counter()
        if freeze:
            self.scene.freeze(n, t)
        deadline = self.step_started + self.inner_deadline_s if self.deadline_s else None
        y, k, residual, reason = self.y, 0, float("nan"), "budget"
        self.restart()
        while k < self.K:
            y_tilde = query(y)
            residual = distance(y_tilde.tolist(), y.tolist())
            y, k = self.update(y, y_tilde), k + 1
            if self.eps is not None and residual <= self.eps:
                reason = "tolerance"
                break
            if deadline is not None and time.perf_counter() >= deadline:
                reason = "deadline"
                break
        commit(y)
        return StepLog(iterations=k, residual=residual, reason=reason if self.K else "explicit")

    def _kernel_step(self, n, t) -> StepLog:
        """The same macro-step in C (classical.c); its FMU calls count in the FMUs' counters."""
        self.step_started = time.perf_counter()
        self.configure_kernel()
        io, y_next, u = self.planned(lambda measure: self.kernel.fixed_point_step(n, t, self.y, int(self.sequential),
                                                                                  measure))
        self.book_kernel(n, t)
        self.y_step_start, self.y, self.u = self.y, y_next, u
        return StepLog(iterations=io.iterations, residual=io.residual, reason=REASONS[io.reason])

    def configure_kernel(self):
        """The budget, tolerance and deadline of the kernel's next macro-steps."""
        self.kernel.configure(self.K, self.eps, self.inner_deadline_s if self.deadline_s else None)

    def book_kernel(self, n, t):
        """After kernel macro-steps, the last one step n at t: where the subsystems are."""
        for s in self.subsystems:
            s.note_kernel_step(n, t)

    def took_block(self, log, done):
        """After a block of kernel steps: y^n and y^{n+1} of its last step and its committed inputs
        (copied: the next call overwrites the log), so _undo_step works as after step()."""
        self.y_step_start = log.b_at(done - 2) if done > 1 else self.y
        self.y, self.u = log.b_at(done - 1), log.a_hat_at(done - 1)

    def restart(self):
        """A new macro-step's iteration begins (accelerators forget what they learnt)."""

    def update(self, y, y_tilde):
        """The next iterate from y and its image y_tilde = S^n(G y): Picard takes the image."""
        return y_tilde


class GaussSeidelIterMaster(JacobiIterMaster):
    """The same iteration with sequential passes (each subsystem sees its predecessors' new outputs)."""
    style = ("tab:brown", "D")
    sequential = True
