"""Thin wrapper over one FMI 2.0 or 3.0 co-simulation FMU instance (loaded by fmpy).

Keeps FMI names, converts arguments, turns bad statuses into FmuError carrying the FMU's own
log message, and exposes the raw C function pointers for the fast path, all in fmi2 form; the
FMI 3 specifics (instantiation, typed setters, the fmi2-signature shim) live in wavecosim/fmi/fmi3.py.
Only kernel/ and fmi/ import ctypes; the parts above pass C values made by wavecosim.kernel.cvalues.
"""
import atexit
import contextlib
import copy
import ctypes
import itertools
import math
import shutil
import tempfile
import weakref
import zipfile
from pathlib import Path

import numpy as np
from fmpy import platform as fmpy_platform
from fmpy import read_model_description, sharedLibraryExtension
from fmpy.model_description import ValidationError
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2StepFinishedTYPE, fmi2Terminated
from fmpy.fmi2 import fmi2LastSuccessfulTime

from ..errors import FmuError
from ..kernel import fmicall
from ..kernel.build import helper_library
from ..kernel.contract import names
from .me import DEFAULT_TOLERANCE, ModelExchange
from .messages import MessageLog, cut
from .fmi3 import load_binary
from .sources import provide_binary
from .unpack import regular_file, unpack
from .values import BOOLEAN, REAL, as_python, category, integer_range, is_int32, is_number

_STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}
WARNING = 1
# An FMU's call counters (Fmu.calls), in the order of kernel/c/fmicall.h's enum FmiCall, which the
# kernel's calls count in: doSteps, states saved and restored, value gets and sets (one each per call).
CALLS = tuple("doStep" if kind == "do_step" else kind for kind in names("fmicall.h", "FmiCall", "FMI_CALL_"))
_VALUE_TYPES = ("Real", "Integer", "Boolean", "String", "Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16",
                "Int32", "UInt32", "Int64", "UInt64", "Binary")
COUNTED = {**{f"fmi{v}DoStep": 0 for v in "23"}, "fmi2GetFMUstate": 1, "fmi3GetFMUState": 1, "fmi2SetFMUstate": 2,
           "fmi3SetFMUState": 2, **{f"fmi{v}{verb}{kind}": CALLS.index(verb.lower()) for v in "23"
                                    for verb in ("Get", "Set") for kind in _VALUE_TYPES}}


def fails(status):
    """Whether an fmi2 status fails the call: worse than fmi2Warning (as the kernel's fmi_fails, kernel/c/fmicall.h)."""
    return status > WARNING
_libc = ctypes.CDLL(None)
_libc.calloc.restype = ctypes.c_void_p
_libc.calloc.argtypes = [ctypes.c_size_t, ctypes.c_size_t]
_libc.free.argtypes = [ctypes.c_void_p]


_message_logs = weakref.WeakValueDictionary()     # componentEnvironment -> the MessageLog of an FMU instance
_environments = itertools.count(1)


def _to_log(env, instance, status, category, message):
    """One message, formatted by kernel/c/fmilog.c, into the log of the instance its environment names."""
    log = _message_logs.get(env or 0)
    if log is not None:
        log.append((status, message.decode("utf-8", "replace") if message else ""))


_SINK = fmi2CallbackLoggerTYPE(_to_log)
_formatter = []


def message_logger(messages):
    """(logger, componentEnvironment) of a new FMI 2 instance whose messages go to `messages`: the C
    logger that formats the message with its printf arguments, as the FMI logger's contract says
    (kernel/c/fmilog.c); without a C compiler, a Python logger that keeps the format as it is."""
    if not _formatter:
        lib = helper_library("fmilog")
        if lib is not None:
            lib.fmilog_set_sink(ctypes.cast(_SINK, ctypes.c_void_p))
        _formatter.append(lib and ctypes.cast(lib.fmilog_logger, fmi2CallbackLoggerTYPE))
    if _formatter[0] is None:
        return fmi2CallbackLoggerTYPE(lambda env, instance, status, category, message: messages.append(
            (status, message.decode("utf-8", "replace") if message else ""))), None
    environment = next(_environments)
    _message_logs[environment] = messages
    return _formatter[0], environment


