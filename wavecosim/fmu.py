"""Thin wrapper over one FMI 2.0 co-simulation FMU instance (loaded by fmpy).

Keeps FMI names, converts arguments, turns bad statuses into FmuError carrying the FMU's own
log message, and exposes the raw C function pointers for the fast path. Nothing above this
module imports ctypes except the hot paths (frozen_port_map.py, fast_path.py).
"""
import atexit
import ctypes
import math
import shutil
import tempfile
import zipfile
from pathlib import Path

import numpy as np
from fmpy import platform as fmpy_platform
from fmpy import read_model_description, sharedLibraryExtension
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2StepFinishedTYPE

from .errors import FmuError

_STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}
_libc = ctypes.CDLL(None)
_libc.calloc.restype = ctypes.c_void_p
_libc.calloc.argtypes = [ctypes.c_size_t, ctypes.c_size_t]
_libc.free.argtypes = [ctypes.c_void_p]


def extract_fmu(path: Path) -> Path:
    """Extract an FMU into a fresh temporary folder, refusing members that would escape it."""
    path = Path(path)
    if not path.exists():
        raise FmuError(f"FMU file not found: {path}")
    if not zipfile.is_zipfile(path):
        raise FmuError(f"{path} is not an FMU (not a zip archive)")
    target = Path(tempfile.mkdtemp(prefix="wavecosim-fmu-"))
    atexit.register(shutil.rmtree, target, True)
    try:
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
            if "modelDescription.xml" not in names:
                raise FmuError(f"{path} is not an FMU (no modelDescription.xml)")
            root = target.resolve()
            for member in names:
                dest = (target / member).resolve()
                if dest != root and root not in dest.parents:
                    raise FmuError(f"{path}: archive member {member!r} escapes the extraction folder")
            z.extractall(target)
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
    if pool is None or not path.exists():
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


def check_version(path, folder):
    """FMI 2.0 only, read from modelDescription.xml's root before anything else parses it."""
    import xml.etree.ElementTree as ET
    try:
        version = ET.parse(folder / "modelDescription.xml").getroot().get("fmiVersion", "?")
    except ET.ParseError as exc:
        raise FmuError(f"{path}: cannot read modelDescription.xml: {exc}") from None
    if version != "2.0":
        raise FmuError(f"{path.name} is an FMI {version} FMU; wavecosim runs FMI 2.0 co-simulation FMUs"
                       + (" (FMI 3.0 support is not built yet)" if version.startswith("3") else ""))


def check_runnable(path, folder, description):
    """One line naming the FMU and the reason when this build cannot run it: no co-simulation
    interface, or no binary for this platform."""
    cs = description.coSimulation
    if cs is None:
        raise FmuError(f"{path}: the FMU has no co-simulation interface")
    binary = folder / "binaries" / fmpy_platform / f"{cs.modelIdentifier}{sharedLibraryExtension}"
    if not binary.exists():
        have = sorted(p.name for p in (folder / "binaries").iterdir()) if (folder / "binaries").is_dir() else []
        raise FmuError(f"{path.name} has no binary for this platform ({fmpy_platform}; it has: "
                       f"{', '.join(have) or 'none'})")


def _is_number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_whole(v):
    return isinstance(v, int) and not isinstance(v, bool)


# FMI type -> (FMU2Slave setter, (accepts the YAML value, converts it))
SETTERS = {
    "Real": ("setReal", (_is_number, float)),
    "Integer": ("setInteger", (_is_whole, int)),
    "Enumeration": ("setInteger", (_is_whole, int)),
    "Boolean": ("setBoolean", (lambda v: isinstance(v, bool), bool)),
    "String": ("setString", (lambda v: isinstance(v, str), str)),
}


