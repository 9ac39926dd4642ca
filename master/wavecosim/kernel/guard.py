"""ctypes binding of kernel/c/guard.c: fatal signals, exit() and freeze requests of a supervised run's
process recorded in a GuardFault (which may live in memory another process reads), the faulting
thread parked so a rescue thread can write what was computed (wavecosim/run/containment.py); and
the other process-level calls a supervised run makes (the parent's death, an exception raised in the
main thread, the FMU binaries mapped into the process)."""
import ctypes
import os
import signal
import threading
from pathlib import Path

from .abi import mirrors
from .build import kernel_library
from .fmicall import FmiCallNow

FRAMES = 48                       # guard.c GUARD_FRAMES
KINDS = ("none", "signal", "exit", "frozen")
_PR_SET_PDEATHSIG = 1


@mirrors("guard", "GuardFault")
class GuardFault(ctypes.Structure):
    """guard.c's record of the first fault: kind (KINDS), signal, code (si_code or exit status),
    the faulting thread, whether it parked (rescuable) and its stack's code addresses."""
    _fields_ = [("kind", ctypes.c_int), ("signal", ctypes.c_int), ("code", ctypes.c_int), ("thread", ctypes.c_int),
                ("main_thread", ctypes.c_int), ("rescuable", ctypes.c_int), ("frames", ctypes.c_int),
                ("declined", ctypes.c_int), ("address", ctypes.c_void_p), ("pc", ctypes.c_void_p * FRAMES)]

    def summary(self):
        """The record as plain data (None without a fault)."""
        if not self.kind:
            return None
        return {"kind": KINDS[self.kind], "signal": signal_name(self.signal), "code": self.code,
                "main_thread": bool(self.main_thread), "rescuable": bool(self.rescuable),
                "address": self.address or 0, "pc": [p or 0 for p in self.pc[:self.frames]]}


@mirrors("guard", "RunStatus")
class RunStatus(ctypes.Structure):
    """guard.c's RunStatus: the page a supervised run's parent and child share (run/channel.py)."""
    _fields_ = [("magic", ctypes.c_uint32), ("state", ctypes.c_int32), ("exit_code", ctypes.c_int32),
                ("request", ctypes.c_int32), ("pid", ctypes.c_int32), ("spare", ctypes.c_int32),
                ("heartbeat", ctypes.c_double), ("call", FmiCallNow), ("opening", ctypes.c_char * 64),
                ("fault", GuardFault)]


def signal_name(number):
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}" if number else ""


def _library():
    lib = kernel_library("guard", "containment")
    if not hasattr(lib, "_guard_ready"):
        lib.guard_arm.argtypes = [ctypes.POINTER(GuardFault), ctypes.c_int]
        lib.guard_disarm.restype = None
        lib._guard_ready = True
    return lib


def require():
    """Load the guard library now: a supervised run calls this before it forks, so a library that is
    neither in the package nor buildable is the parent's one-line FmuError."""
    _library()


def arm(fault, notify_fd):
    """Hold the process's faults from now on (call from the main thread): `fault` is a GuardFault the
    handlers fill, `notify_fd` the write end of the rescue pipe. Raises OSError if it cannot."""
    if _library().guard_arm(ctypes.byref(fault), notify_fd):
        raise OSError("the fatal-signal handlers could not be installed")


def disarm():
    """Faults and exit() are the process's own again."""
    _library().guard_disarm()


def freeze_main():
    """Ask the main thread to park if it is inside a foreign call (see GuardFault.declined)."""
    return _library().guard_freeze_main() == 0


def freeze_signal():
    return _library().guard_freeze_signal()


def claim_frozen():
    """Record a freeze the main thread did not take (its signal blocked, ignored or handled by an FMU)
    and wake the rescue; False when a fault was recorded before."""
    return _library().guard_claim_frozen() == 1


def die_with_parent(signum):
    """This process gets `signum` when its parent dies (Linux prctl PR_SET_PDEATHSIG; elsewhere nothing
    happens)."""
    try:
        ctypes.CDLL(None).prctl(_PR_SET_PDEATHSIG, signum)
    except (AttributeError, OSError):
        pass


def raise_in_main(exc_class):
    """Raise exc_class in the main thread at its next Python instruction."""
    ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(threading.main_thread().ident),
                                               ctypes.py_object(exc_class))


def fmu_libraries(entries):
    """[{path, ranges, entries}] of every FMU binary mapped into this process (a shared library under
    a `binaries/` folder): its address ranges (from /proc/self/maps) and the addresses of those of the
    function names `entries` it exports."""
    found = {}
    try:
        lines = Path("/proc/self/maps").read_text().splitlines()
    except OSError:
        return []
    for line in lines:
        fields = line.split(None, 5)
        if len(fields) < 6 or "/binaries/" not in fields[5] or ".so" not in fields[5]:
            continue
        lo, hi = (int(x, 16) for x in fields[0].split("-"))
        found.setdefault(fields[5], []).append([lo, hi])
    return [{"path": path, "ranges": ranges, "entries": _entries(path, entries)} for path, ranges in found.items()]


def _entries(path, names):
    try:
        lib = ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_LAZY)
    except OSError:
        return {}
    out = {}
    for name in names:
        try:
            out[name] = ctypes.cast(getattr(lib, name), ctypes.c_void_p).value
        except AttributeError:
            pass
    return out
