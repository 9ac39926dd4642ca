"""What the classical masters share: they exchange physical port variables, inputs = G outputs.

Each subsystem's output is the conjugate of its input (effort for a flow input, flow for an effort
input); G comes from the Dirac structure split by causality (Scene.input_map). A pass hands every
subsystem its inputs G y: all from the old y (Jacobi), or with the outputs its predecessors just
produced (Gauss-Seidel, `sequential`).
"""
import numpy as np

from .base import Master


class PhysicalMaster(Master):
    """Base of the physical-domain masters: holds G and the committed outputs y^n."""
    wave = False
    sequential = False

    def __init__(self, scene, settings):
        super().__init__(scene, settings)
        self.G = scene.input_map()
        self.y = np.zeros(scene.n_channels)          # the FMUs output e = f = 0 before their first step

    def sweep(self, y, call):
        """One pass: each subsystem gets inputs G y and returns its new outputs via call(sub, inputs)."""
        y_new = y.copy()
        source = y_new if self.sequential else y
        for sub, off in zip(self.subsystems, self.scene.offsets):
            inputs = self.G[off:off + sub.m] @ source
            y_new[off:off + sub.m] = call(sub, list(inputs))
        return y_new


def step_forward(sub, n, t, inputs):
    """One doStep from the current state, nothing saved first (for masters that never roll back)."""
    sub.begin(n, t)
    return sub.advance(inputs)
