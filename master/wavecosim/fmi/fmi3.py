"""What an FMI 3.0 co-simulation FMU needs beyond the FMI 2 wrapper (wavecosim/fmi/fmu.py): instantiation,
typed setters, and fmi2-signature calls in front of its fmi3 functions.

The calls keep the fmi2 contract the masters and the C kernel are written against: `component` is
a Shim (the struct of kernel/c/fmi3shim.c, mirrored here), the C path calls the shim's
functions in the kernel library libfmi3shim.so, the Python path calls the FMU's own fmi3 functions through
the same struct's out-arguments. A doStep that asks to terminate the simulation or returned early
becomes an Error status, and `failure` says which.
"""
import ctypes

from fmpy import platform_tuple, sharedLibraryExtension
from fmpy.fmi3 import FMU3Slave

from ..errors import FmuError
from ..kernel.abi import mirrors
from ..kernel.build import kernel_library
from .values import is_number

PLATFORM = platform_tuple               # binaries/x86_64-linux/
# fmi2 name (what callers ask for) -> (fmi3 function, fmi3shim.c function), in Fmi3Shim's field order
FUNCTIONS = {"fmi2GetFMUstate": ("fmi3GetFMUState", "fmi3shim_getFMUstate"),
             "fmi2SetFMUstate": ("fmi3SetFMUState", "fmi3shim_setFMUstate"),
             "fmi2FreeFMUstate": ("fmi3FreeFMUState", "fmi3shim_freeFMUstate"),
             "fmi2SetReal": ("fmi3SetFloat64", "fmi3shim_setReal"),
             "fmi2DoStep": ("fmi3DoStep", "fmi3shim_doStep"),
             "fmi2GetReal": ("fmi3GetFloat64", "fmi3shim_getReal")}
_OUT = ("eventHandlingNeeded", "terminateSimulation", "earlyReturn", "lastSuccessfulTime")


class BinaryError(FmuError):
    """An FMU's shared library that does not load: the FMU's fault, not the scenario's."""


def load_binary(slave_class, fmu, model_identifier):
    """fmpy's slave (slave_class) of `fmu`, its binary loaded; a binary that does not load (not a shared
    library, a missing dependency) is an FmuError naming it and the loader's reason."""
    try:
        return slave_class(guid=fmu.description.guid, unzipDirectory=str(fmu.folder),
                           modelIdentifier=model_identifier, instanceName=fmu.name)
    except Exception as exc:                    # fmpy raises a bare Exception for a library that does not load
        if not str(exc).startswith("Failed to load shared library"):
            raise
        reason = str(exc).rsplit(": ", 1)[-1].strip()
        raise BinaryError(f"{fmu.name}: its binary {model_identifier}{sharedLibraryExtension} does not load ({reason})",
                          subsystem=fmu.name) from None


@mirrors("fmi3shim", "Fmi3Shim")
class Shim(ctypes.Structure):
    """kernel/c/fmi3shim.c, Fmi3Shim: the instance, its fmi3 functions, the last doStep's out-arguments."""
    _fields_ = [("instance", ctypes.c_void_p), *[(FUNCTIONS[k][0], ctypes.c_void_p) for k in FUNCTIONS],
                ("eventHandlingNeeded", ctypes.c_bool), ("terminateSimulation", ctypes.c_bool),
                ("earlyReturn", ctypes.c_bool), ("lastSuccessfulTime", ctypes.c_double)]


def _whole_in(bits, signed):
    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    return lambda v: isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi


def setters(is_number):
    """FMI 3 type -> (FMU3Slave setter, (accepts the YAML value, converts it)); integers range-checked."""
    table = {"Float64": ("setFloat64", (is_number, float)), "Float32": ("setFloat32", (is_number, float)),
             "Enumeration": ("setInt64", (_whole_in(64, True), int)),
             "Boolean": ("setBoolean", (lambda v: isinstance(v, bool), bool)),
             "String": ("setString", (lambda v: isinstance(v, str), str))}
    for bits in (8, 16, 32, 64):
        table[f"Int{bits}"] = (f"setInt{bits}", (_whole_in(bits, True), int))
        table[f"UInt{bits}"] = (f"setUInt{bits}", (_whole_in(bits, False), int))
    return table


