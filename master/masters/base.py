"""The contract every master meets: `step(n, t)` advances all subsystems by one macro-step."""
from dataclasses import dataclass, field


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
    extra: dict = field(default_factory=dict)


class Master:
    """Base of all masters. Subclasses set `wave` (port mode of the FMUs) and implement step()."""
    name = "?"
    wave = True
    needs_rollback = True

    def __init__(self, scene, settings):
        self.scene, self.settings = scene, settings
        self.subsystems = scene.subsystems
        self.dt = scene.scenario.dt

    def step(self, n, t) -> StepLog:
        raise NotImplementedError

    def close(self):
        """Release anything the master holds beyond the scene (threads, C buffers)."""
