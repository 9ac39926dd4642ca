"""`newton`: interface Newton with rollback, the monolithic macro-step (wavecosim/masters/monolithic.py) as a master.

With `master.fast` (auto, as for DR) the whole macro-step runs in C (wavecosim/kernel/newton.py), to
the last bit the same.
"""
import time

from ..kernel.linalg import matvec
from .monolithic import solve_interface
from ..kernel.newton import NewtonKernel
from .base import KernelOwner, StepLog, WaveMaster, kernel_refusal


class NewtonMaster(KernelOwner, WaveMaster):
    """Monolithic macro-step: solve b* = S^n(P b*) to roundoff, then advance with a = P b*."""
    style = ("black", "*")

    def __init__(self, scene, settings):
        self.kernel = None
        super().__init__(scene, settings)
        self.fast_note = kernel_refusal(scene, str(settings.fast).lower())
        if self.fast_note is None:
            self.kernel, self.fast_note = NewtonKernel(scene.kernel_scene(), self.P), "C kernel"

    def _compile(self):
        super()._compile()
        if self.kernel is not None:
            self.kernel.set_map(self.P)

    def make_step(self, n, t) -> StepLog:
        if self.kernel is not None:
            return self._kernel_step(n, t)
        self.scene.freeze(n, t)
        b_star, iters, res, _ = solve_interface(self.scene, self.P, self.b, where=f" at step {n} (t = {t:.6g})")
        a_hat = matvec(self.P, b_star.tolist())
        self._commit(a_hat)
        return StepLog(iterations=iters, residual=res, reason="converged", a_hat=a_hat)

    def _kernel_step(self, n, t) -> StepLog:
        """The same macro-step in C (newton.c); its FMU calls count in the FMUs' counters."""
        self.step_started = time.perf_counter()
        io, b_next, a_hat, _ = self.kernel.step(n, t, self.b)
        book_kernel_step(self.subsystems, n, t)
        self._b_step_start, self._b = self._b, b_next
        return StepLog(iterations=io.iterations, residual=io.residual, reason="converged", a_hat=a_hat)


def book_kernel_step(subsystems, n, t):
    """After a kernel macro-step, step n at t: where the Subsystems are (the kernel counted its calls)."""
    for s in subsystems:
        s.note_kernel_step(n, t)
