"""Many queries of one frozen port map in one C call (kernel/c/queries.c, the kernel library
libqueries.so): the FMU calls of as many Subsystem.raw_query calls, made in C over the FMU's own
function table (wavecosim/core/frozen_port_map.py, Subsystem.raw_queries)."""
import ctypes

import numpy as np

from .build import helper_library
from .drkernel import FMI_NAMES, DRFunctions
from .fmicall import FmiFailure


class Queries:
    """fq_queries over one FMU's function table."""

    def __init__(self, lib, pointer, calls):
        self.lib, self.fns = lib, DRFunctions(*[pointer(name) for name in FMI_NAMES], ctypes.addressof(calls))
        self.failed = FmiFailure()

    def __call__(self, comp, state, in_vr, out_vr, m, t, h, rows, dirty, no_prior=0):
        """Each row of `rows` as a query from x_i^n (held in the handle `state`; restored first only
        when dirty[0], the caller's flag, which the call sets as the instance moves; the doSteps get noSetFMUStatePriorToCurrentPoint = no_prior): (outputs as rows,
        queries made, the FMU function that failed as a code of fmicall.FUNCTION_NAMES (0: none), its
        status)."""
        inputs = np.ascontiguousarray(rows, dtype=float)
        out, p = np.empty_like(inputs), ctypes.c_void_p
        done = self.lib.fq_queries(ctypes.byref(self.fns), comp, ctypes.byref(state), in_vr, out_vr, m, t, h,
                                   p(inputs.ctypes.data), len(inputs), p(out.ctypes.data), ctypes.byref(dirty), int(no_prior),
                                   ctypes.byref(self.failed))
        return out, done, self.failed.function if done < len(inputs) else 0, self.failed.status


def batch(pointer, calls):
    """Queries over an FMU's function table (pointer(fmi2 name) -> the function's address), counting
    in its call counters `calls` (a ctypes array, fmicall.h), or None without the library (no C compiler)."""
    lib = helper_library("queries")
    return lib and Queries(lib, pointer, calls)
