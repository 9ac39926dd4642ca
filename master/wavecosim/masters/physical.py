"""What the classical masters share: they exchange physical port variables, inputs = G outputs.

Each subsystem's output is the conjugate of its input (effort for a flow input, flow for an effort
input); G comes from the Dirac structure split by causality (Scene.input_map). A pass hands every
subsystem its inputs G y: all from the old y (Jacobi), or with the outputs its predecessors just
produced (Gauss-Seidel, `sequential`).
"""
import numpy as np

from ..kernel.linalg import Sparse, matvec_rows, norm1, total
from .base import Master


class PhysicalMaster(Master):
    """Base of the physical-domain masters: holds G and the committed outputs y^n."""
    wave = False
    sequential = False

    def __init__(self, scene, settings):
        super().__init__(scene, settings)
        self.G = Sparse.from_dense(scene.input_map())    # rows summed in order, as the C kernel does
        self.y = np.zeros(scene.n_channels)          # the FMUs output e = f = 0 before their first step

    def sweep(self, y, call, inputs_used=None):
        """One pass: each subsystem gets inputs G y and returns its new outputs via call(sub, inputs);
        the inputs handed out are written into inputs_used when given."""
        y_new = y.copy()
        source = y_new if self.sequential else y
        for sub, off in zip(self.subsystems, self.scene.offsets):
            inputs = matvec_rows(self.G, source, off, off + sub.m)
            if inputs_used is not None:
                inputs_used[off:off + sub.m] = inputs
            y_new[off:off + sub.m] = call(sub, inputs)
        return y_new


class RollbackPhysicalMaster(PhysicalMaster):
    """A physical master that freezes x^n: it can undo its commit and redo it with other inputs."""
    guardable = True

    def __init__(self, scene, settings):
        super().__init__(scene, settings)
        self.y_step_start = self.y
        self.u = np.zeros(scene.n_channels)          # the inputs of the last commit

    def _commit(self, y):
        """The one commit of the macro-step, with inputs G y (sequentially for Gauss-Seidel)."""
        self.y_step_start = self.y
        self.y = self.sweep(y, lambda sub, inputs: sub.advance(inputs), self.u)

    def _undo_step(self):
        """Every subsystem back at x^n and y^n back, after the commit of macro-step n."""
        self.scene.restore_frozen()
        self.y = self.y_step_start

    def _recommit(self, inputs):
        """After _undo_step: commit macro-step n again with these stacked inputs; returns y^{n+1}."""
        self.y_step_start, self.u = self.y, np.asarray(inputs, float)
        self.y = np.asarray(self.scene.advance(list(inputs)))
        return self.y

    @property
    def _committed_outputs(self):
        """The outputs of the last commit: y^{n+1}."""
        return list(self.y)

    def _committed_inputs(self, log):
        return list(self.u)

    def _supply(self, inputs, outputs):
        """Energy into the ports over a step, dt sum(input * output) (each a conjugate pair), and its
        traffic dt sum |input * output|."""
        powers = [u * y for u, y in zip(inputs, outputs)]
        return self.dt * total(powers), self.dt * norm1(powers)


def step_forward(sub, n, t, inputs):
    """One doStep from the current state, nothing saved first (for masters that never roll back)."""
    sub.begin(n, t)
    return sub.advance(inputs)
