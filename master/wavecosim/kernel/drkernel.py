"""The fast path of the DR master: Algorithm 1 for a whole macro-step in one call into C.

The C kernel (kernel/c/drkernel.c, built with the FMUs into the kernel library libdrkernel.so) calls
each FMU through its own fmi2 function pointers with preallocated buffers, and does the DR
arithmetic in the operation order of wavecosim/kernel/linalg.py, so its numbers are bit-identical to the
readable reference `DRMaster` (wavecosim/masters/dr.py). This module wires the kernel up through
ctypes: `Kernel` owns one C kernel for a scene's subsystems, given as plain data
(kernel/description.py, KernelScene), and the buffers it shares with Python. The master that uses
it is wavecosim/masters/dr_fast.py::FastDRMaster. An FMI 3 FMU arrives in fmi2 form: its functions
are kernel/c/fmi3shim.c's, which take the FMU's shim as their fmi2Component.
"""
import ctypes
import functools
import math
import os

import numpy as np

from .abi import mirrors
from .build import kernel_library
from .contract import constant, names
from ..errors import ConfigError, FmuError
from .linalg import Sparse
from .portview import MultiRate, ObservedPort, PortView, SignedPort
from .signals import SignalPlan

LOG_PAD = 8               # a log's rows steps + LOG_PAD apart: 8 KiB apart, a step's values would share cache sets
PARALLEL_MIN_US = 150.0   # a thread pays only when it takes over at least this much work per evaluation round
DR_MAX_THREADS = constant("drkernel.h", "DR_MAX_THREADS")
CPUS_ENV = "WAVECOSIM_CPUS"
REASONS = names("drkernel.h", "DRReason", "DR_", dash=True)     # the kernel never gives "converged"
LEDGER_LOG = names("drkernel.h", "DRLedgerLog", "DR_LOG_")        # the ledger's rows of a log
LEDGER_ACTIONS = names("drkernel.h", "DRLedgerAction", "DR_LEDGER_")
STARTS = names("drkernel.h", "DRStart", "DR_START_")              # masters/dr_options.py
FUNCTIONS = (None, "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2SetReal", "fmi2DoStep", "fmi2GetReal")
FAILED_EXTRA = constant("drkernel.h", "DR_FAILED_EXTRA")   # the signals or a subsystem stepped alone failed
PASSES_CACHED, PASSES_EACH = (constant("drkernel.h", f"DR_PASSES_{w}") for w in ("CACHED", "EACH"))   # run_steps
FMI_NAMES = ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate", "fmi2SetReal", "fmi2DoStep",
              "fmi2GetReal")


class Trace:
    """The queries (u^k, S(u^k)) of one macro-step's inner loop, read like the reference's list of
    pairs; a pair is unpacked into lists only when it is read (most steps nobody reads them)."""

    def __init__(self, values, n, count):
        self._values, self._n, self._count = values, n, count

    def __len__(self):
        return self._count

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        k = k + len(self) if k < 0 else k
        if not 0 <= k < len(self):
            raise IndexError("trace index out of range")
        n, v = self._n, self._values
        return v[2 * n * k:2 * n * k + n], v[2 * n * k + n:2 * n * (k + 1)]

    def __iter__(self):
        return (self[k] for k in range(len(self)))

    def as_array(self):
        """All pairs as one (count, 2, n) array, without a Python object per pair."""
        arr = np.frombuffer(self._values, dtype=np.float64, count=2 * self._n * self._count)
        return arr.reshape(self._count, 2, self._n)


@mirrors("drkernel", "queries", "floor", "DRFunctions")
class DRFunctions(ctypes.Structure):
    """drkernel.h: the FMU functions the kernel calls."""
    _fields_ = [(name, ctypes.c_void_p) for name in
                ("getFMUstate", "setFMUstate", "freeFMUstate", "setReal", "doStep", "getReal")]


