"""Zero-order-hold Jacobi: every FMU gets the other's last output, one doStep each, no iteration."""
from .base import StepLog
from .physical import PhysicalMaster, step_forward


class ExplicitMaster(PhysicalMaster):
    """y^{n+1} = Phi(x^n, G y^n) for all subsystems at once; no state is saved or restored."""
    style = ("tab:red", "v")
    needs_rollback = False

    def step(self, n, t) -> StepLog:
        self.y = self.sweep(self.y, lambda sub, inputs: step_forward(sub, n, t, inputs))
        return StepLog(iterations=0, reason="explicit")
