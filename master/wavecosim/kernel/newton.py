"""The kernel route of the newton master: kernel/c/newton.c runs a whole macro-step of
wavecosim/masters/newton.py (the interface Newton of monolithic.solve_interface, then the commit)
in C, through the DR kernel's subsystem evaluation with the FMUs in wave port mode, in the
reference's operation order, so the numbers are bit-identical. `NewtonKernel` wires it up through
ctypes; the master picks it with `master.fast` like DR.
"""
import ctypes
import math

import numpy as np

from ..errors import FmuError, NumericalError
from .abi import mirrors
from .contract import constant
from .drkernel import Kernel, load_library

_int_p, _double_p = ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_double)
# The interface Newton's constants, the same for the Python solve (masters/monolithic.py) and newton.c.
TOL = 1e-14
ACCEPT = 1e-9           # absolute, scaled by 1 + |b|
ACCEPT_REL = 1e-5       # relative to the port-wave scale |a| + |b|
MAX_ITER = 30
STALL = 3
NON_FINITE, SINGULAR = "non-finite residual", "singular Jacobian"
WHY = {constant("newton.h", code): why for code, why in (("NT_NONFINITE", NON_FINITE), ("NT_SINGULAR", SINGULAR),
                                                        ("NT_NO_MEMORY", "out of memory"))}
NOT_CONVERGED = constant("newton.h", "NT_NOT_CONVERGED")


@mirrors("drkernel", "NTSettings")
class NTSettings(ctypes.Structure):
    """newton.h: Newton's constants, monolithic.py's."""
    _fields_ = [("tol", ctypes.c_double), ("accept", ctypes.c_double), ("accept_rel", ctypes.c_double),
                ("max_iter", ctypes.c_int), ("stall", ctypes.c_int)]


def _csr(P):
    return P.start.ctypes.data_as(_int_p), P.col.ctypes.data_as(_int_p), P.val.ctypes.data_as(_double_p)


class NewtonKernel:
    """A DR kernel over the scene's subsystems (wave mode) and the Newton macro-step on it."""

    def __init__(self, scene, P, counted=True):
        """counted: its FMU calls count in the FMUs' counters (not the certificates', drkernel.Kernel)."""
        self.lib = load_library()
        self.base = Kernel(scene, None, None, counted)
        self.base.configure(scene.dt, 0)
        self.n = scene.n
        self.settings = NTSettings(TOL, ACCEPT, ACCEPT_REL, MAX_ITER, STALL)
        self.handle = self.lib.nt_create(self.base.handle, *_csr(P), ctypes.byref(self.settings))
        if not self.handle:
            self.base.close()
            raise FmuError("the Newton kernel could not be created (out of memory)")
        self._handle = ctypes.c_void_p(self.handle)
        self.b_next, self.a_hat, self.out = np.empty(self.n), np.empty(self.n), np.empty(2)

    def set_map(self, P):
        """A new wave map P (gamma retuned)."""
        if self.lib.nt_set_map(self._handle, *_csr(P)):
            raise FmuError("the Newton kernel refused the wave map (out of memory)")

    def step(self, n, t, b):
        """Macro-step n from b^n: (io, b^{n+1}, a_hat, S-evaluations); raises the reference's errors."""
        self.base.io.t = t
        b_n = np.ascontiguousarray(b, dtype=np.float64)
        rc = self.lib.nt_step(self._handle, self.base._io, b_n.ctypes.data, self.b_next.ctypes.data,
                              self.a_hat.ctypes.data, self.out.ctypes.data)
        self._check(rc, n, t)
        return self.base.io, self.b_next.tolist(), self.a_hat.tolist(), int(self.out[0])

    def solve(self, n, t, b):
        """b* of monolithic.solve_interface at x^n from b^n (a list), the subsystems left at x^n; raises
        the reference's errors. Its FMU calls are booked nowhere (the certificates' own)."""
        self.base.io.t = t
        b_n = np.ascontiguousarray(b, dtype=np.float64)
        rc = self.lib.nt_solve(self._handle, self.base._io, b_n.ctypes.data, self.b_next.ctypes.data,
                               self.out.ctypes.data)
        self._check(rc, n, t)
        return self.b_next.tolist()

    def _check(self, rc, n, t):
        """The reference's exception for a return code of nt_step or nt_solve."""
        if rc:
            where = f" at step {n} (t = {t:.6g})"
            if rc < 0:
                raise self.base.failure(n, t)
            if rc == NOT_CONVERGED:
                raise not_converged(where, self.base.io.residual, float(self.out[1]))
            source = nan_source(self.base.subsystems, int(self.out[1])) if WHY[rc] == NON_FINITE else None
            raise failed(where, WHY[rc], source)

    def close(self):
        if self.handle:
            self.lib.nt_destroy(self.handle)
            self.handle = None
        self.base.close()


def not_converged(where, res, scale):
    """The error of a Newton solve whose best residual is past both acceptance levels."""
    return NumericalError(f"interface Newton{where} did not converge: |b - S(Pb)| = {res:.3g} "
                          f"(> {ACCEPT_REL:g} of the port-wave scale {scale:.3g})")


def failed(where, why, source=None):
    """The error of a Newton solve that cannot go on (why: "non-finite residual", "singular Jacobian");
    source: the subsystem whose outgoing wave was not finite (nan_source), named as the NaN's maker."""
    cause = (f": subsystem {source} gave a non-finite outgoing wave for a finite incident one (a NaN or an "
             f"infinity from its FMU)" if source else "")
    return NumericalError(f"interface Newton{where}: {why}{cause}")


def nan_channel(a, s):
    """The first channel whose outgoing wave s is not finite for a finite incident wave a, else -1."""
    return next((j for j, (x, y) in enumerate(zip(a, s)) if math.isfinite(x) and not math.isfinite(y)), -1)


def nan_source(subsystems, channel):
    """The name of the subsystem (channels in their order) that holds `channel`, None for -1."""
    for sub in subsystems if channel >= 0 else ():
        if channel < sub.m:
            return sub.name
        channel -= sub.m
    return None
