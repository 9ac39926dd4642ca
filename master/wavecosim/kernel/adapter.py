"""The wave adapter's C side (kernel/c/adapter.c, the kernel library libadapter.so): its struct,
field for field, and the library with its argument types and a size check of the struct. The port
that uses it is wavecosim.core.adapter_kernel.KernelAdapter.
"""
import ctypes

from .abi import mirrors
from .contract import constant
from .build import kernel_library
from .fmicall import FmiFailure

LIBRARY_NAME = "adapter"                   # libadapter.so, from kernel/c/adapter.c
SHIM = ("getFMUstate", "setFMUstate", "freeFMUstate", "setReal", "doStep", "getReal")   # drkernel.h DRFunctions, less calls
AD_FMU, AD_SINGULAR, AD_STALLED = (constant("adapter.h", name) for name in ("AD_FMU", "AD_SINGULAR", "AD_STALLED"))
_D, _L = ctypes.POINTER(ctypes.c_double), ctypes.c_long


@mirrors("adapter", "WaveAdapterC")
class AdapterC(ctypes.Structure):
    """adapter.h: WaveAdapterC, field for field."""
    _fields_ = [("fn", ctypes.c_void_p * (len(SHIM) + 1)), ("comp", ctypes.c_void_p), ("state", ctypes.c_void_p),
                ("in_vr", ctypes.POINTER(ctypes.c_uint)), ("out_vr", ctypes.POINTER(ctypes.c_uint)),
                ("m", ctypes.c_int), ("no_prior", ctypes.c_int), ("effort_in", ctypes.POINTER(ctypes.c_int)),
                ("sign", _D),
                ("gamma", ctypes.c_double), ("c", ctypes.c_double), ("k", ctypes.c_double), ("wu", _D), ("wy", _D),
                ("tol", ctypes.c_double), ("accept", ctypes.c_double), ("slope_rel", ctypes.c_double),
                ("max_iter", ctypes.c_int), ("stall", ctypes.c_int), ("dirty", ctypes.c_void_p),
                ("have_slope", ctypes.c_int), ("u", _D), ("y", _D), ("D", _D), ("J_inv", _D),
                ("h2", ctypes.c_double), ("u_scale", ctypes.c_double), ("evaluations", _L), ("do_steps", _L),
                ("accepted", _L), ("worst_accepted", ctypes.c_double),
                ("a", _D), ("e", _D), ("f", _D), ("b", _D), ("failure", ctypes.c_int),
                ("failed", FmiFailure), ("failed_rel", ctypes.c_double),
                ("failed_r", _D), ("work", _D)]


_lib = None


def load_library():
    """The adapter library, built if missing or stale; raises FmuError if it cannot be (LayoutError if its
    struct differs from AdapterC)."""
    global _lib
    if _lib is None:
        _lib = kernel_library(LIBRARY_NAME, "the wave adapter library")
    return _lib


def _doubles(values):
    return (ctypes.c_double * len(values))(*values)


def new_adapter(fns, comp, state, dirty, in_vr, out_vr, effort_in, sign, memory):
    """A WaveAdapterC over the FMU function table `fns` (a DRFunctions) and component `comp`, saving
    x_i^n into the handle at address `state`, the flag at address `dirty` saying the FMU moved away from it, with the ports.WaveAdapter memory it takes over
    (u, y, D, J_inv, h2, u_scale and the figures); the Newton constants are set by the caller.
    Returns (the library, the struct, a reference to it for the calls)."""
    lib, m, st = load_library(), len(effort_in), AdapterC()
    ctypes.memmove(st.fn, ctypes.addressof(fns), ctypes.sizeof(st.fn))
    st.comp, st.state, st.dirty, st.m, st.in_vr, st.out_vr = comp, state, dirty, m, in_vr, out_vr
    # arrays assigned to the struct's pointers stay alive with it (ctypes keeps them)
    st.effort_in, st.sign = (ctypes.c_int * m)(*effort_in), _doubles(sign)
    st.u, st.y = _doubles(memory["u"]), _doubles(memory["y"])
    st.D, st.J_inv = _doubles(memory["D"]), _doubles(memory["J_inv"])
    st.wu, st.wy, st.a, st.e, st.f, st.b, st.failed_r = [_doubles([0.0] * m) for _ in range(7)]
    st.work = _doubles([0.0] * lib.adapter_work_size(m))
    for key in ("have_slope", "h2", "u_scale", "evaluations", "do_steps", "accepted", "worst_accepted"):
        setattr(st, key, memory[key])
    return lib, st, ctypes.byref(st)


def shim(lib, struct):
    """(function table, component) of an adapter as an fmi2 wave port, for the DR kernel to call."""
    return [ctypes.cast(getattr(lib, f"adapter_{name}"), ctypes.c_void_p).value for name in SHIM], \
        ctypes.addressof(struct)


def field_address(struct, name):
    """The address of field `name` of an adapter struct (the kernel reads it at each step)."""
    return ctypes.addressof(struct) + getattr(type(struct), name).offset