class Fmi3:
    """The FMI 3.0 side of one Fmu: its FMU3Slave, its shim, and the calls in fmi2 form."""
    interface = "coSimulation"
    slave_class = FMU3Slave
    prefix = "fmi3"
    real = "Float64"
    platform = PLATFORM
    setters = setters(is_number)
    access = {**{t: t for t in ("Float64", "Float32", "Boolean", "String", "Binary")},
              **{f"{sign}Int{bits}": f"{sign}Int{bits}" for sign in ("", "U") for bits in (8, 16, 32, 64)},
              "Enumeration": "Int64"}     # FMI type -> the get/set pair of FMU3Slave that carries it
    enumeration_bits = 64

    def __init__(self, fmu, model_identifier, slave=None):
        """A new instance through fmpy's FMU3Slave, or through `slave`, a copy of another instance's
        (the binary already loaded: `borrowed`)."""
        def log(env, status, category, message):
            fmu.messages.append((status, message.decode("utf-8", "replace") if message else ""))
        self.borrowed = slave is not None
        self.slave = slave or load_binary(FMU3Slave, fmu, model_identifier)
        fmu.checked(self.slave.instantiate, "fmi3InstantiateCoSimulation", logMessage=log)
        self.shim = Shim(self.slave.component, *[self.address(FUNCTIONS[k][0]) for k in FUNCTIONS])
        self.component = ctypes.addressof(self.shim)
        self._shim_lib = None

    def address(self, fname):
        """Address of one of the FMU's fmi3 functions; None if it does not export it."""
        try:
            return ctypes.cast(self.slave.dll[fname], ctypes.c_void_p).value
        except AttributeError:
            return None

    def setup_experiment(self, fmu, start_time, tolerance):
        """FMI 3 has no fmi2SetupExperiment: start time and tolerance go to enter_initialization."""

    def enter_initialization(self, fmu, start_time, tolerance):
        fmu.checked(self.slave.enterInitializationMode, "fmi3EnterInitializationMode", tolerance=tolerance,
                    startTime=start_time)

    def get_real(self, vrs):
        return self.slave.getFloat64(vrs)

    def set_real(self, vrs, values):
        self.slave.setFloat64(vrs, values)

    def free_state(self, handle):
        self.slave.fmi3FreeFMUState(self.slave.component, ctypes.byref(handle))

    def raw_function(self, fname):
        """A Python callable with the fmi2 signature of `fname`, taking `component` first; as that is
        this FMU's own shim, it calls the instance's fmi3 function directly (no argtypes: callers
        pass pre-converted arguments)."""
        fn, inst = self.slave.dll[FUNCTIONS[fname][0]], ctypes.c_void_p(self.slave.component)
        if fname in ("fmi2SetReal", "fmi2GetReal"):
            return lambda comp, vr, n, values: fn(inst, vr, n, values, n)
        if fname == "fmi2DoStep":
            return self._do_step(fn, inst)
        return lambda comp, *args: fn(inst, *args)

    def _do_step(self, fn, inst):
        shim = self.shim
        out = [ctypes.byref(shim, getattr(Shim, name).offset) for name in _OUT]
        flags = (ctypes.c_bool(False), ctypes.c_bool(True))

        def do_step(comp, t, h, no_set_prior):
            status = fn(inst, t, h, flags[bool(no_set_prior)], *out)
            return 3 if status <= 1 and (shim.terminateSimulation or shim.earlyReturn) else status
        return do_step

    def function_pointer(self, fname):
        """Address of fmi3shim.c's fmi2-signature function for `fname` (it takes `component`);
        AttributeError, as for FMI 2, when the FMU does not export the fmi3 function behind it."""
        if getattr(self.shim, FUNCTIONS[fname][0]) is None:
            raise AttributeError(f"{FUNCTIONS[fname][0]} is not exported")
        if self._shim_lib is None:
            self._shim_lib = kernel_library("fmi3shim", "the FMI 3 shim")
        return ctypes.cast(self._shim_lib[FUNCTIONS[fname][1]], ctypes.c_void_p).value

    @staticmethod
    def name(fname):
        """The fmi3 function called for an fmi2 name."""
        return FUNCTIONS.get(fname, (fname,))[0]

    def fmu_status(self, fname, status):
        """The status the FMU itself returned: a doStep the shim reports as Error because it asked to
        terminate or returned early was OK or Warning in the FMU (it may still be terminated)."""
        if fname == "fmi2DoStep" and status == 3 and (self.shim.terminateSimulation or self.shim.earlyReturn):
            return 1
        return status

    def asked_to_end(self, fmu, status):
        """The lastSuccessfulTime of a doStep that set terminateSimulation, else None."""
        return self.shim.lastSuccessfulTime if self.shim.terminateSimulation else None

    def failure(self, fname, status_text):
        """(function name, what happened) for a call in fmi2 form that returned an error status."""
        name, shim = self.name(fname), self.shim
        if fname == "fmi2DoStep" and (shim.terminateSimulation or shim.earlyReturn):
            flag = "terminateSimulation" if shim.terminateSimulation else "earlyReturn"
            return name, f"set {flag} (last successful time {shim.lastSuccessfulTime:.6g})"
        return name, f"returned {status_text}"