def extract_fmu(path: Path) -> Path:
    """Extract an FMU into a fresh temporary folder (removed at exit), refusing members that would
    escape it and an archive that unpacks to too much (fmi/unpack.py)."""
    path = Path(path)
    if regular_file(path, FmuError) is None:
        raise FmuError(f"FMU file not found: {path}")
    if not zipfile.is_zipfile(path):
        raise FmuError(f"{path} is not an FMU (not a zip archive)")
    target = Path(tempfile.mkdtemp(prefix="wavecosim-fmu-"))
    atexit.register(shutil.rmtree, target, True)
    try:
        with zipfile.ZipFile(path) as z:
            if "modelDescription.xml" not in z.namelist():
                raise FmuError(f"{path} is not an FMU (no modelDescription.xml)")
        unpack(path, target, FmuError)
    except (zipfile.BadZipFile, OSError) as exc:
        shutil.rmtree(target, ignore_errors=True)
        raise FmuError(f"{path}: cannot extract FMU: {exc}") from None
    except FmuError:
        shutil.rmtree(target, ignore_errors=True)
        raise
    return target


def shared_folder(path: Path, pool):
    """(key, folder): one extraction per FMU file for all its instances opened with the same pool
    (a dict the caller owns, e.g. one per scene), so they share one loaded binary and N instances
    of one FMU cost no more code in the caches than one; pool None: a folder of its own."""
    path = Path(path)
    if pool is None or not path.is_file():
        return None, extract_fmu(path)
    st = path.resolve().stat()
    key = (str(path.resolve()), st.st_mtime_ns, st.st_size)
    entry = pool.get(key)
    if entry is None:
        entry = pool[key] = [extract_fmu(path), 0]
    entry[1] += 1
    return key, entry[0]


def release_folder(pool, key, folder):
    """One instance less on a shared extraction; the folder goes with the last one."""
    entry = pool.get(key) if pool is not None else None
    if entry is not None and entry[0] == folder:
        entry[1] -= 1
        if entry[1] > 0:
            return
        del pool[key]
    shutil.rmtree(folder, ignore_errors=True)


def check_version(path, folder) -> str:
    """FMI 2.0 or 3.0, read from modelDescription.xml's root before anything else parses it."""
    import xml.etree.ElementTree as ET
    try:
        version = ET.parse(folder / "modelDescription.xml").getroot().get("fmiVersion", "?")
    except ET.ParseError as exc:
        raise FmuError(f"{path}: cannot read modelDescription.xml: {exc}") from None
    if version != "2.0" and not version.startswith("3."):
        raise FmuError(f"{path.name} is an FMI {version} FMU; wavecosim runs FMI 2.0 and 3.0 co-simulation FMUs")
    return version


def check_runnable(path, folder, description, platform=fmpy_platform, interface="coSimulation"):
    """One line naming the FMU and the reason when this build cannot run it: no co-simulation
    interface (nor, in FMI 2, a model-exchange one), no binary for this platform (binaries/<platform>:
    linux64 in FMI 2, x86_64-linux in 3), or a binary for it whose name is not the modelIdentifier's."""
    cs = getattr(description, interface)
    if cs is None:
        others = [k for k in ("modelExchange", "scheduledExecution") if getattr(description, k, None) is not None]
        raise FmuError(f"{path}: the FMU has no co-simulation interface" + (f" (it has {', '.join(others)} only)"
                                                                               if others else ""))
    name = f"{cs.modelIdentifier}{sharedLibraryExtension}"
    binary = folder / "binaries" / platform / name
    if binary.exists():
        return
    others = sorted(p.name for p in binary.parent.glob(f"*{sharedLibraryExtension}")) if binary.parent.is_dir() else []
    if others:
        raise FmuError(f"{path.name}: binaries/{platform} holds {', '.join(others)}, but the modelIdentifier "
                       f"{cs.modelIdentifier!r} asks for {name}: the library must be named after the modelIdentifier")
    have = sorted(p.name for p in (folder / "binaries").iterdir()) if (folder / "binaries").is_dir() else []
    raise FmuError(f"{path.name} has no binary for this platform ({platform}; it has: {', '.join(have) or 'none'})")


_schema_checked = {}


