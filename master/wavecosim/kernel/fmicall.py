"""The kernel's FMI call table (kernel/c/fmicall.h): the record its one status check leaves of a failed
FMU call, mirrored for the bindings that turn it into the error the Python route raises."""
import ctypes

from .abi import mirrors


@mirrors("drkernel", "adapter", "queries", "FmiFailure")
class FmiFailure(ctypes.Structure):
    """fmicall.h: the FMU call that failed, its DR_FN_* or SG_FN_*, and the fmi2Status it returned."""
    _fields_ = [("function", ctypes.c_int), ("status", ctypes.c_int)]
