"""The kernel's FMI call table (kernel/c/fmicall.h): the record its one status check leaves of a failed
FMU call, mirrored for the bindings that turn it into the error the Python route raises; and the FMU
call in progress, which every kernel library and the Python route write, in a supervised run into the
status page its parent shares (`trace_calls`), so a process stuck in an FMU that holds every signal
still names the subsystem and the call (`call_now`)."""
import ctypes

from .abi import mirrors
from .build import LOAD_HOOKS
from .contract import constant


@mirrors("drkernel", "adapter", "queries", "FmiFailure")
class FmiFailure(ctypes.Structure):
    """fmicall.h: the FMU call that failed, its DR_FN_* or SG_FN_*, and the fmi2Status it returned."""
    _fields_ = [("function", ctypes.c_int), ("status", ctypes.c_int)]


@mirrors("guard", "FmiCallNow")
class FmiCallNow(ctypes.Structure):
    """fmicall.h: the component of the FMU call in progress and its code (CALLS; 0: none)."""
    _fields_ = [("instance", ctypes.c_void_p), ("function", ctypes.c_int), ("spare", ctypes.c_int)]


LOAD = "the load of its binary"
FMI_ENTRIES = tuple(f"fmi2{n}" for n in (
    "Instantiate", "FreeInstance", "SetupExperiment", "EnterInitializationMode", "ExitInitializationMode",
    "Terminate", "Reset", "GetReal", "GetInteger", "GetBoolean", "GetString", "SetReal", "SetInteger", "SetBoolean",
    "SetString", "GetFMUstate", "SetFMUstate", "FreeFMUstate", "SerializedFMUstateSize", "SerializeFMUstate",
    "DeSerializeFMUstate", "GetDirectionalDerivative", "SetRealInputDerivatives", "GetRealOutputDerivatives",
    "DoStep", "CancelStep", "GetStatus", "GetRealStatus", "GetIntegerStatus", "GetBooleanStatus",
    "GetStringStatus", "SetDebugLogging")) + tuple(f"fmi3{n}" for n in (
    "InstantiateCoSimulation", "FreeInstance", "EnterInitializationMode", "ExitInitializationMode", "Terminate",
    "Reset", "GetFloat64", "SetFloat64", "GetFloat32", "SetFloat32", "GetInt32", "SetInt32", "GetBoolean",
    "SetBoolean", "GetString", "SetString", "GetFMUState", "SetFMUState", "FreeFMUState", "DoStep",
    "EnterStepMode", "UpdateDiscreteStates", "EnterEventMode"))
_KERNEL = {f"{prefix}_{verb}": f"fmi2{name}" for prefix, verb, name in (
    ("DR_FN", "GET_STATE", "GetFMUstate"), ("DR_FN", "SET_STATE", "SetFMUstate"), ("DR_FN", "SET_REAL", "SetReal"),
    ("DR_FN", "DO_STEP", "DoStep"), ("DR_FN", "GET_REAL", "GetReal"), ("SG_FN", "GET_INTEGER", "GetInteger"),
    ("SG_FN", "SET_INTEGER", "SetInteger"), ("SG_FN", "GET_BOOLEAN", "GetBoolean"),
    ("SG_FN", "SET_BOOLEAN", "SetBoolean"), ("FN", "FREE_STATE", "FreeFMUstate"))}
CALLS = {constant("drkernel.h" if key.startswith("DR") else "fmicall.h", key): name for key, name in _KERNEL.items()}
CALLS.update({64 + k: name for k, name in enumerate((LOAD, *FMI_ENTRIES))})     # the Python route's, past the kernel's
CODES = {name: code for code, name in sorted(CALLS.items(), reverse=True)}      # a name's lowest code
_page = []                 # the RunStatus the calls are written into, while a supervised run traces them


def trace_calls(status):
    """From now on every FMU call of this process is written into status.call (a RunStatus's), and
    the subsystem whose FMU is opened into status.opening; None: no longer."""
    _page[:] = [status] if status is not None else []
    from .build import loaded_libraries
    for lib in loaded_libraries():
        _point(lib)


def _point(lib):
    """Point a kernel library's fmi_call_now at the traced page (or back at its own slot)."""
    try:
        slot = ctypes.c_void_p.in_dll(lib, "fmi_call_now")
        idle = ctypes.addressof(FmiCallNow.in_dll(lib, "fmi_call_idle"))
    except ValueError:                     # a library that makes no FMU call
        return
    slot.value = ctypes.addressof(_page[0].call) if _page else idle


LOAD_HOOKS.append(_point)


def enter(instance, name):
    """The Python route's FMU call `name` of the component `instance` (None before it has one) begins."""
    if _page:
        now = _page[0].call
        now.instance, now.function = instance, CODES.get(name, 0)


def leave():
    """The Python route's call returned."""
    if _page:
        _page[0].call.function = 0


def traced(fn, instance, name):
    """fn, an FMU function the Python route calls, writing itself as the call in progress while calls
    are traced (else fn itself): two stores before the call, one after."""
    if not _page:
        return fn
    now, code = _page[0].call, CODES.get(name, 0)

    def call(*args):
        now.instance, now.function = instance, code
        status = fn(*args)
        now.function = 0
        return status
    return call


def opening(name):
    """The set-up opens the FMU of subsystem `name` now."""
    if _page:
        _page[0].opening = name.encode("utf-8", "replace")[:63]


def call_now(status):
    """(instance, call name, opening) of the call in progress a RunStatus records; the call is "" when none."""
    now = status.call
    return now.instance or 0, CALLS.get(now.function, ""), status.opening.decode("utf-8", "replace")