class Fmu:
    """One instantiated, initialized FMU; `name` is the subsystem name used in messages."""

    def __init__(self, path, name, values=None, integer_values=None, start_time=0.0, optional=(), pool=None):
        """Load, instantiate and initialize; `values` (and `integer_values`) are start values and
        parameters by name, each set with the FMI type its variable declares (Real, Integer,
        Enumeration, Boolean, String); names in `optional` are skipped when the FMU lacks them.
        Instances opened with one `pool` share the extracted FMU (see shared_folder)."""
        self.path, self.name = Path(path), name
        self._pool = pool
        self._key, self._dir = shared_folder(self.path, pool)
        check_version(self.path, self._dir)
        try:
            self.description = read_model_description(str(self._dir), validate=False)
        except Exception as exc:  # fmpy raises bare exceptions for malformed XML
            raise FmuError(f"{self.path}: cannot read modelDescription.xml: {exc}") from None
        cs = self.description.coSimulation
        check_runnable(self.path, self._dir, self.description)
        if cs.canBeInstantiatedOnlyOncePerProcess:       # its own copy of the binary for each instance
            release_folder(pool, self._key, self._dir)
            self._key, self._dir = None, extract_fmu(self.path)
        self.can_save_state = bool(cs.canGetAndSetFMUstate)
        self.variables = {v.name: v for v in self.description.modelVariables}
        self.messages = []
        self._callbacks = self._make_callbacks()
        self._slave = FMU2Slave(guid=self.description.guid, unzipDirectory=str(self._dir),
                                modelIdentifier=cs.modelIdentifier, instanceName=name)
        self.dll = self._slave.dll
        self._checked(self._slave.instantiate, "fmi2Instantiate", callbacks=self._callbacks)
        self.component = self._slave.component
        drop = [k for k in optional if k not in self.variables]
        given = {k: v for k, v in {**(values or {}), **(integer_values or {})}.items() if k not in drop}
        self._setup(given, start_time)

    def _make_callbacks(self):
        def logger(env, instance, status, category, message):
            text = message.decode("utf-8", "replace") if message else ""
            self.messages.append((status, text))
        cb = fmi2CallbackFunctions()
        self._logger_ref = fmi2CallbackLoggerTYPE(logger)
        cb.logger = self._logger_ref
        self._alloc_ref = fmi2CallbackAllocateMemoryTYPE(_libc.calloc)
        self._free_ref = fmi2CallbackFreeMemoryTYPE(_libc.free)
        cb.allocateMemory = self._alloc_ref
        cb.freeMemory = self._free_ref
        cb.stepFinished = fmi2StepFinishedTYPE()
        cb.componentEnvironment = None
        return cb

    def last_message(self) -> str:
        return self.messages[-1][1] if self.messages else "no message from the FMU"

    def _checked(self, call, fname, *args, **kwargs):
        try:
            return call(*args, **kwargs)
        except Exception as exc:
            raise FmuError(f"{self.name}: {fname} failed: {self.last_message()}", subsystem=self.name) from exc

    def _setup(self, given, start_time):
        self._checked(self._slave.setupExperiment, "fmi2SetupExperiment", startTime=start_time)
        by_type = {}
        for name, value in given.items():
            kind = self.variable(name).type
            setter, convert = SETTERS.get(kind, (None, None))
            if setter is None or not convert[0](value):
                raise FmuError(f"{self.name}: {name} is a {kind} variable of {self.path.name}; got {value!r}",
                               subsystem=self.name, variable=name)
            by_type.setdefault(setter, ([], []))
            by_type[setter][0].append(self.vr(name))
            by_type[setter][1].append(convert[1](value))
        for setter, (vrs, vals) in by_type.items():
            self._checked(getattr(self._slave, setter), f"fmi2{setter[0].upper()}{setter[1:]}", vrs, vals)
        self._checked(self._slave.enterInitializationMode, "fmi2EnterInitializationMode")
        self._checked(self._slave.exitInitializationMode, "fmi2ExitInitializationMode")

    def variable(self, name):
        if name not in self.variables:
            raise FmuError(f"{self.name}: the FMU {self.path.name} has no variable {name!r}", subsystem=self.name,
                           variable=name)
        return self.variables[name]

    def vr(self, name) -> int:
        return self.variable(name).valueReference

    def vrs(self, names) -> np.ndarray:
        return np.array([self.vr(n) for n in names], dtype=np.uint32)

    # ---- the calls a master makes, status-checked ----
    def get_real(self, vrs) -> np.ndarray:
        return np.array(self._checked(self._slave.getReal, "fmi2GetReal", list(map(int, vrs))))

    def set_real(self, vrs, values):
        values = [float(v) for v in values]
        if not all(math.isfinite(v) for v in values):
            raise FmuError(f"{self.name}: refusing to set a non-finite input {values}", subsystem=self.name)
        self._checked(self._slave.setReal, "fmi2SetReal", list(map(int, vrs)), values)

    def free_state_handle(self, handle):
        """Free a saved state held in a ctypes fmi2FMUstate handle (the frozen port map's x_i^n)."""
        self._checked(self._slave.fmi2FreeFMUstate, "fmi2FreeFMUstate", self.component, ctypes.byref(handle))

    @property
    def slave(self):
        """The fmpy FMU2Slave (for code that wants fmpy's own calls, e.g. the bench's plain loop)."""
        return self._slave

    def raw_function(self, fname):
        """A fresh ctypes function object without argtypes: callers pass pre-converted arguments."""
        return self.dll[fname]

    def function_pointer(self, fname) -> int:
        """Address of one of the FMU's own fmi2 functions, for the C fast path."""
        return ctypes.cast(self.dll[fname], ctypes.c_void_p).value

    def status_error(self, fname, status, step=None, time=None):
        """The FmuError for a raw call that returned `status`."""
        where = "" if step is None else f" at step {step} (t = {time:.6g})"
        return FmuError(f"subsystem {self.name}: {fname} returned {_STATUS.get(status, status)}{where}: "
                        f"{self.last_message()}", subsystem=self.name, step=step, time=time)

    def close(self):
        if getattr(self, "_slave", None) is not None:
            try:
                self._slave.terminate()
            except Exception:
                pass
            try:
                self._slave.freeInstance()
            except Exception:
                pass
            self._slave = None
        if self._dir is not None:
            release_folder(self._pool, self._key, self._dir)
            self._dir = None
