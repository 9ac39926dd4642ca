"""The wave adapter's C side (kernel/c/adapter.c, the kernel library libadapter.so): its struct,
field for field, and the library with its argument types and a size check of the struct. The port
that uses it is wavecosim.core.adapter_kernel.KernelAdapter.
"""
import ctypes

from .build import kernel_library
from ..errors import FmuError

LIBRARY_NAME = "adapter"                   # libadapter.so, from kernel/c/adapter.c
SHIM = ("getFMUstate", "setFMUstate", "freeFMUstate", "setReal", "doStep", "getReal")   # drkernel.h DRFunctions
AD_OK, AD_FMU, AD_SINGULAR, AD_STALLED = range(4)
_D, _L = ctypes.POINTER(ctypes.c_double), ctypes.c_long


class AdapterC(ctypes.Structure):
    """adapter.h: WaveAdapterC, field for field."""
    _fields_ = [("fn", ctypes.c_void_p * len(SHIM)), ("comp", ctypes.c_void_p), ("state", ctypes.c_void_p),
                ("in_vr", ctypes.POINTER(ctypes.c_uint)), ("out_vr", ctypes.POINTER(ctypes.c_uint)),
                ("m", ctypes.c_int), ("no_prior", ctypes.c_int), ("effort_in", ctypes.POINTER(ctypes.c_int)), ("sign", _D),
                ("gamma", ctypes.c_double), ("c", ctypes.c_double), ("k", ctypes.c_double), ("wu", _D), ("wy", _D),
                ("tol", ctypes.c_double), ("accept", ctypes.c_double), ("slope_rel", ctypes.c_double),
                ("max_iter", ctypes.c_int), ("stall", ctypes.c_int), ("dirty", ctypes.c_int),
                ("have_slope", ctypes.c_int), ("u", _D), ("y", _D), ("D", _D), ("J_inv", _D),
                ("h2", ctypes.c_double), ("u_scale", ctypes.c_double), ("evaluations", _L), ("do_steps", _L),
                ("accepted", _L), ("worst_accepted", ctypes.c_double), ("calls", _L * 3),
                ("a", _D), ("e", _D), ("f", _D), ("b", _D), ("failure", ctypes.c_int),
                ("failed_function", ctypes.c_int), ("failed_status", ctypes.c_int), ("failed_rel", ctypes.c_double),
                ("failed_r", _D), ("work", _D)]


_lib = None


def load_library():
    """The adapter library, built (with the FMUs) if missing or stale; raises FmuError if it cannot be."""
    global _lib
    if _lib is None:
        lib = kernel_library(LIBRARY_NAME, "the wave adapter library")
        lib.adapter_work_size.restype = ctypes.c_size_t
        lib.adapter_work_size.argtypes = [ctypes.c_int]
        lib.adapter_solve.argtypes = [ctypes.POINTER(AdapterC), ctypes.c_double, ctypes.c_double]
        lib.adapter_reinvert.argtypes = [ctypes.POINTER(AdapterC)]
        lib.adapter_struct_size.restype = ctypes.c_size_t
        if lib.adapter_struct_size() != ctypes.sizeof(AdapterC):
            raise FmuError(f"{LIBRARY_NAME}: WaveAdapterC has {lib.adapter_struct_size()} bytes, "
                           f"wavecosim.kernel.adapter.AdapterC {ctypes.sizeof(AdapterC)} (the layouts differ)")
        _lib = lib
    return _lib
