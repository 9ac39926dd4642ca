"""Signals, sources and subsystems stepped alone inside the kernel's blocks of macro-steps
(kernel/c/signals.c, in libdrkernel.so): the C side of wavecosim/core/signals.py's Signals.begin_step,
making the same FMU calls with the same numbers. `SignalPlan` builds it from plain data (the
scene's `Signals.plan()`), hands it the source tables' values before each block and books the
calls of the subsystems stepped alone.
"""
import ctypes

import numpy as np

from .abi import mirrors
from .contract import constant, names
from .fmicall import FUNCTION_NAMES, FmiFailure
from ..errors import FmuError, NumericalError

SG_FMU, SG_NONFINITE = (constant("signals.h", name) for name in ("SG_FMU", "SG_NONFINITE"))   # SGFailure.kind
TYPES = names("signals.h", "SGType", "SG_")                  # the types of the values a signal carries
FMU_FUNCTIONS = ("fmi2GetReal", "fmi2SetReal", "fmi2DoStep", "fmi2GetInteger", "fmi2SetInteger", "fmi2GetBoolean",
                 "fmi2SetBoolean")


@mirrors("drkernel", "SGFmu")
class SGFmu(ctypes.Structure):
    """signals.h: one FMU's functions and instance."""
    _fields_ = [(name, ctypes.c_void_p) for name in ("getReal", "setReal", "doStep", "getInteger", "setInteger",
                                                      "getBoolean", "setBoolean", "comp", "calls")]


@mirrors("drkernel", "SGSignal")
class SGSignal(ctypes.Structure):
    """signals.h: one signal's source column, input category, scaling and range."""
    _fields_ = [("column", ctypes.c_int), ("to", ctypes.c_int), *[(name, ctypes.c_double) for name in
                                                                   ("factor", "offset", "lo", "hi")]]


@mirrors("drkernel", "SGFailure")
class SGFailure(ctypes.Structure):
    """signals.h: why the last step's signals failed."""
    _fields_ = [("kind", ctypes.c_int), ("index", ctypes.c_int), ("call", FmiFailure), ("step", ctypes.c_int),
                ("value", ctypes.c_double)]


def _array(kind, values):
    return (kind * max(1, len(values)))(*values)


def _calls(calls):
    """(count, FMU and type of each call, starts, value references, signals) of get or set calls
    [(FMU, type (TYPES), value references, signals)]."""
    starts = [0]
    for _, _, vrs, _ in calls:
        starts.append(starts[-1] + len(vrs))
    return [len(calls), _array(ctypes.c_int, [c[0] for c in calls]), _array(ctypes.c_int, [TYPES.index(c[1]) for c in calls]),
            _array(ctypes.c_int, starts), _array(ctypes.c_uint, [v for c in calls for v in c[2]]),
            _array(ctypes.c_int, [k for c in calls for k in c[3]])]


def _functions(fmu, wanted):
    """SGFmu of an FMU (a description.KernelFmu): the functions in `wanted` (the others NULL)."""
    table = SGFmu(comp=fmu.component, calls=fmu.calls)
    for name, field in zip(FMU_FUNCTIONS, SGFmu._fields_):
        if name in wanted:
            setattr(table, field[0], fmu.pointer(name))
    return table


class SignalPlan:
    """signals.c's plan over a kernel (`handle`) from `plan` (description.KernelScene.signals: the
    FMUs as KernelFmu (port subsystems first, then those stepped alone), the signals, the getReal and
    setReal calls, the tables) and the outputs read of each subsystem stepped alone (`alone_vrs`, one
    list each); book_alone(j, n, t) says the j-th stepped alone is at step n (its calls count in its FMU's counters)."""

    def __init__(self, lib, handle, plan, alone_vrs, book_alone):
        self.lib, self.plan, self.book_alone = lib, plan, book_alone
        self.subsystems, self.alone = plan["subsystems"], plan["alone"]
        wanted = [set(FMU_FUNCTIONS[:3]) for _ in self.subsystems]
        for fmu, kind, _, _ in plan["reads"] + plan["writes"]:
            if kind != "real":
                wanted[fmu] |= {f"fmi2Get{kind.title()}", f"fmi2Set{kind.title()}"}
        fmus = (SGFmu * max(1, len(self.subsystems)))(*[_functions(f, w) for f, w in zip(self.subsystems, wanted)])
        sigs, alone_starts = plan["signals"], [0]
        for vrs in alone_vrs:
            alone_starts.append(alone_starts[-1] + len(vrs))
        signals = (SGSignal * max(1, len(sigs)))(*[SGSignal(column, TYPES.index(to), factor, offset, lo, hi)
                                                   for column, to, factor, offset, lo, hi in sigs])
        args = [len(self.subsystems), fmus, len(sigs), signals, *_calls(plan["reads"]), *_calls(plan["writes"]),
                len(self.alone),
                _array(ctypes.c_int, self.alone), _array(ctypes.c_int, alone_starts),
                _array(ctypes.c_uint, [v for vrs in alone_vrs for v in vrs])]
        self.handle = self.lib.sg_create(handle, *args)
        if not self.handle:
            raise FmuError("the kernel could not take the signals (out of memory)")
        self.rows = alone_starts[-1]
        self.table = None
        self.lib.sg_attach(self.handle)

    def prepare(self, n0, count):
        """Before a block of steps n0 .. n0 + count - 1: the source tables' values of its steps."""
        if self.plan["tables"] is None:
            return
        self.table = np.array(self.plan["tables"](n0, count), dtype=np.float64).reshape(-1, count)
        self.lib.sg_set_table(self.handle, self.table.ctypes.data, max(count, 1), n0, count)

    def book(self, n0, done, failed):
        """After steps n0 .. n0 + done - 1 (and a failure in step n0 + done): the step each subsystem
        stepped alone is at."""
        if not (done or failed):
            return
        last = n0 + done - (0 if failed else 1)
        for a in range(len(self.alone)):
            self.book_alone(a, last, self.plan["t0"] + last * self.plan["dt"])

    def error(self, n, t):
        """The error of the step whose signals failed, as the Python route raises it."""
        f = self._failure()
        if f.kind == SG_NONFINITE:
            return NumericalError(self.plan["nonfinite"](f.index, f.value, f.step))
        if f.kind == SG_FMU:
            name = FUNCTION_NAMES.get(f.call.function)
            return self.subsystems[f.index].error(name, f.call.status, n, t)
        return FmuError(f"the kernel's signals had no source table values for step {f.step}")

    def _failure(self):
        """signals.h: the SGFailure of the last step."""
        return SGFailure.from_address(self.lib.sg_failure(self.handle))

    def close(self):
        if self.handle:
            self.lib.sg_destroy(self.handle)
            self.handle = None
