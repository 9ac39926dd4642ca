"""The bench's floor of a run (kernel/c/floor.c, the kernel library libfloor.so; used by bench/ only,
kept here because only kernel/ and fmi/ bind C): every FMU call the C kernel makes is recorded in
order through shims (`FloorRecorder.hook`, put between the kernel and the FMUs for one run with
fmi/fmu.py's `interposed`), then made again from C alone, with the same arguments, on freshly
instantiated FMUs (`replay`). Its time is what those FMU calls cost with nothing around them.
"""
import ctypes

from .build import kernel_library
from .drkernel import FMI_NAMES as NAMES, DRFunctions as FLFunctions       # floor.h: the kernel's table
from ..errors import FmuError


_lib = None


def library():
    global _lib
    if _lib is None:
        _lib = kernel_library("floor", "the floor's recorder")
    return _lib


class FloorRecorder:
    """Records the FMU calls the kernel makes while `hook` is the FMU layer's pointer hook and
    recording is on (start .. stop); `names` lists the FMU instances' names in the order they were
    first seen (the replay needs fresh instances of the same names)."""

    def __init__(self):
        self.lib = library()
        self.handle = self.lib.fl_create()
        if not self.handle:
            raise FmuError("the floor's recorder could not be created (out of memory)")
        self.shims = FLFunctions()
        self.lib.fl_shims(ctypes.byref(self.shims))
        self.names, self._seen = [], set()

    def hook(self, name, component, fname, lookup):
        """The pointer hook (fmi/fmu.py, interposed): the recording shim of fname for the FMU instance
        `name` (its fmi2Component), registered on first sight (the FMU's own function for a name it
        does not record)."""
        if fname not in NAMES:
            return lookup(fname)
        if component not in self._seen:
            table = FLFunctions(*[lookup(n) for n in NAMES])
            if self.lib.fl_register(self.handle, component, ctypes.byref(table)) < 0:
                raise FmuError("the floor's recorder takes at most 64 FMU instances")
            self._seen.add(component)
            self.names.append(name)
        return getattr(self.shims, FLFunctions._fields_[NAMES.index(fname)][0])

    def start(self):
        self.lib.fl_start(self.handle)

    def stop(self):
        self.lib.fl_stop()

    @property
    def calls(self):
        return self.lib.fl_calls(self.handle)

    def replay(self, instances):
        """Seconds the recorded calls take made again on fresh instances ({name: (fmi2Component,
        pointer(fmi2 name) -> address)})."""
        order = [instances[name] for name in self.names]
        comps = (ctypes.c_void_p * len(order))(*[comp for comp, _ in order])
        tables = (FLFunctions * len(order))(*[FLFunctions(*[pointer(n) for n in NAMES]) for _, pointer in order])
        failed = ctypes.c_int(-1)
        seconds = self.lib.fl_replay(self.handle, comps, tables, ctypes.byref(failed))
        if seconds < 0 or failed.value >= 0:
            raise FmuError(f"the floor's replay failed (call {failed.value} of {self.calls})")
        return seconds

    def close(self):
        if self.handle:
            self.lib.fl_destroy(self.handle)
            self.handle = None