@mirrors("drkernel", "DRStep")
class DRStep(ctypes.Structure):
    """drkernel.h: inputs and results of one macro-step."""
    _fields_ = [("t", ctypes.c_double), ("dt", ctypes.c_double), ("K", ctypes.c_int), ("eps", ctypes.c_double),
                ("deadline_s", ctypes.c_double), ("measure", ctypes.c_int), ("iterations", ctypes.c_int),
                ("reason", ctypes.c_int), ("residual", ctypes.c_double), ("failed_subsystem", ctypes.c_int),
                ("failed_function", ctypes.c_int), ("failed_status", ctypes.c_int), ("stopped", ctypes.c_int),
                ("ledger_on", ctypes.c_int), ("ledger", ctypes.c_double), ("traffic", ctypes.c_double),
                ("ledger_rtol", ctypes.c_double), ("step_deadline_s", ctypes.c_double), ("round_s", ctypes.c_double),
                ("tail_s", ctypes.c_double), ("t0", ctypes.c_double), ("at", ctypes.c_int), ("passes", ctypes.c_int),
                ("passed", ctypes.c_int)]


_lib = None


def load_library():
    """The kernel library, built (with the FMUs) if missing or stale, its signatures those drkernel.h
    and its parts' headers declare (contract.py); raises FmuError if it cannot be built."""
    global _lib
    if _lib is None:
        _lib = kernel_library("drkernel", "the kernel library")
    return _lib


class BlockLog:
    """The macro-steps run in one kernel call, one row per step: iterations, reason (index into
    REASONS), residual, a (steps x n), b^{n+1} (steps x n); `observed` holds the observed values one
    per row (values x steps), as the kernel logs them (each value contiguous), and `ledger` the energy
    ledger's (LEDGER_LOG x steps). `stopped`: the kernel stopped early after the last step (its H may
    exceed the cap, or a value is not finite). `address`, `ld`: where the log lives for the C passes
    (its first value, doubles between rows); the views are made when first read. `passed`: its first
    steps the kernel's passes went over (blocks.Pass), the rest are the caller's. `last`: the StepLog
    of a stopped call's last step after the master's guard judged it (None: the step is booked in
    the log, as the energy ledger's are)."""

    __slots__ = ("columns", "n", "stopped", "address", "ld", "passed", "last")

    def __init__(self, columns, n, stopped=False, address=None, ld=None, passed=0):
        self.columns, self.n, self.stopped = columns, n, stopped     # one row per logged value
        self.address = columns.ctypes.data if address is None else address
        self.ld = columns.strides[0] // 8 if ld is None else ld
        self.passed = passed         # its first steps the kernel's passes went over (run_steps' passes)
        self.last = None

    a_rows = property(lambda self: range(3, 3 + self.n))                 # the rows of a_hat
    observed_at = property(lambda self: 3 + 2 * self.n)                  # the first observed value's row
    ledger_at = property(lambda self: len(self.columns) - len(LEDGER_LOG))   # LEDGER_LOG x steps, from this row
    iterations = property(lambda self: self.columns[0])
    reason = property(lambda self: self.columns[1])
    residual = property(lambda self: self.columns[2])
    a_hat = property(lambda self: self.columns[3:3 + self.n].T)
    b = property(lambda self: self.columns[3 + self.n:3 + 2 * self.n].T)
    observed = property(lambda self: self.columns[3 + 2 * self.n:self.ledger_at])
    ledger_rows = property(lambda self: self.columns[self.ledger_at:])
    ledger = property(lambda self: dict(zip(LEDGER_LOG, self.ledger_rows)))

    def __len__(self):
        return self.columns.shape[1]

    def a_hat_at(self, j):
        """a of step j, a copy."""
        return self.columns[3:3 + self.n, j].copy()

    def b_at(self, j):
        """b^{n+1} of step j, a copy."""
        return self.columns[3 + self.n:3 + 2 * self.n, j].copy()

    def first(self, k):
        """The first k steps (not stopped): this log when that is all of it."""
        if k == len(self) and not self.stopped:
            return self
        return BlockLog(self.columns[:, :k], self.n, address=self.address, ld=self.ld, passed=min(self.passed, k))


