"""Zero-order-hold Jacobi: every FMU gets the other's last output, one doStep each, no iteration.

With `master.fast` (auto, as for DR) the step runs in C (wavecosim/kernel/classical.py), one
call per step or blocks of steps (masters/kernel_route.py), to the last bit the same."""
import numpy as np

from .base import StepLog
from .kernel_route import KernelRoute
from .physical import PhysicalMaster, step_forward


class ExplicitMaster(KernelRoute, PhysicalMaster):
    """y^{n+1} = Phi(x^n, G y^n) for all subsystems at once; no state is saved or restored."""
    style = ("tab:red", "v")
    needs_rollback = False

    def __init__(self, scene, settings):
        super().__init__(scene, settings)
        self.held = np.zeros(scene.n_channels)   # the inputs held over the last step made in Python
        self.attach_kernel(scene, settings)

    def make_step(self, n, t) -> StepLog:
        if self.kernel is not None:
            _, self.y = self.planned(lambda measure: self.kernel.explicit_step(n, t, self.y, int(self.sequential),
                                                                              measure))
            self.book_kernel(n, t)
            return StepLog(iterations=0, reason="explicit")
        self.y = self.sweep(self.y, lambda sub, inputs: step_forward(sub, n, t, inputs), self.held)
        return StepLog(iterations=0, reason="explicit")

    def block_iterations(self, log):
        """0: an explicit step has no inner loop."""
        return 0

    def configure_kernel(self):
        """Nothing to set: an explicit step has no inner loop."""

    def book_kernel(self, n, t):
        """After kernel macro-steps, the last one step n at t: where the subsystems are."""
        for sub in self.subsystems:
            sub.begin(n, t)

    def took_block(self, log, done):
        """After a block of kernel steps: its last y^{n+1} (copied: the next call overwrites the log)."""
        self.y = log.b_at(done - 1)