def schema_note(path, folder, version):
    """A one-line warning when modelDescription.xml fails its FMI schema (fmpy reads it all the same
    without validation, as many tools' files need), else None; checked once per FMU file."""
    st = path.resolve().stat()
    key = (str(path.resolve()), st.st_mtime_ns, st.st_size)
    if key not in _schema_checked:
        note = None
        try:
            read_model_description(str(folder), validate=True)
        except ValidationError as exc:
            first = exc.problems[0] if exc.problems else str(exc).splitlines()[0]
            more = f" and {len(exc.problems) - 1} more" if len(exc.problems) > 1 else ""
            note = (f"{path.name}: modelDescription.xml does not conform to the FMI {version} schema ({first}"
                    f"{more}); read without validation, as fmpy's validate=False reads it")
        except Exception:                  # not a schema problem: the unvalidated read reports it
            pass
        _schema_checked[key] = note
    return _schema_checked[key]


# FMI type -> (FMU2Slave setter, (accepts the YAML value, converts it))
SETTERS = {
    "Real": ("setReal", (is_number, float)),
    "Integer": ("setInteger", (is_int32, int)),
    "Enumeration": ("setInteger", (is_int32, int)),
    "Boolean": ("setBoolean", (lambda v: isinstance(v, bool), bool)),
    "String": ("setString", (lambda v: isinstance(v, str), str)),
}


class Fmi2:
    """The FMI 2.0 side of one Fmu: its FMU2Slave; the calls are the FMU's own fmi2 functions."""
    interface = "coSimulation"
    slave_class = FMU2Slave
    prefix = "fmi2"
    real = "Real"
    platform = fmpy_platform
    setters = SETTERS
    access = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean",
              "String": "String"}             # FMI type -> the get/set pair of FMU2Slave that carries it
    enumeration_bits = 32

    def __init__(self, fmu, model_identifier, slave=None):
        """A new instance through fmpy's FMU2Slave, or through `slave`, a copy of another instance's
        (the binary already loaded, its functions looked up: `borrowed`)."""
        self._callbacks = self._make_callbacks(fmu.messages)
        self.borrowed = slave is not None
        self.slave = slave or load_binary(FMU2Slave, fmu, model_identifier)
        fmu.checked(self.slave.instantiate, "fmi2Instantiate", callbacks=self._callbacks)
        self.component = self.slave.component

    def _make_callbacks(self, messages):
        cb = fmi2CallbackFunctions()
        self._logger_ref, environment = message_logger(messages)
        cb.logger = self._logger_ref
        self._alloc_ref = fmi2CallbackAllocateMemoryTYPE(_libc.calloc)
        self._free_ref = fmi2CallbackFreeMemoryTYPE(_libc.free)
        cb.allocateMemory = self._alloc_ref
        cb.freeMemory = self._free_ref
        cb.stepFinished = fmi2StepFinishedTYPE()
        cb.componentEnvironment = environment
        return cb

    def setup_experiment(self, fmu, start_time, tolerance):
        fmu.checked(self.slave.setupExperiment, "fmi2SetupExperiment", tolerance=tolerance, startTime=start_time)

    def enter_initialization(self, fmu, start_time, tolerance):
        fmu.checked(self.slave.enterInitializationMode, "fmi2EnterInitializationMode")

    def get_real(self, vrs):
        return self.slave.getReal(vrs)

    def set_real(self, vrs, values):
        self.slave.setReal(vrs, values)

    def free_state(self, handle):
        self.slave.fmi2FreeFMUstate(self.component, ctypes.byref(handle))

    def raw_function(self, fname):
        return self.slave.dll[fname]

    def function_pointer(self, fname):
        return ctypes.cast(self.slave.dll[fname], ctypes.c_void_p).value

    @staticmethod
    def name(fname):
        """The FMU's function called for an fmi2 name (itself)."""
        return fname

    def failure(self, fname, status_text):
        """(function name, what happened) for a call that returned an error status."""
        return fname, f"returned {status_text}"

    def fmu_status(self, fname, status):
        """The status the FMU itself returned for a call in fmi2 form that gave `status` (itself)."""
        return status

    def asked_to_end(self, fmu, status):
        """fmi2Discard with fmi2GetBooleanStatus(fmi2Terminated) true: the fmi2LastSuccessfulTime."""
        try:
            if status != 2 or not self.slave.getBooleanStatus(fmi2Terminated):
                return None
        except Exception:                  # an FMU without the call: an ordinary Discard
            return None
        try:
            return float(self.slave.getRealStatus(fmi2LastSuccessfulTime))
        except Exception:
            return math.nan


class ModelExchange2(ModelExchange, Fmi2):
    """An FMI 2.0 FMU with model exchange only, stepped as co-simulation (wavecosim/fmi/me.py)."""


_pointer_hook = None       # hook(name, component, fname, lookup) -> the address function_pointer gives (see interposed)


