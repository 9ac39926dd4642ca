"""ctypes binding of kernel/c/guard.c: fatal signals, exit() and freeze requests of a supervised run's
process recorded in a GuardFault (which may live in memory another process reads), the faulting
thread parked so a rescue thread can write what was computed (wavecosim/run/containment.py)."""
import ctypes
import signal

from .build import kernel_library

FRAMES = 48                       # guard.c GUARD_FRAMES
KINDS = ("none", "signal", "exit", "frozen")


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