def available_cpus():
    """The cores this process may run on, or $WAVECOSIM_CPUS when set (e.g. a container's CPU quota,
    which the affinity mask does not show)."""
    value = os.environ.get(CPUS_ENV, "").strip()
    if value:
        if not value.isdigit() or int(value) < 1:
            raise ConfigError(f"{CPUS_ENV} must be a positive integer, got {value!r}")
        return int(value)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def thread_plan(costs_us, n_threads):
    """Subsystem -> thread (0 = the caller): longest evaluation first onto the least loaded thread."""
    load, plan = [0.0] * n_threads, [0] * len(costs_us)
    for i in sorted(range(len(costs_us)), key=lambda i: -costs_us[i]):
        k = min(range(n_threads), key=lambda k: (load[k], k))
        plan[i] = k
        load[k] += costs_us[i]
    return plan, load


class Kernel:
    """One C kernel over a scene's subsystems (wave mode), with its buffers b, a_hat, u^0, u^K."""

    def __init__(self, scene, P, J_L):
        """scene: a description.KernelScene. P, J_L: linalg.Sparse or dense rows; None for a route without
        them (kernel/classical.py, newton.py), which then runs the subsystems in the port mode the scene
        opened them in."""
        lib = self.lib = load_library()
        n = scene.n
        self.scene, self.subsystems = scene, scene.subsystems
        self.plan, self.views, self.shims = None, [], []    # signals.c's plan, portview.c's views and shims
        array = ctypes.c_double * n
        self.n = n
        # b^n, a, u^0, u^K side by side, so that one slice reads all four after a macro-step
        self.results = (ctypes.c_double * (4 * n))()
        self.b, self.a_hat, self.u0, self.uK = [array.from_buffer(self.results, 8 * n * j) for j in range(4)]
        self.handle = lib.dr_create(len(self.subsystems), n, None, None, self.b, self.a_hat, self.u0, self.uK)
        if not self.handle:
            raise FmuError("the DR kernel could not be created (out of memory)")
        self._handle = ctypes.c_void_p(self.handle)
        try:
            if P is not None:
                self.set_maps(P, J_L)
        except FmuError:
            self.close()
            raise
        for i, s in enumerate(self.subsystems):
            self._set_subsystem(i, s)
        self.io = DRStep(measure=0, eps=-1.0, deadline_s=0.0, t0=scene.t0)
        self.at = (None, None)                     # (n, t) of the last macro_step
        self._io = ctypes.byref(self.io)
        self._macro_step = lib.dr_macro_step       # called with pre-converted arguments
        self.threads = 1
        self.trace, self.trace_capacity = None, 0
        self.width, self.log, self._log_at = lib.dr_log_width(self._handle), np.empty((0, 0)), None
        self._run_steps = functools.partial(lib.dr_run_steps, self._handle)     # (io, n0, count, log, ld, H_cap)

    def _set_subsystem(self, i, s):
        """Subsystem i (a description.KernelSubsystem): its functions, or portview.c's signed shim over
        them (over multirate.c's shim for substeps), or its wave adapter in C. x_i^n goes into the scene's own handle (s.state), so that after
        a fast macro-step the scene holds x_i^n exactly as after the reference one."""
        lib, fns, comp = self.lib, DRFunctions(*s.functions), s.component
        if s.counters is not None:
            lib.dr_set_adapter(self.handle, i, *s.counters)
        if s.substeps is not None:
            self.shims.append(MultiRate(lib, fns, comp, s.m, s.substeps))
            fns, comp = self.shims[-1].functions, self.shims[-1].handle
            lib.dr_set_adapter(self.handle, i, None, self.shims[-1].do_steps)
        if s.scales is not None:
            self.shims.append(SignedPort(lib, fns, comp, s.m, *s.scales))
            fns, comp = self.shims[-1].functions, self.shims[-1].handle
        if lib.dr_set_subsystem(self.handle, i, ctypes.byref(fns), comp, s.state, s.vr_in, s.vr_out, s.m,
                                s.offset) or lib.dr_set_no_prior(self.handle, i, s.no_prior):
            self.close()
            raise FmuError(f"subsystem {s.name}: the DR kernel refused its port")

    def observe(self, names, steps=0, bound=None):
        """Read these variables of each subsystem (names[i], H_i first) after every commit of run_steps,
        with a log of room for `steps` steps made now; returns an empty BlockLog of the blocks' layout
        (what the runner prepares its passes with). bound: (limit, indices of the observed values
        over all subsystems): run_steps also stops after a step where one is above the limit."""
        for i, (s, vars_i) in enumerate(zip(self.subsystems, names)):
            port = vars_i if isinstance(vars_i, ObservedPort) else None
            vrs = (ctypes.c_uint * len(vars_i))(*(range(len(vars_i)) if port else s.fmu.vrs(vars_i)))
            if self.lib.dr_set_observed(self._handle, i, vrs, len(vars_i)):
                raise FmuError(f"subsystem {s.name}: the DR kernel could not keep {len(vars_i)} observed values")
            if port is not None:
                self._view(i, s, port)
        if self.scene.signals is not None:
            self._take_signals(names[len(self.subsystems):])
        limit, rows = bound or (math.inf, [])
        if self.lib.dr_set_bound(self._handle, limit, (ctypes.c_int * len(rows))(*rows), len(rows)):
            raise FmuError("the DR kernel could not keep the growth bound (out of memory)")
        self.width = self.lib.dr_log_width(self._handle)
        self._log_room(0, steps)
        return BlockLog(self.log[:, :0], self.n)

    def _view(self, i, s, port):
        """Subsystem i's observed values through portview.c's view of its physical port."""
        view = PortView(self.lib, s.fmu.pointer("fmi2GetReal"), s.fmu.component, s.fmu.vrs(port.names),
                        port, s.impedance if port.adapter else None)
        self.views.append(view)
        self.lib.dr_set_observed_view(self._handle, i, view.get, view.handle, int(not port.has_H))

    def _take_signals(self, alone_names):
        """The scene's signals and subsystems stepped alone into the blocks (signals.c), reading
        alone_names[j] of the j-th subsystem stepped alone after each step."""
        if self.plan is not None:
            self.plan.close()
        scene = self.scene
        vrs = [fmu.vrs(names) for fmu, names in zip(scene.alone, alone_names)]
        self.plan = SignalPlan(self.lib, self._handle, scene.signals, vrs, FUNCTIONS, scene.book_alone)

    def _log_room(self, keep, steps):
        """A log of room for `steps` steps per call (written through once, so no page of it is first
        touched inside a block), its first `keep` columns kept; the kernel writes the ledger's plain
        rows into the rest once (dr_prepare_log), not each block."""
        if self.log.shape[0] == self.width and self.log.shape[1] >= steps:
            return
        log = np.full((self.width, max(steps, 1) + LOG_PAD), math.nan)
        if keep:
            log[:, :keep] = self.log[:, :keep]
        self.log, self._log_at = log, log.ctypes.data
        ld = log.shape[1]
        self.lib.dr_prepare_log(self._handle, self._io, self._log_at + 8 * keep, ld, ld - keep)

    def keep_ledger(self, ledger, traffic, rtol, step_deadline_s=None):
        """From the next run_steps on, the kernel books the interface energy ledger from (L, traffic)
        and redoes a step that would lift it above tol, within step_deadline_s (drkernel.c, ledger_step)."""
        io = self.io
        io.ledger_on, io.ledger, io.traffic, io.ledger_rtol = 1, ledger, traffic, rtol
        io.step_deadline_s = step_deadline_s or 0.0

    def set_passes(self, passes):
        """The passes (blocks.Pass) run_steps makes, when asked, over the steps it logs (drkernel.h,
        dr_set_passes)."""
        p = ctypes.c_void_p * max(1, len(passes))
        fns, args = p(*[q.function for q in passes]), p(*[ctypes.addressof(q.args) for q in passes])
        if self.lib.dr_set_passes(self._handle, len(passes), fns, args):
            raise FmuError(f"the DR kernel refused {len(passes)} passes over its log (drkernel.h, DR_MAX_PASSES)")

    def run_steps(self, n0, count, H_cap=math.inf, measure=False, at=0, passes=False):
        """Macro-steps n0 .. n0 + count - 1 in one call (drkernel.h, dr_run_steps): (steps done, their
        BlockLog, the FmuError of the step after them or None). The call logs from column `at` on,
        after the last call's first `at` steps (joined_log reads them as one, without a copy); the log
        is overwritten by the next call from column 0. passes: it makes the passes (set_passes) over
        the block's steps as it logs them, PASSES_CACHED a few at a time, PASSES_EACH after every step
        (BlockLog.passed: how far they went)."""
        self._log_room(at, at + count)
        io = self.io
        io.measure, io.at, io.passes = measure, at, passes
        log, ld = self.log, self.log.shape[1]
        if self.plan is not None:
            self.plan.prepare(n0, count)
        done = self._run_steps(self._io, n0, count, self._log_at + 8 * at, ld, H_cap)
        n, failed = n0 + done, self.io.failed_subsystem != -1
        if self.plan is not None:
            self.plan.book(n0, done, failed)
        error = self.failure(n, n * self.io.dt) if failed else None
        passed = max(0, min(io.passed - at, done)) if passes else 0
        return done, BlockLog(log[:, at:at + done], self.n, bool(io.stopped), self._log_at + 8 * at, ld, passed), error

    def step_in_progress(self):
        """The macro-step the kernel is making or made last (from t_n, which each step sets first): read
        by another thread while run_steps runs, it tells how far the call has come."""
        return int(round(self.io.t / self.io.dt)) if self.io.dt > 0 else 0

    def redo_do_steps(self):
        """doSteps of the FMUs in the energy ledger's redos the kernel made so far."""
        return self.lib.dr_redo_do_steps(self._handle)

    def joined_log(self, steps, stopped):
        """The log's first `steps` columns as one BlockLog (a call and the calls it went on after)."""
        passed = min(self.io.passed, steps) if self.io.passes else 0
        return BlockLog(self.log[:, :steps], self.n, stopped, passed=passed)

    def set_options(self, relaxation, anderson, start, memory=False, extrapolate=False):
        """The DR master's named options (wavecosim/masters/dr_options.py; start: an index of STARTS);
        forgets b^{n-1}, a^{n-1} and the Anderson differences."""
        if (self.lib.dr_set_options(self._handle, float(relaxation), int(anderson), int(start))
                or self.lib.dr_set_anderson_modes(self._handle, int(bool(memory)), int(bool(extrapolate)))):
            raise FmuError(f"the DR kernel refused its options (relaxation {relaxation}, anderson {anderson})")

    def set_anchors(self, on):
        """Keep the energy ledger's anchors in the inner loop (a run with the ledger needs them)."""
        self.lib.dr_set_anchors(self._handle, int(bool(on)))

    def set_previous(self, a_prev):
        """a^{n-1} for the start of the next macro-step after an undo (None: the step undone was the first)."""
        self.lib.dr_set_previous(self._handle, None if a_prev is None else (ctypes.c_double * self.n)(*a_prev))

    def set_maps(self, P, J_L):
        """P and J_L (linalg.Sparse, or dense rows) for the next macro-steps, copied by the kernel."""
        args = []
        for M in (P, J_L):
            M = M if isinstance(M, Sparse) else Sparse.from_dense(M)
            args += [M.start.ctypes.data_as(ctypes.POINTER(ctypes.c_int)),
                     M.col.ctypes.data_as(ctypes.POINTER(ctypes.c_int)),
                     M.val.ctypes.data_as(ctypes.POINTER(ctypes.c_double))]
        if self.lib.dr_set_maps(self.handle, *args):
            raise FmuError("the DR kernel refused the coupling maps (out of memory)")

    def record(self, capacity):
        """Record up to `capacity` inner-loop queries (u^k, S(u^k)) per macro-step (0 = stop)."""
        if capacity > self.trace_capacity:
            self._trace_type = ctypes.c_double * (2 * self.n * capacity)
            self.trace = self._trace_type()
        self.trace_capacity = max(capacity, 0)
        self.lib.dr_set_trace(self.handle, self.trace, self.trace_capacity)

    def recorded(self, iterations):
        """[(u^k, S(u^k))] of the last macro-step, as the reference DRMaster.S records them."""
        count = min(iterations, self.trace_capacity)
        copy = (ctypes.c_double * (2 * self.n * count))()          # not the whole capacity (K may be huge)
        ctypes.memmove(copy, self.trace, 16 * self.n * count)
        return Trace(copy, self.n, count)

    def configure(self, dt, K, eps=None, deadline_s=None):
        self.io.dt, self.io.K = dt, K
        self.io.eps = -1.0 if eps is None else eps
        self.io.deadline_s = deadline_s or 0.0

    def macro_step(self, n, t, measure=False):
        """Algorithm 1, lines 3-22, in C; raises the FmuError the reference path would raise."""
        io = self.io
        io.t, io.measure, self.at = t, measure, (n, t)
        if self._macro_step(self._handle, self._io):
            raise self.failure(n, t)
        return io

    def redo(self, supplied, budget, left_s, round_s):
        """The energy ledger's redo of the step macro_step just made (drkernel.h, dr_ledger_redo), with
        left_s seconds to the step's deadline (inf: none): (s, supply, traffic, action, rounds); b and
        a_hat become the redo's."""
        out = (ctypes.c_double * 5)()
        if self.lib.dr_ledger_redo(self._handle, self._io, supplied, budget, left_s, round_s, out):
            raise self.failure(*self.at)
        return out[0], out[1], out[2], int(out[3]), int(out[4])

    def failure(self, n, t):
        io = self.io
        if io.failed_subsystem == FAILED_EXTRA:
            return self.plan.error(n, t)
        sub = self.subsystems[io.failed_subsystem]
        inner = sub.adapter_error(n, t) if sub.adapter_error else None      # the wave adapter's own failure
        return inner or sub.fmu.error(FUNCTIONS[io.failed_function], io.failed_status, n, t)

    def costs(self):
        """Median µs per evaluation of each subsystem since the last call (steps run with measure)."""
        out = (ctypes.c_double * len(self.subsystems))()
        self.lib.dr_costs(self.handle, out)
        return list(out)

    def counts(self):
        """[(doStep, save, restore)] made by the kernel per subsystem."""
        out = (ctypes.c_long * (3 * len(self.subsystems)))()
        self.lib.dr_counts(self.handle, out)
        return [tuple(out[3 * i:3 * i + 3]) for i in range(len(self.subsystems))]

    def set_threads(self, plan):
        """Evaluate subsystem i on thread plan[i] (0 = the caller); False if threads cannot start."""
        n_threads = max(plan) + 1
        ok = self.lib.dr_set_threads(self.handle, n_threads, (ctypes.c_int * len(plan))(*plan)) == 0
        self.threads = n_threads if ok else 1
        return ok

    def thread_plan(self):
        """The plan in force in the kernel: [thread of subsystem i]."""
        out = (ctypes.c_int * len(self.subsystems))()
        self.lib.dr_thread_plan(self.handle, out)
        return list(out)

    def close(self):
        if self.plan is not None:
            self.plan.close()
            self.plan = None
        if self.handle:
            self.lib.dr_destroy(self.handle)
            self.handle = None
        for part in self.views + self.shims:
            part.close()
        self.views, self.shims = [], []
