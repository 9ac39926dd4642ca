"""Physical ports on the kernel route (kernel/c/portview.c, in libdrkernel.so): a signed port as an
fmi2 shim the kernel calls like an FMU (`SignedPort`; a multi-rate subsystem's substeps likewise,
kernel/c/multirate.c, `MultiRate`), and the view the runner reads a physical port
through after each commit in blocks of steps (`ObservedPort`, `PortView`), both bit for bit what
wavecosim/core/ports.py and readings.py compute in Python.
"""
import ctypes
from dataclasses import dataclass

from ..errors import FmuError



@dataclass
class ObservedPort:
    """What the runner reads of a physical port after a commit (readings.Sampler._physical_part):
    `names` ([energy,] efforts, flows, recorded outputs) read raw, returned as [H or NaN, e, sign f,
    (adapter) b, outputs]; `len()` is the number of values returned."""
    names: list
    has_H: bool
    m: int
    sign: list
    adapter: bool
    n_out: int

    def __len__(self):
        return 1 + 2 * self.m + (self.m if self.adapter else 0) + self.n_out


class SignedPort:
    """An FMU with port signs behind portview.c's shim: (functions, component) for the kernel."""

    def __init__(self, lib, fns, comp, m, in_scale, out_scale):
        self.lib = lib
        scales = [(ctypes.c_double * m)(*map(float, v)) for v in (in_scale, out_scale)]
        self.handle = self.lib.sp_create(ctypes.byref(fns), comp, m, *scales)
        if not self.handle:
            raise FmuError("the kernel could not wrap a signed physical port (out of memory)")
        self.functions = type(fns)()
        self.lib.sp_functions(ctypes.byref(self.functions))

    def close(self):
        if self.handle:
            self.lib.sp_destroy(self.handle)
            self.handle = None


class MultiRate:
    """An FMU making `substeps` doSteps per macro-step behind multirate.c's shim: (functions, component)
    for the kernel, and the address of its count of the FMU's doSteps (`do_steps`)."""

    def __init__(self, lib, fns, comp, m, substeps):
        n, scale, stage_vrs, stage = substeps
        self.lib = lib
        vrs = (ctypes.c_uint * len(stage_vrs))(*stage_vrs) if stage_vrs is not None else None
        self.handle = self.lib.mr_create(ctypes.byref(fns), comp, n, scale, m, vrs, stage)
        if not self.handle:
            raise FmuError("the kernel could not wrap a multi-rate subsystem (out of memory)")
        self.functions = type(fns)()
        self.lib.mr_functions(ctypes.byref(self.functions))
        self.do_steps = self.lib.mr_do_steps(self.handle)

    def close(self):
        if self.handle:
            self.lib.mr_destroy(self.handle)
            self.handle = None


class PortView:
    """portview.c's view of one physical port over the FMU's own getReal (`get`, `comp`); `impedance`:
    the addresses of the wave adapter's gamma and k, or None."""

    def __init__(self, lib, get, comp, vrs, port: ObservedPort, impedance=None):
        self.lib = lib
        gamma, k = impedance or (None, None)
        self.handle = self.lib.pv_create(get, comp, (ctypes.c_uint * len(vrs))(*vrs), int(port.has_H), port.m,
                                         port.n_out, (ctypes.c_double * port.m)(*map(float, port.sign)), gamma, k)
        if not self.handle:
            raise FmuError("the kernel could not make a physical port's view (out of memory)")
        assert self.lib.pv_size(self.handle) == len(port)
        self.get = ctypes.cast(self.lib.pv_getReal, ctypes.c_void_p).value

    def close(self):
        if self.handle:
            self.lib.pv_destroy(self.handle)
            self.handle = None
