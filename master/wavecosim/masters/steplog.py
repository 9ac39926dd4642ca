"""What one macro-step did, as a master's step() and its route's step_log() give it."""
from dataclasses import dataclass


@dataclass
class StepLog:
    """What one macro-step did: inner iterations, last inner residual and why the iteration stopped.

    Wave masters also give the incident waves used (a_hat), and DR the iterates u^0 and u^K."""
    iterations: int = 0
    residual: float = float("nan")
    reason: str = "none"
    a_hat: list = None
    u0: list = None
    uK: list = None
    ledger: tuple = None      # the energy ledger's figures of the step: (I^n, L^n, s, action, redo rounds)