@contextlib.contextmanager
def interposed(hook):
    """Within the block, Fmu.function_pointer(fname) gives hook(name, component, fname, lookup) (the
    instance's name and fmi2Component) instead of the FMU's own address lookup(fname): the one seam through which a tool stands between the C kernel and an
    FMU's functions (the bench's floor records the kernel's FMU calls so, bench/real_fmus.py). The
    kernel takes its pointers when a master opens its route, so the master must open in the block;
    None: no hook. Not thread-safe: one block at a time."""
    global _pointer_hook
    previous, _pointer_hook = _pointer_hook, hook
    try:
        yield
    finally:
        _pointer_hook = previous


def _settable_in_initialization(v):
    """Whether a variable may be set in initialization mode (fmpy's rule: an input, a tunable
    non-parameter, or a non-constant variable with initial = exact; an FMI 3 structural parameter
    only in configuration mode)."""
    if v.causality == "structuralParameter":
        return False
    return v.causality == "input" or (v.causality != "parameter" and v.variability == "tunable") \
        or (v.variability != "constant" and v.initial == "exact")


def set_up_tolerance(description, given, at_most, model_exchange):
    """The tolerance an FMU is set up with: `given`, else its DefaultExperiment's, else none (under
    `at_most`, a model-exchange FMU's solver's own, DEFAULT_TOLERANCE); at most `at_most`."""
    experiment = description.defaultExperiment
    tolerance = given
    if tolerance is None and experiment is not None and experiment.tolerance is not None:
        tolerance = float(experiment.tolerance)
    if tolerance is None and model_exchange and at_most is not None:
        tolerance = DEFAULT_TOLERANCE
    return tolerance if tolerance is None or at_most is None else min(tolerance, at_most)


