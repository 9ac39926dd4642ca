"""The kernel route of the classical masters (explicit, gauss-seidel, jacobi-iter, gauss-seidel-iter).

kernel/c/classical.c runs a whole macro-step of the Python reference
(wavecosim/masters/explicit.py, fixed_point.py) in C, through the DR kernel's subsystem evaluation with the FMUs
in their physical port mode, in the reference's operation order, so the numbers are bit-identical.
`ClassicalKernel` wires it up through ctypes; the masters pick it with `master.fast` like DR
(wavecosim/masters/kernel_route.py), one macro-step per call or blocks of them.
"""
import ctypes
import functools
import math

import numpy as np

from ..errors import FmuError
from .drkernel import Kernel, load_library

_double_p = ctypes.POINTER(ctypes.c_double)


class ClassicalKernel:
    """A DR kernel over the scene's subsystems (physical mode) and the classical step on it."""

    def __init__(self, scene, G, explicit, sequential):
        self.lib = load_library()
        self.base = Kernel(scene, None, None)
        self.base.configure(scene.dt, 0)
        self.n = scene.n
        ptr = ctypes.POINTER(ctypes.c_int)
        self.handle = self.lib.cl_create(self.base.handle, G.start.ctypes.data_as(ptr), G.col.ctypes.data_as(ptr),
                                         G.val.ctypes.data_as(_double_p), int(explicit), int(sequential))
        if not self.handle:
            self.base.close()
            raise FmuError("the classical kernel could not be created (out of memory)")
        self._handle, self._step = ctypes.c_void_p(self.handle), self.lib.cl_fixed_point_step
        self._b = np.frombuffer(self.base.b, dtype=np.float64)          # y^n for cl_run_steps, in place
        # the DR kernel's block call, log and observed values, with the classical step in it
        self.base._run_steps = functools.partial(self.lib.cl_run_steps, self._handle)

    def run_steps(self, n0, count, y, H_cap=math.inf, measure=False, passes=False):
        """Macro-steps n0 .. n0 + count - 1 from outputs y in one call (classical.h, cl_run_steps):
        (steps done, their drkernel.BlockLog, the FmuError of the step after them or None);
        measure: time the evaluations (Kernel.costs); passes: make the kernel's passes (Kernel.run_steps)."""
        self._b[:] = y
        return self.base.run_steps(n0, count, H_cap, measure, passes=passes)

    def configure(self, K, eps, deadline_s):
        self.base.configure(self.base.io.dt, K, eps, deadline_s)

    def fixed_point_step(self, n, t, y, sequential, measure=False):
        """Macro-step n from outputs y: (io, y^{n+1}, committed inputs); raises the reference's FmuError."""
        io = self.base.io
        io.t, io.measure = t, measure
        y_n = np.ascontiguousarray(y, dtype=np.float64)
        y_next, u = np.empty(self.n), np.empty(self.n)
        if self._step(self._handle, self.base._io, y_n.ctypes.data, y_next.ctypes.data, u.ctypes.data, sequential):
            raise self.base.failure(n, t)
        return io, y_next, u

    def one_pass(self, n, t, y, commit=False, first=False, measure=False):
        """One Jacobi pass from y (classical.h, cl_pass): (outputs, inputs handed out); first: macro-step
        n at t begins; commit: the state is kept. Raises the reference's FmuError."""
        io = self.base.io
        io.t, io.measure = t, measure
        y_n = np.ascontiguousarray(y, dtype=np.float64)
        y_new, u = np.empty(self.n), np.empty(self.n)
        if self.lib.cl_pass(self._handle, self.base._io, y_n.ctypes.data, y_new.ctypes.data, u.ctypes.data,
                            int(commit), int(first)):
            raise self.base.failure(n, t)
        return y_new, u

    def explicit_step(self, n, t, y, sequential, measure=False):
        """Explicit macro-step n from outputs y, nothing saved: (io, y^{n+1})."""
        self.base.io.t, self.base.io.measure = t, measure
        y_n = np.ascontiguousarray(y, dtype=np.float64)
        y_next = np.empty(self.n)
        if self.lib.cl_explicit_step(self._handle, self.base._io, y_n.ctypes.data, y_next.ctypes.data, sequential):
            raise self.base.failure(n, t)
        return self.base.io, y_next

    def close(self):
        if self.handle:
            self.lib.cl_destroy(self.handle)
            self.handle = None
        self.base.close()