class Fmu:
    """One instantiated, initialized FMU (FMI 2.0 or 3.0); `name` is the subsystem name used in messages."""

    def __init__(self, path, name, values=None, integer_values=None, start_time=0.0, optional=(), pool=None,
                 tolerance=None, initialize=None, like=None, hold=False, tolerance_at_most=None):
        """Load, instantiate and initialize; `values` (and `integer_values`) are start values and
        parameters by name, each set with the FMI type its variable declares (Real, Integer,
        Enumeration, Boolean, String; in FMI 3 also Float32 and every IntN/UIntN); names in
        `optional` are skipped when the FMU lacks them. Instances opened with one `pool` share the
        extracted FMU (see shared_folder). The experiment starts at `start_time` with `tolerance`
        (None: the DefaultExperiment's, or none when it gives none; at most `tolerance_at_most`), as fmpy
        sets it up;
        `initialize(fmu)`, when given, runs in initialization mode (e.g. to set inputs). `like`, an Fmu
        of the same file, lends its parsed modelDescription, and its loaded binary when both are in one
        folder (see twin). `hold`: the instance stays in initialization mode until
        end_initialization() (a scene settles its connected inputs first, core/signals.py)."""
        self.path, self.name = Path(path), name
        self.calls = (ctypes.c_long * len(CALLS))()     # its calls that went through (CALLS), the one count of them
        fmicall.opening(name)
        self._pool = pool
        self._key, self.folder = shared_folder(self.path, pool)
        if like is not None:
            self.fmi_version, self.description, self.notes = like.fmi_version, like.description, []
        else:
            self._read_description()
        binding = Fmi2
        if self.fmi_version != "2.0":
            from .fmi3 import Fmi3 as binding
        elif self.description.coSimulation is None and self.description.modelExchange is not None:
            binding = ModelExchange2
        cs = getattr(self.description, binding.interface)
        if cs is not None and like is None:
            needed = [f for f in dir(binding.slave_class) if f.startswith(binding.prefix)]     # what fmpy loads
            provide_binary(self.path, self.folder, self.description, cs, binding.platform, needed)
        if like is None:
            check_runnable(self.path, self.folder, self.description, binding.platform, binding.interface)
        if cs.canBeInstantiatedOnlyOncePerProcess:       # its own copy of the binary for each instance
            release_folder(pool, self._key, self.folder)
            self._key, self.folder = None, extract_fmu(self.path)
        self.can_save_state = bool(cs.canGetAndSetFMUstate)
        self.variable_steps = bool(getattr(cs, "canHandleVariableCommunicationStepSize", True))
        self.variables = like.variables if like is not None else {v.name: v for v in self.description.modelVariables}
        self.messages = MessageLog(name)        # bounded: the last few, and the run's log file
        self.phase = "instantiated"        # of the FMI state machine: instantiated, initialization, step, error, fatal
        try:
            self._fmi = self._bind(binding, cs.modelIdentifier, like)
        except AttributeError as exc:                 # the library lacks an FMI function fmpy loads
            self.close()
            raise FmuError(f"{self.path.name}: its binary cannot be used: {exc}") from None
        except FmuError:
            self.close()
            raise
        self.component = self._fmi.component
        drop = [k for k in optional if k not in self.variables]
        self.given = {k: v for k, v in {**(values or {}), **(integer_values or {})}.items() if k not in drop}
        tolerance = set_up_tolerance(self.description, tolerance, tolerance_at_most, binding is ModelExchange2)
        self.start_time, self.tolerance, self.initialize = start_time, tolerance, initialize
        try:
            self._setup(self.given, initialize)
            if not hold:
                self.end_initialization()
        except BaseException:
            self.close()                   # an instance that failed to initialize is freed, not leaked
            raise

    def end_initialization(self):
        """Leave initialization mode (fmi2ExitInitializationMode) into the step phase."""
        self.checked(self._fmi.slave.exitInitializationMode, f"{self._fmi.prefix}ExitInitializationMode")
        self.phase = "step"

    def _read_description(self):
        """fmiVersion, the parsed modelDescription.xml and the notes on it."""
        self.fmi_version = check_version(self.path, self.folder)
        try:
            self.description = read_model_description(str(self.folder), validate=False)
        except Exception as exc:  # fmpy raises bare exceptions for malformed XML
            raise FmuError(f"{self.path}: cannot read modelDescription.xml: {exc}") from None
        self.notes = [note] if (note := schema_note(self.path, self.folder, self.fmi_version)) else []

    def _bind(self, binding, model_identifier, like):
        """The binding of a new instance: through a copy of `like`'s fmpy slave when both are
        co-simulation instances in one folder (the binary already loaded), else its own."""
        if like is None or like.folder != self.folder or like._fmi is None or binding.interface != "coSimulation":
            fmicall.enter(None, fmicall.LOAD)
            try:
                return binding(self, model_identifier)
            finally:
                fmicall.leave()
        slave = copy.copy(like._fmi.slave)
        slave.instanceName, slave.component = self.name, None
        return binding(self, model_identifier, slave)

    @property
    def once_per_process(self):
        """The FMU allows one instance per process: each instance gets its own copy of the binary."""
        return bool(getattr(self.description, self._fmi.interface).canBeInstantiatedOnlyOncePerProcess)

    def twin(self, name, own_copy=False):
        """Another instance of this FMU with the same start values, parameters and experiment, in the
        same loaded binary (this one's pool), or in a copy of its own (own_copy, or no pool), for probes
        (core/quirks.py)."""
        pool = {} if own_copy or self._pool is None else self._pool
        return Fmu(self.path, name, self.given, start_time=self.start_time, pool=pool, tolerance=self.tolerance,
                   initialize=self.initialize, like=self)

    def last_message(self) -> str:
        """The FMU's last message, cut to a few hundred characters (for one-line errors)."""
        last = self.messages.last()
        return cut(last, 300) if last is not None else "no message from the FMU"

    def checked(self, call, fname, *args, **kwargs):
        """call(*args, **kwargs), an fmpy method; its exception becomes an FmuError with the FMU's message."""
        fmicall.enter(getattr(self, "component", None), fname)
        try:
            result = call(*args, **kwargs)
        except Exception as exc:
            self.note_status(getattr(exc, "status", 3))
            raise FmuError(f"{self.name}: {fname} failed: {self.last_message()}", subsystem=self.name) from exc
        finally:
            fmicall.leave()
        self.count(fname)
        return result

    def count(self, fname):
        """Count a call of `fname` (fmi2 or fmi3 name) that went through in `calls`, if it is one counted."""
        kind = COUNTED.get(fname)
        if kind is not None:
            self.calls[kind] += 1

    def calls_address(self):
        """The address of `calls`, where the C kernel counts the calls it makes (kernel/c/fmicall.h)."""
        return ctypes.addressof(self.calls)

    def note_status(self, status):
        """An error status moves the instance out of the state machine's step phase: after fmi2Error
        only state, get, reset and free calls are allowed, after fmi2Fatal none (close() obeys)."""
        if status >= 4:
            self.phase = "fatal"
        elif status == 3 and self.phase != "fatal":
            self.phase = "error"

    def _setup(self, given, initialize):
        """Set up the experiment, set the given values, enter initialization mode and set again those
        the standard lets be set there (fmpy's rule), then run `initialize`."""
        fmi, start_time = self._fmi, self.start_time
        fmi.setup_experiment(self, start_time, self.tolerance)
        by_type = {}
        for name, value in given.items():
            kind = self.scalar(name).type
            setter, convert = fmi.setters.get(kind, (None, None))
            if setter is None or not convert[0](value):
                raise FmuError(f"{self.name}: {name} is a {kind} variable of {self.path.name}; got {value!r}",
                               subsystem=self.name, variable=name)
            by_type.setdefault(setter, []).append((name, convert[1](value)))
        self._set_given(by_type, lambda v: True)
        fmi.enter_initialization(self, start_time, self.tolerance)
        self.phase = "initialization"
        self._set_given(by_type, _settable_in_initialization)
        if initialize is not None:
            initialize(self)

    def _set_given(self, by_type, settable):
        """Set the given values ({setter: [(name, value)]}) whose variable is `settable`."""
        fmi = self._fmi
        for setter, pairs in by_type.items():
            chosen = [(self.vr(name), value) for name, value in pairs if settable(self.variables[name])]
            if chosen:
                self.checked(getattr(fmi.slave, setter), f"{fmi.prefix}{setter[0].upper()}{setter[1:]}",
                             [vr for vr, _ in chosen], [value for _, value in chosen])

    def variable(self, name):
        if name not in self.variables:
            raise FmuError(f"{self.name}: the FMU {self.path.name} has no variable {name!r}", subsystem=self.name,
                           variable=name)
        return self.variables[name]

    def scalar(self, name):
        """The variable, refused in one line if it is an array (FMI 3 dimensions): only scalars are set and read."""
        v = self.variable(name)
        if getattr(v, "dimensions", None):
            raise FmuError(f"{self.name}: {name} is an array variable of {self.path.name}; wavecosim sets and "
                           f"reads scalar variables only", subsystem=self.name, variable=name)
        return v

    def vr(self, name) -> int:
        return self.variable(name).valueReference

    def vrs(self, names) -> np.ndarray:
        return np.array([self.vr(n) for n in names], dtype=np.uint32)

    @property
    def real_type(self):
        """The FMI type ports, readings and the raw fmi2GetReal exchange: Real (FMI 2), Float64 (FMI 3)."""
        return self._fmi.real

    def real_vrs(self, names) -> list:
        """Value references of scalar Real (FMI 2) or Float64 (FMI 3) variables, the types ports and
        readings exchange; another type is refused in one line."""
        for name in names:
            kind = self.scalar(name).type
            if kind != self._fmi.real:
                raise FmuError(f"{self.name}: {name} is a {kind} variable of {self.path.name}; a port or reading "
                               f"needs a {self._fmi.real}", subsystem=self.name, variable=name)
        return [self.vr(n) for n in names]

    def kind(self, name):
        """The FMI type of a scalar variable, refused in one line when wavecosim cannot carry it."""
        v = self.scalar(name)
        if v.type not in self._fmi.access:
            raise FmuError(f"{self.name}: {name} is a {v.type} variable of {self.path.name}; wavecosim carries "
                           f"{', '.join(self._fmi.access)}", subsystem=self.name, variable=name)
        return v.type

    def integer_range(self, fmi_type):
        """(lowest, highest) value of an integer type of this FMU's FMI version."""
        return integer_range(fmi_type, self._fmi.enumeration_bits)

    def get_values(self, fmi_type, vrs) -> list:
        """Values of variables of one FMI type as Python values (float, int, bool, str, bytes)."""
        kind, suffix = category(fmi_type), self._fmi.access[fmi_type]
        got = self.checked(getattr(self._fmi.slave, f"get{suffix}"), f"{self._fmi.prefix}Get{suffix}",
                           list(map(int, vrs)))
        return [as_python(kind, v) for v in got]

    def set_values(self, fmi_type, vrs, values):
        """Set variables of one FMI type from Python values (a Real must be finite)."""
        if category(fmi_type) == REAL:
            self._finite([float(v) for v in values])
        elif category(fmi_type) == BOOLEAN:
            values = [bool(v) for v in values]
        suffix = self._fmi.access[fmi_type]
        self.checked(getattr(self._fmi.slave, f"set{suffix}"), f"{self._fmi.prefix}Set{suffix}",
                     list(map(int, vrs)), list(values))

    def _finite(self, values):
        if not all(math.isfinite(v) for v in values):
            raise FmuError(f"{self.name}: refusing to set a non-finite input {values}", subsystem=self.name)

    # ---- the calls a master makes, status-checked ----
    def get_real(self, vrs) -> np.ndarray:
        return np.array(self.checked(self._fmi.get_real, self._fmi.name("fmi2GetReal"),
                                     list(map(int, vrs))))

    def set_real(self, vrs, values):
        values = [float(v) for v in values]
        self._finite(values)
        self.checked(self._fmi.set_real, self._fmi.name("fmi2SetReal"), list(map(int, vrs)), values)

    def free_state_handle(self, handle):
        """Free a saved state held in a ctypes FMU state handle (the frozen port map's x_i^n)."""
        self.checked(self._fmi.free_state, self._fmi.name("fmi2FreeFMUstate"), handle)

    @property
    def slave(self):
        """The fmpy FMU2Slave or FMU3Slave (for code that wants fmpy's own calls, e.g. the bench's plain loop)."""
        return self._fmi.slave

    def raw_function(self, fname):
        """A callable with the fmi2 signature of `fname` (e.g. "fmi2DoStep") taking `component` first:
        the FMU's own ctypes function for FMI 2, a wrapper of its fmi3 function for FMI 3 (wavecosim/fmi/fmi3.py).
        No argtypes: callers pass pre-converted arguments. In a supervised run each call is written as
        the call in progress (kernel/fmicall.py traced)."""
        return fmicall.traced(self._fmi.raw_function(fname), self.component, self._fmi.name(fname))

    def function_pointer(self, fname) -> int:
        """Address of a C function with the fmi2 signature of `fname` taking `component`, for the C fast
        path: the FMU's own for FMI 2, kernel/c/fmi3shim.c's for FMI 3 (or the hook's within `interposed`)."""
        if _pointer_hook is not None:
            return _pointer_hook(self.name, self.component, fname, self._fmi.function_pointer)
        return self._fmi.function_pointer(fname)

    def function_name(self, fname):
        """The FMU's own function behind an fmi2 name (fmi3SetFloat64 for fmi2SetReal in FMI 3)."""
        return self._fmi.name(fname)

    def asked_to_end(self, status):
        """None, or the time the FMU reached when a doStep that returned `status` is the FMU asking to
        end the simulation (its last successful time; NaN when it cannot say)."""
        return self._fmi.asked_to_end(self, status)

    def check(self, fname, status, step=None, time=None):
        """The one status check of a call in fmi2 form (`fname`): status_error raised when it fails,
        else the call counted."""
        if fails(status):
            raise self.status_error(fname, status, step, time)
        self.count(fname)

    def status_error(self, fname, status, step=None, time=None):
        """The FmuError for a call in fmi2 form (`fname`) that returned `status`."""
        where = "" if step is None else f" at step {step} (t = {time:.6g})"
        self.note_status(self._fmi.fmu_status(fname, status))
        shown, what = self._fmi.failure(fname, _STATUS.get(status, status))
        return FmuError(f"subsystem {self.name}: {shown} {what}{where}: {self.last_message()}",
                        subsystem=self.name, step=step, time=time)

    def free_state_allowed(self):
        """Whether fmi2FreeFMUstate may still be called (not after fmi2Fatal)."""
        return getattr(self, "phase", "fatal") != "fatal"

    def close(self):
        """Terminate (only from the step phase: not after an error) and free the instance (not after
        fatal), as the FMI state machine allows; then release the extracted folder."""
        fmi, self._fmi = getattr(self, "_fmi", None), None
        slave = getattr(fmi, "slave", None)
        phase = getattr(self, "phase", "fatal")
        free = slave.freeInstance if slave is not None and not getattr(fmi, "borrowed", False) else (
            lambda: getattr(slave, f"{fmi.prefix}FreeInstance")(slave.component))    # a borrowed binary stays loaded
        calls = ([slave.terminate] if phase == "step" else []) + ([free] if phase != "fatal" else [])
        for call in calls if slave is not None else ():
            try:
                call()
            except Exception:
                pass
        if getattr(self, "folder", None) is not None:
            release_folder(self._pool, self._key, self.folder)
            self.folder = None
