"""Runs one scenario with one master: set up the parts, step them, summarise.

    live = LiveRun(scenario, ...)        scene, master, sampler, observers, recorder tables
    live.start()                         reading at t = 0, first rows
    for n in range(N): live.step(n)      before_step, master.step, after_step, one row
    live.finish(status, error)           summary.json, metadata.json, the RunResult

When the master can make many macro-steps in one call (the C kernel's run_steps) and every observer
takes them at once (Observer.after_block), `advance` makes blocks of up to BLOCK_STEPS steps: the
same numbers as step by step, to the last bit, without crossing into Python at every step.

A monolithic reference runs in lockstep (its own LiveRun) when asked, so errors are computed as
both runs stream and memory does not grow with the number of steps.
"""
import math
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..kernel import blocks
from ..errors import (ConfigError, Interrupted, OutputError, RunFailed, SimulationEnded, Terminated,
                      WavecosimError)
from ..fmi.values import BOOLEAN, INTEGER, category
from ..kernel.drkernel import REASONS as KERNEL_REASONS
from ..kernel.linalg import total
from ..core.gamma import GammaTuner
from ..masters import MASTERS
from ..masters.adaptive import adaptive
from ..masters.base import REASONS, WaveMaster, require_wave_tuning
from .bounds import Bounds, named_for_cause
from . import containment
from ..masters.dr_options import auto_gamma
from .metadata import run_metadata
from .observers import Observer
from ..core.certificates import sampling
from .observers.certificates import CertificatePace, CertificateSampler
from .observers.energy_guard import EnergyGuard
from .observers.energy_ledger import EnergyLedger
from .observers.errors import ErrorTracker, ScaledErrors, error_observers, stored_reference, stored_rows
from .observers.fne_watch import FneWatch
from .observers.freeze_watch import FreezeWatch
from .observers.gamma import GammaLog, TunedGammaLog
from .observers.passivity import Passivity
from .observers.step_control import StepControl
from .outputs import cannot
from .recorder import BLOCK, Interrupts, Labels, Table, Texts, ints, write_json, write_mat
from ..core.readings import Sampler
from ..core.quirks import RestoreWatch
from ..core.scene import build_scene
from ..fmi.messages import LogFile

FORMATS = ("csv", "mat")
CALLS = ("doStep", "save", "restore")       # the FMU calls a run counts (fmu_calls)
# The columns of steps.csv every run has, then the observers' (their `described`); docs/outputs.md
# is generated from these.
STEP_DESCRIBED = {
    "time": ("the grid time t₀ + (n + 1)·Δt at the end of macro-step n", "s"),
    "iterations": ("inner iterations made in the step (0 for a master that does not iterate)", "1"),
    "inner_residual": ("the size of the last inner update, |uᵏ⁺¹ − uᵏ| (wave masters, sqrt(J)) or |yᵏ⁺¹ − yᵏ| "
                       "(physical masters, the port variables' units: no one unit); NaN when no iteration ran", "sqrt(J)"),
    "reason": (f"why the inner loop stopped: {', '.join(REASONS)}", "text"),
}
STEP_COLUMNS = tuple(STEP_DESCRIBED)
OBSERVERS = (EnergyLedger, EnergyGuard, GammaLog, TunedGammaLog, FneWatch, CertificateSampler, CertificatePace,
             Passivity, FreezeWatch, StepControl, ErrorTracker, ScaledErrors)    # every observer, in the order they act (their columns too)
BLOCK_STEPS = BLOCK                    # macro-steps per call of the master, at most a table block
HAND_OVER_S = 1.0                      # rows booked are handed to the writer at least this often
DURABLE_S = 0.05                       # in a supervised run: the most time of steps a process killed outright loses
MAX_STEPS = 10 ** 8                    # more macro-steps than this only when asked (--force, max_steps=None)
assert REASONS[:len(KERNEL_REASONS)] == KERNEL_REASONS     # the kernel's reason codes are the runner's


def grid_inverse(dt):
    """1/dt when it is a whole number (the grid is then k / (1/dt)), else 0 (the grid is k * dt)."""
    inverse = round(1.0 / dt)
    return inverse if inverse > 0 and abs(inverse * dt - 1.0) < 1e-12 else 0


def grid_clock(dt):
    """k -> the grid value k dt: k / (1/dt) when 1/dt is a whole number (so t = 0.3 is 0.3, not
    0.30000000000000004), else k * dt."""
    inverse = grid_inverse(dt)
    if inverse:
        return lambda k: k / inverse
    return lambda k: k * dt


def grid_times(k, dt):
    """grid_clock for an array of step indices."""
    return grid_clock(dt)(np.asarray(k, float))


def _structured(table):
    """A table's rows as a NumPy structured array, one float field per column ('reason' and the
    recorded String outputs as text)."""
    data = table.array()
    texts = {c: f.texts for c, f in zip(table.columns, table.formats) if isinstance(f, Texts)}
    fields = [(c, "U12" if c == "reason" else f"U{max(map(len, texts[c]), default=1) or 1}" if c in texts
               else "f8") for c in table.columns]
    out = np.empty(len(data), dtype=fields)
    for j, (name, _) in enumerate(fields):
        if name == "reason" or name in texts:
            names = REASONS if name == "reason" else texts[name]
            out[name] = [names[int(v)] for v in data[:, j]]
        else:
            out[name] = data[:, j]
    return out


@dataclass
class RunResult:
    """What a run produced: `trajectory` and `steps` as NumPy structured arrays whose first field is
    `time` (fmpy's plot_result and write_csv take them as they are), `summary` (as summary.json),
    status and message; arrays of long runs are read back from their files when asked."""
    label: str
    master: str
    K: int
    columns: list
    units: dict
    error_columns: list
    trajectory_table: Table = None
    steps_table: Table = None
    first: dict = field(default_factory=dict)      # values at t = 0 that steps.csv has no row for
    summary: dict = field(default_factory=dict)
    status: str = "finished"
    message: str = ""
    reference: "RunResult" = None                  # the lockstep monolithic reference, when one ran

    @property
    def trajectory(self):
        return _structured(self.trajectory_table)

    @property
    def steps(self):
        return _structured(self.steps_table)

    @property
    def t(self):
        return self.trajectory_table.array()[:, 0]

    @property
    def outputs(self):
        return self.trajectory_table.array()[:, 1:]

    def column(self, name):
        return self.outputs[:, self.columns.index(name)]

    def _series(self, key, column):
        """A per-step column with its value at t = 0 in front: one entry per trajectory row."""
        if column not in self.steps_table.columns:
            return None
        data = self.steps_table.array()[:, self.steps_table.columns.index(column)]
        return np.concatenate([[self.first.get(key, np.nan)], data])

    @property
    def energy(self):
        """Total stored energy H at every recorded grid point, t = 0 included."""
        return self._series("H", "H_total")

    @property
    def error(self):
        """Error against the monolithic reference at every recorded grid point (None without one)."""
        return self._series("error", "error")

    def per_subsystem(self, prefix):
        """The per-subsystem columns `prefix<name>` of steps (r_, fne_, gamma_) as one 2-D array."""
        cols = [c for c in self.steps_table.columns if c.startswith(prefix) and c != "fne_watch"]
        data = self.steps_table.array()
        return data[:, [self.steps_table.columns.index(c) for c in cols]]

    def to_pandas(self):
        """The trajectory as a pandas DataFrame indexed by time (pandas is not a dependency)."""
        import pandas as pd
        return pd.DataFrame(self.trajectory).set_index("time")


def _warn_stderr(message):
    print(f"warning: {message}", file=sys.stderr, flush=True)


def _once(warn):
    """`warn` that lets each distinct message through once."""
    seen = set()

    def once(message):
        if message not in seen:
            seen.add(message)
            warn(message)
    return once


def open_parts(scenario, warn, share=None):
    """Scene, master and gamma tuner of a run; whatever was opened is closed if set-up fails. A run
    alongside another (the lockstep reference) shares the other scene's FMU binaries and quirks."""
    cls = adaptive(MASTERS[scenario.master.algorithm], scenario.master)
    scene = build_scene(scenario, wave=cls.wave, needs_rollback=cls.needs_rollback,
                        pool=share.pool if share else None, quirks=share.quirks if share else None)
    for note in scene.notes:
        warn(note)
    master = None
    gamma = auto_gamma(scenario.gamma, scenario.master) if cls.iterates else scenario.gamma
    try:
        tuner = None
        if cls.wave and isinstance(gamma, str):
            tuner = GammaTuner(scene, gamma, warn if cls.iterates else None)
            tuner.initial([0.0] * scene.n_channels)                # sets the scene's per-subsystem gammas
        master = cls(scene, scenario.master)
        require_wave_tuning(master, gamma, scenario.source)
        return scene, master, tuner
    except BaseException:
        if master is not None:
            master.close()
        scene.close()
        raise


def make_observers(scenario, scene, master, tuner, certificates, warn):
    """The observers this run needs, in the order they act (the energy guard first); none where no
    subsystem has a port (nothing exchanges energy)."""
    obs, unavailable = [], []
    if not scene.n_channels:
        return obs
    has_H = all(s.port.energy is not None for s in scene.subsystems)
    guard = scenario.master.energy_guard or master.default_guard
    if guard == "ledger" and master.guardable:
        obs.append(EnergyLedger(master))
    elif guard == "monolithic" and master.guardable and master.iterates:
        if has_H:
            obs.append(EnergyGuard(master))
        else:
            unavailable.append("energy_guard (monolithic: needs every subsystem's stored energy H)")
    if isinstance(master, WaveMaster):
        obs.append(TunedGammaLog(scene, master, tuner) if tuner and tuner.retune else GammaLog(scene, master, tuner))
    certs = scenario.certificates
    pace = sampling(certs, master.evaluations)
    if master.iterates and scenario.fne_watch and certificates:
        obs.append(FneWatch(scene, master, pace, warn))
    augmented = master.iterates and has_H
    if certificates and master.iterates and certs.augmented and not has_H:
        unavailable.append("max_augmented_pos (Theorem 1 needs every subsystem's stored energy H)")
    if certificates and scene.wave and (certs.fne_pairs or (certs.augmented and augmented)):
        obs.append(CertificateSampler(scene, master, certs, augmented=augmented, pace=pace))
    if any(isinstance(o, (FneWatch, CertificateSampler)) for o in obs):
        obs.append(CertificatePace(pace))
    obs.append(Passivity(scene, unavailable))
    obs.append(FreezeWatch(scene, warn))
    if master.variable:
        obs.append(StepControl(master))
    return obs


class LiveRun:
    """One run while it runs; it owns its parts and closes them."""

    def __init__(self, scenario, out_dir=None, label=None, certificates=True, warn=None, file_suffix=True,
                 output_interval=1, formats=("csv",), share=None):
        self.scenario, self.warn = scenario, warn or _warn_stderr
        settings = scenario.master
        self.label = label or f"{settings.algorithm}_K{settings.K}"
        self.scene, self.master, tuner = open_parts(scenario, self.warn, share)
        self.observers = make_observers(scenario, self.scene, self.master, tuner, certificates, self.warn)
        self.guard_mode = (settings.energy_guard or self.master.default_guard) if self.master.guardable else "n/a"
        if any(o.needs_trace for o in self.observers):
            self.master.enable_trace(True)
        self.out_dir, self.formats = (Path(out_dir) if out_dir is not None else None), formats
        self.suffix = f"_{self.label}" if file_suffix else ""
        self.fmu_log = LogFile(self.out_dir / f"fmu_log{self.suffix}.txt") if self.out_dir is not None else None
        for s in self.scene.subsystems + self.scene.signal_only if self.fmu_log is not None else ():
            s.fmu.messages.attach(self.fmu_log)
        self.every, self.n_steps, self.dt, self.t0 = output_interval, scenario.n_steps, scenario.dt, scenario.start_time
        self.sampler = Sampler(self.scene, self.scene.outputs)
        self.columns = list(self.scene.outputs)
        self.bounds = Bounds(self.scene, self.scene.outputs, scenario.growth_bound, self.sampler.types)
        self.master_time, self.steps_done, self.started = 0.0, 0, time.perf_counter()
        self.iterations = [0, 0]                       # sum and max of the inner iterations of the steps made one by one
        self.loop_time = 0.0                           # start() to the last row written: the run's own per-step cost
        self.led, self.failure, self.recent = 0, None, {}   # as a lockstep reference (lead)
        self.block_steps = 0                                # macro-steps made in blocks
        self.rows_pass, self.kernel_passes = None, False    # the blocks' C passes (_prepare_blocks)
        self.in_block = None                                # n0 of the kernel call in progress
        self.block_cap = BLOCK_STEPS                        # macro-steps per kernel call at most (see durable)
        self.durable = False
        self.write_error = None                             # an OutputError met while finishing
        self.calls_at_start = self.excluded = None          # set by start(): a run that failed before has none

    def more(self, n):
        """Whether steps are left after n: the fixed grid's count, or the varying step's end time."""
        return self.master.more(n) if self.master.variable else n < self.n_steps

    def progress_of(self, n):
        """Steps done as the progress shows them: n, or the share of the time made, in fixed steps."""
        if not self.master.variable:
            return n
        return min(self.n_steps, round((self.time_of(n) - self.t0) / self.dt))

    def add_observer(self, observer: Observer):
        """Before start(): one more observer (e.g. the error tracker), acting last."""
        self.observers.append(observer)

    def _tables(self):
        rows = self.n_steps // self.every + 2
        path = (lambda kind: self.out_dir / f"{kind}{self.suffix}.csv") if self.out_dir else (lambda kind: None)
        self.trajectory = Table(["time", *self.columns], path("trajectory"), expected_rows=rows,
                                formats=self._output_formats())
        obs_cols = [c for o in self.observers for c in o.columns]
        formats = {"iterations": ints, "reason": Labels(REASONS)}
        for o in self.observers:
            formats.update(o.formats)
        self.steps = Table([*STEP_COLUMNS, *obs_cols], path("steps"), expected_rows=rows, formats=formats)
        self.scratch = np.full(len(self.steps.columns), np.nan)
        self.slices, self.spans, at = [], {}, len(STEP_COLUMNS)
        for o in self.observers:
            self.slices.append(self.scratch[at:at + len(o.columns)])
            self.spans[id(o)] = slice(at, at + len(o.columns))
            at += len(o.columns)
        clock, t0 = grid_clock(self.dt), self.t0
        self.time_of = lambda k: t0 + clock(k)          # t_k = t0 + k dt
        if self.master.variable:                        # the accepted steps' times
            self.time_of, self.every = self.master.time_at, 1

    def _output_formats(self):
        """Integer and Boolean outputs written as integers, String (Binary) outputs as quoted text."""
        texts = self.sampler.typed.texts
        return {c: Texts(texts[c]) if c in texts else ints for c, kind in zip(self.columns, self.sampler.types)
                if c in texts or category(kind) in (INTEGER, BOOLEAN)}

    def start(self):
        """Read the FMUs at t = 0, start the observers, record the first trajectory row."""
        self._tables()
        self.calls_at_start = self._counts()
        self.excluded = [(0,) * len(CALLS)] * len(self.calls_at_start)
        first = self.sampler.read()
        for o in self.observers:
            o.start(first)
        row = self.trajectory.next_row()
        row[0], row[1:] = self.t0, first.outputs
        self.trajectory.commit_row()
        self.bounds.start(first, self.time_of)
        self.first = {"H": total(first.H), "error": next((o.first for o in self.observers
                                                        if isinstance(o, ErrorTracker)), math.nan)}
        self.bracket = any(type(o).before_step is not Observer.before_step for o in self.observers)
        self.guard, self.guard_row = next(((o, row) for o, row in zip(self.observers, self.slices) if o.redoes),
                                          (None, None))
        self.after = [(o, row) for o, row in zip(self.observers, self.slices) if o is not self.guard]
        self.recent = {0: first.outputs}
        self._plan_blocks()
        self.restores = RestoreWatch(self.scene, self.master.needs_rollback and self.durable)
        self.calls_at_start = self._counts()
        self.loop_started = time.perf_counter()

    def step(self, n):
        """Macro-step n: observers before, the master, observers after (the guard may redo), one row;
        returns the Reading of the FMUs after it."""
        t = self.time_of(n) if self.master.variable else self.t0 + n * self.dt
        self.scene.begin_step(n, t)                  # signals held, signal-only subsystems stepped
        before = self._counts() if self.bracket else None
        for o in self.observers:
            o.before_step(n, t)
        if before is not None:                       # observers' own FMU calls are not the master's
            now = self._counts()
            if now != before:
                self.excluded = [tuple(x + a - b for x, a, b in zip(*c)) for c in zip(self.excluded, now, before)]
        if self.kernel_guard:                        # the kernel makes the step and the ledger's redo in one call
            self.master.keep_ledger(*self.guard.kernel_state())
        t0 = time.perf_counter()
        log = self.master.step(n, t)
        self.master_time += time.perf_counter() - t0
        reading = self._after_master(n, t, log)
        if self.scene.ended is not None:            # an FMU ended the simulation with this step
            raise self.scene.ended
        return reading

    def _after_master(self, n, t, log):
        """After the master made step n: read the FMUs, the guard (it may redo), the observers, one row."""
        reading = self.sampler.read()
        if self.guard is not None:
            t0 = time.perf_counter()
            redo = self.guard.after_step(n, t, log, reading, self.guard_row)
            self.master_time += time.perf_counter() - t0
            if redo is not None:
                log, reading = redo, self.sampler.read()
        for o, row in self.after:
            o.after_step(n, t, log, reading, row)
        self._record(n, log, reading)
        self.bounds.check(reading, n)
        self.loop_time = time.perf_counter() - self.loop_started
        return reading

    def _plan_blocks(self):
        """Blocks when the master can make them, every observer takes them and nothing acts before a
        step (a paced observer: before the steps it names; blocks stop before them)."""
        guard = self.guard
        self.cap = guard.cap if isinstance(guard, EnergyGuard) else math.inf
        self.ledger = isinstance(guard, EnergyLedger)
        route = self.master.route()
        self.kernel_guard = self.ledger and route is not None and route.guards_steps()
        self.blocks = (route is not None
                       and all(o.paced or type(o).before_step is Observer.before_step for o in self.observers)
                       and all(o.blocks for o, _ in self.after)
                       and (guard is None or isinstance(guard, EnergyGuard)
                            or (self.ledger and route.keeps_ledger))          # classical: step by step
                       and not self.scene.steps_in_python and self.sampler.whole and blocks.library() is not None)
        self.paced = [o for o in self.observers if o.paced]          # blocks stop before their steps
        if self.blocks:
            layout = self.master.observe(self.sampler.observed, BLOCK_STEPS,
                                         (self.bounds.limit, self.bounds.bounded(self.sampler.rows("outputs"))))
            self.block_observers = [(o, self.spans[id(o)]) for o in ([guard] if self.ledger else [])
                                    + [o for o, _ in self.after]]
            self._prepare_blocks(layout)

    def _prepare_blocks(self, layout):
        """The C passes built in set-up, from an empty log of the blocks' layout, so the first block
        costs no more than the others; with every row kept the kernel makes them as it logs the steps."""
        readings = self.sampler.block(layout.observed)
        self.rows_pass = self._rows_pass(layout, readings)
        for o, _ in self.block_observers:
            o.prepare_block(layout, readings)
        self.passes = [(self.rows_pass, None)] + [(o.block_pass(), span) for o, span in self.block_observers
                                                   if o.block_pass() is not None]
        self.python_observers = [(o, span) for o, span in self.block_observers if o.block_pass() is None]
        self.rows_pass.args.lds, self.rows_pass.args.ldt = self.steps.ld, self.trajectory.ld
        for p, _ in self.passes[1:]:
            p.args.ldo = self.steps.ld
        self.kernel_passes = self.every == 1
        if self.kernel_passes:
            self.master.set_passes([p for p, _ in self.passes])

    def block_size(self, n):
        """How many macro-steps advance(n, ...) may make in one call of the master."""
        if not (self.blocks and self.master.can_run_steps(n)):
            return 1
        end = min(self.n_steps, self.restores.next)              # a block ends where the restore is checked
        if not self.paced:
            return min(self.block_cap, end - n)
        return max(1, min([self.block_cap, end - n] + [o.next_before(n) - n for o in self.paced]))

    def make_durable(self):
        """A supervised run (before start): its rows are in the files after every kernel call, and its
        kernel calls last about DURABLE_S at most (they start short and grow): the rows of a call still
        in progress are lost when the process is killed outright. Its restores are re-checked."""
        self.durable, self.block_cap = True, min(BLOCK_STEPS, 32)

    def _resize_blocks(self, done, seconds):
        if self.durable and done > 0:
            fit = int(DURABLE_S * done / seconds) if seconds > 0 else BLOCK_STEPS
            self.block_cap = max(1, min(BLOCK_STEPS, fit, 2 * self.block_cap))

    def advance(self, n, count):
        """Macro-steps from n on: up to `count` in one call of the master when count > 1, else step(n);
        returns how many were made."""
        if count == 1:
            self.step(n)
            return 1
        return self.step_block(n, count)

    def step_block(self, n0, count):
        """Macro-steps n0 .. n0 + count - 1 in one call of the master; the master stops early after a
        step the energy guard must judge (or with a non-finite value), which is then finished as in
        step() (the ledger is kept, and redone, in the kernel: such a step is in the block, and a
        non-finite value ends the run after it). Returns the steps made; raises the FmuError of the
        step after them."""
        if self.ledger:
            self.master.keep_ledger(*self.guard.kernel_state())
        if self.kernel_passes:
            self._aim(self.steps.reserve_at(count), self.trajectory.reserve_at(count))
        t0 = time.perf_counter()
        self.in_block = n0
        done, log, error = self.master.run_steps(n0, count, self.cap, self.kernel_passes)
        self.in_block = None
        self.master_time += time.perf_counter() - t0
        self._resize_blocks(done, time.perf_counter() - t0)
        self.block_steps += done
        whole = done - 1 if log.stopped and not self.ledger else done      # the ledger's kernel books every step
        if whole:
            self._after_block(n0, log.first(whole))
        if whole < done:
            n = n0 + whole
            self._after_master(n, self.t0 + n * self.dt, self.master.step_log(log, whole))
        elif log.stopped:
            self.bounds.check(self.sampler.read(), n0 + done - 1)
        self.loop_time = time.perf_counter() - self.loop_started
        if error is not None:
            raise error
        return done

    def _after_block(self, n0, log):
        """The observers and the rows of a block of steps (all finite: the kernel stops at a non-finite
        value): the C passes over the steps the kernel did not make them over (log.passed on), then
        the observers without one; with an output interval the rows kept are picked afterwards."""
        count, every = len(log), self.every == 1
        if every:                                        # the rows step_block aimed the passes at
            rows = steps_at = None
        else:                                            # as the tables' blocks: the passes' ld
            rows = np.empty((self.steps.ld, len(self.steps.columns)), order="F")[:count]
            trajectory = np.empty((self.trajectory.ld, 1 + len(self.columns)), order="F")[:count]
            steps_at = blocks.columns(rows)[0]
            self._aim(steps_at, blocks.columns(trajectory)[0])
        if log.passed < count:
            for p, _ in self.passes:
                p.steps(n0, log, log.passed, count - log.passed)
        if self.python_observers:
            if every:
                rows, steps_at = self.steps.reserve(count), self.steps.reserve_at(count)
            readings, ld = self.sampler.block(log.observed), self.steps.ld
            for o, span in self.python_observers:
                o.after_block(n0, log, readings, rows[:, span], (steps_at + 8 * ld * span.start, ld))
        self.steps_done = n0 + count
        if every:
            self.steps.commit_rows(count)
            self.trajectory.commit_rows(count)
        else:
            ks = np.arange(n0 + 1, n0 + count + 1)
            keep = (ks % self.every == 0) | (ks == self.n_steps)
            self.steps.append_block(rows[keep])
            self.trajectory.append_block(trajectory[keep])
        self.hand_over()

    def _aim(self, steps_at, trajectory_at):
        """The C passes of a block at its first row of the steps and of the trajectory (addresses; the
        tables' ld between columns): the observers' columns are spans of the steps'."""
        args, ld = self.rows_pass.args, self.steps.ld
        args.steps, args.trajectory = steps_at, trajectory_at
        for p, span in self.passes[1:]:
            p.args.out = steps_at + 8 * ld * span.start

    def _rows_pass(self, log, readings):
        """block_rows_steps with its fixed arguments: where the outputs are in the kernel's log, the grid."""
        outputs = blocks.ints([log.observed_at + r for r in readings.rows("outputs")])
        return blocks.Pass("block_rows_steps", blocks.BlockRows(
            n_out=len(self.columns), inverse=grid_inverse(self.dt), dt=self.dt, outputs=outputs, t0=self.t0,
            iterations_sum=0.0, iterations_max=-math.inf))

    def _iteration_totals(self):
        """(sum, max) of the inner iterations per step over the steps made so far, blocks included."""
        total, most = self.iterations
        if self.rows_pass is not None:
            args = self.rows_pass.args
            total, most = total + int(args.iterations_sum), max(most, int(max(args.iterations_max, 0)))
        return total, most

    def lead(self, n, end):
        """As the lockstep reference of a run at step n: make the steps up to end - 1 not made yet,
        keeping the outputs of the grid points after n (`recent`); a failure stops it and is kept in
        `failure`. Returns how many steps were made in all."""
        self.recent = {k: v for k, v in self.recent.items() if k > n}
        while self.failure is None and self.led < end:
            try:
                reading = self.step(self.led)
            except WavecosimError as exc:
                self.failure = exc
                break
            self.led += 1
            self.recent[self.led] = reading.outputs
        return self.led

    def _counts(self):
        """Each FMU's calls so far (CALLS), one tuple per subsystem: those with a port, then those stepped alone."""
        return [tuple(s.calls[k] for k in CALLS) for s in self.scene.subsystems + self.scene.signal_only]

    def fmu_calls_by_subsystem(self):
        """{subsystem: its doStep, save and restore calls from the first step on}, observers' probes excluded."""
        now = self._counts()
        start = now if self.calls_at_start is None else self.calls_at_start     # before the first step: none yet
        excluded = [(0,) * len(CALLS)] * len(now) if self.excluded is None else self.excluded
        return {s.name: {k: a - b - x for k, a, b, x in zip(CALLS, c, b0, x0)}
                for s, c, b0, x0 in zip(self.scene.subsystems + self.scene.signal_only, now, start, excluded)}

    def hand_over(self):
        """The rows booked so far to the writer threads now (the loop does every second); a durable run's
        are in the files when it returns (a process killed outright keeps them)."""
        tables = [t for t in (getattr(self, "steps", None), getattr(self, "trajectory", None)) if t is not None]
        for table in tables:
            table.hand_over()
        for table in tables if self.durable else ():
            table.wait()

    def step_in_progress(self):
        """The macro-step being made now (inside a kernel call: the one the kernel is at)."""
        if self.in_block is not None:
            return self.master.route().step_in_progress()
        return self.steps_done

    def salvage(self):
        """After a fault inside a kernel call (which never returned): book the steps it made before it."""
        n0, self.in_block = self.in_block, None
        if n0 is None:
            return
        done, log = self.master.route().salvage(n0)
        if done > 0:
            self._after_block(n0, log.first(done))

    def catch_up(self, end):
        """Make the steps up to end - 1 (after a fault in the lockstep reference, which made them)."""
        n = self.steps_done
        while n < end:
            n += self.advance(n, min(self.block_size(n), end - n))

    def rescue(self, error):
        """After a fault (run/containment.py): the files written with the error's status; the FMUs are
        left as they are (one of them faulted, and its process ends next)."""
        self.finish(error.status, str(error), release=False)

    def _record(self, n, log, reading):
        self.steps_done = n + 1
        self.iterations[0] += log.iterations
        self.iterations[1] = max(self.iterations[1], log.iterations)
        s = self.scratch
        s[0], s[1], s[2], s[3] = self.time_of(n + 1), log.iterations, log.residual, REASONS.index(log.reason)
        if (n + 1) % self.every and n + 1 != self.n_steps:
            return
        self.steps.next_row()[:] = s
        self.steps.commit_row()
        row = self.trajectory.next_row()
        row[0], row[1:] = self.time_of(n + 1), reading.outputs
        self.trajectory.commit_row()

    def _simulated(self, n):
        """The simulated time of n steps."""
        return self.time_of(n) - self.t0 if self.master is not None and self.master.variable else n * self.dt

    def fmu_calls(self):
        """doStep, save and restore calls the run made, over every FMU (observers' probes excluded)."""
        by = self.fmu_calls_by_subsystem().values()
        return {k: sum(c[k] for c in by) for k in CALLS}

    def summary(self, status, message):
        settings, sc = self.scenario.master, self.scenario
        n, iters = self.steps_done, self._iteration_totals()
        out = {"label": self.label, "scenario": sc.name, "master": settings.algorithm, "K": settings.K,
               "eps": settings.eps, "dt": sc.dt, "T": sc.T, "start_time": sc.start_time, "times_from": sc.times_from,
               "steps": n, "status": status, "message": message,
               "iterations_mean": iters[0] / n if n else 0.0, "iterations_max": iters[1],
               "wall_time_s": self.master_time, "total_time_s": time.perf_counter() - self.started,
               "loop_time_s": self.loop_time,
               "real_time_factor": self._simulated(n) / self.master_time if self.master_time > 0 else float("nan"),
               "fmu_calls": self.fmu_calls(), "fmu_calls_by_subsystem": self.fmu_calls_by_subsystem(),
               "output_interval": self.every,
               "energy_guard": self.guard_mode, "block_steps": self.block_steps,
               "quirks": {name: {"no_set_fmu_state_prior": d.no_set_fmu_state_prior, "chosen_by": d.chosen_by}
                          for name, d in self.scene.decisions.items()}, "notes": list(self.scene.notes)}
        for o in self.observers:
            out.update(o.summary())
        if self.master is not None:
            out.update(self.master.run_info())
            out.update(self.scene.port_info())
            out.update(self.scene.signal_info())
        return out

    def finish(self, status, message, release=True):
        """Close the tables and parts (the FMUs only with release), write summary.json (and metadata.json,
        MAT files); the RunResult. The rows still to write count in the run's own time (loop_time_s)."""
        started = time.perf_counter()
        self.write_error = self._close_tables()
        if self.write_error is not None and status == "finished":
            status, message = self.write_error.status, str(self.write_error)
        self.loop_time += time.perf_counter() - started
        status, message = self._verdict(status, message)
        summary = self.summary(status, message)
        if release:
            self.close()
        result = RunResult(self.label, self.scenario.master.algorithm, self.scenario.master.K, self.columns,
                           self.sampler.units, list(self.scenario.error), self.trajectory, self.steps,
                           getattr(self, "first", {}), summary, status, message)
        if self.out_dir is not None:
            try:
                self._write_files(result)
            except OutputError as exc:
                self.write_error = self.write_error or exc
        return result

    def _verdict(self, status, message):
        """A finished run that an observer found suspect (a frozen FMU) is `suspect`, with why."""
        why = [v for v in (o.verdict() for o in self.observers) if v]
        if status != "finished" or not why:
            return status, message
        return "suspect", "; ".join(why + ([message] if message else []))

    def units(self):
        """{"trajectory": {column: unit}, "steps": {column: unit}} of the recorded columns: the outputs'
        from the FMUs' modelDescriptions, the steps' from their descriptions (STEP_DESCRIBED, the
        observers'); "" where no unit is known."""
        steps = {c: STEP_DESCRIBED[c][1] for c in STEP_COLUMNS}
        if not MASTERS[self.scenario.master.algorithm].wave:     # a residual of port variables of any unit
            steps["inner_residual"] = ""
        for o in self.observers:
            steps.update({c: o.unit(c) for c in o.columns})
        if "error" in steps:                     # the units of the error columns (one, when they share it)
            steps["error"] = ", ".join(dict.fromkeys(self.sampler.units.get(c, "") for c in self.scenario.error))
        return {"trajectory": {"time": "s", **self.sampler.units}, "steps": steps}

    def _close_tables(self):
        """Write the last rows and close the files; the first OutputError (disk full, ...) or None.
        A table that could not write keeps its file to whole rows."""
        tables = [t for t in (getattr(self, "trajectory", None), getattr(self, "steps", None))
                  if t is not None and t.path is not None]                   # a table without a file: nothing to write
        errors = []
        for close in [t.flush for t in tables] + [t.close for t in tables]:     # both files' last rows at once
            try:
                close()
            except OutputError as exc:
                errors.append(exc)
        if self.fmu_log is not None:
            try:
                self.fmu_log.close()
            except OSError as exc:
                errors.append(cannot(self.fmu_log.path, exc))
        return errors[0] if errors else None

    def _write_files(self, result):
        name = (lambda kind, ext: self.out_dir / f"{kind}{self.suffix}.{ext}")
        write_json(name("summary", "json"), result.summary)
        write_json(name("metadata", "json"), run_metadata(self.scenario, self.scene, self.units()))
        if "mat" in self.formats:
            write_mat(name("trajectory", "mat"), self.trajectory)
            write_mat(name("steps", "mat"), self.steps)

    def close(self):
        """Release the master and the FMUs (idempotent)."""
        if self.master is not None:
            self.master.close()
            self.scene.close()
            self.master = None


def run(scenario, out_dir=None, *, label=None, reference=None, certificates=True, progress=None, warn=None,
        file_suffix=True, output_interval=1, formats=("csv",), max_steps=MAX_STEPS) -> RunResult:
    """Run `scenario` with its master; stream trajectory.csv and steps.csv into out_dir when given.

    reference: None (no errors), a RunResult of the monolithic reference, or "lockstep" (run the
    monolithic reference alongside, writing its files with the label "monolithic"; only where the
    scene has power bonds: without them there is no interface to solve monolithically). Raises
    RunFailed (with .result) on a failure, Interrupted (with .result) on Ctrl-C; a run of more than
    max_steps macro-steps is refused before anything is opened or allocated."""
    check_steps(scenario, max_steps)
    warn = _once(warn or _warn_stderr)                 # the lockstep reference repeats set-up notes
    if reference == "lockstep" and (not scenario.couplings or scenario.master.tolerance is not None):
        reference = None                   # no same-grid reference for a varying step: true_error instead
    live = LiveRun(scenario, out_dir, label, certificates, warn, file_suffix, output_interval, formats)
    ref = None
    try:
        rows = None
        if not scenario.couplings:         # no power bond: no monolithic reference, no errors
            reference = None
        if reference == "lockstep":
            try:
                ref = LiveRun(reference_scenario(scenario), out_dir, "monolithic", False, warn, True,
                              output_interval, formats, share=live.scene)
            except ConfigError as exc:     # e.g. an FMU without state save that only the reference rolls back
                raise type(exc)(f"{exc} (needed by the monolithic reference; --no-reference runs without it)") from None
            reference = lambda k: ref.recent.get(k)          # noqa: E731  (ref steps first)
        elif reference is not None:
            reference, rows = stored_reference(reference), stored_rows(reference)
        if reference is not None:
            for observer in error_observers(live.columns, live.sampler.types, scenario.error, reference, rows):
                live.add_observer(observer)
    except BaseException:
        live.close()
        raise
    contain = containment.current()
    if contain is not None:
        contain.watch(live, ref)
    status, error = _loop(live, ref, progress, contain)
    _raise_before_first_row(status, error, live, ref)
    message = str(error) if error else ""
    if isinstance(error, Interrupted):
        message = f"{error} after {live.steps_done} steps"
    result = live.finish(status, message)
    if ref is not None:
        result.reference = ref.finish(status, message)
    if status == "interrupted":
        raise type(error)(message, result)
    failure = error if status != "finished" else None            # SimulationEnded finishes a run
    failure = failure or live.write_error or (ref.write_error if ref is not None else None)
    if failure is not None:
        raise RunFailed(failure, result) from failure
    return result


def _raise_before_first_row(status, error, live, ref):
    """A run that failed before one of its parts had its first row (an FMU's NaN at t = 0 in the
    reference, which starts first) has nothing to write: its FMUs are released and its error raised."""
    parts = [p for p in (ref, live) if p is not None]
    if status in ("finished", "interrupted") or all(p.calls_at_start is not None for p in parts):
        return
    for part in parts:
        part.close()
    raise error


def check_steps(scenario, max_steps=MAX_STEPS):
    """A ConfigError when the scenario has more than max_steps macro-steps (None: no limit)."""
    if max_steps is not None and scenario.n_steps > max_steps:
        raise ConfigError(f"{scenario.source}: T / dt = {scenario.n_steps:,} macro-steps, over the limit of "
                          f"{max_steps:,} (pass --force, or max_steps=None in Python, to run it anyway)")


def _loop(live, ref, progress, contain=None):
    """Every macro-step of the run (and of its lockstep reference); returns (status, exception).
    Rows go to the writer at least every HAND_OVER_S seconds (DURABLE_S in a supervised run); a
    supervised run (contain) is told which run makes the next steps."""
    every = max(1, live.n_steps // 200)
    active = contain.active if contain is not None else (lambda part: None)
    hand_over_s = HAND_OVER_S if contain is None else DURABLE_S
    for part in (live, ref) if contain is not None else ():
        if part is not None:
            part.make_durable()
    with Interrupts() as stop:
        try:
            for part in (ref, live):
                if part is not None:
                    active(part)
                    part.start()
            n, handed = 0, time.perf_counter()
            while live.more(n):
                count = live.block_size(n)
                if ref is not None:
                    active(ref)
                    count = min(count, ref.lead(n, n + count) - n)
                    if count <= 0:
                        raise ref.failure
                active(live)
                done = live.advance(n, count)
                live.restores.after(n + done)
                stop.check()
                if progress and ((n + done) // every > n // every or not live.more(n + done)):
                    progress(live.progress_of(n + done), live.n_steps)
                n += done
                if time.perf_counter() - handed > hand_over_s:
                    for part in (ref, live):
                        if part is not None:
                            part.hand_over()
                    handed = time.perf_counter()
        except KeyboardInterrupt:
            error = Terminated if stop.signal == signal.SIGTERM else Interrupted
            return "interrupted", error("stopped by SIGTERM" if stop.signal == signal.SIGTERM
                                        else "interrupted by the user")
        except SimulationEnded as exc:              # an FMU ended it: finished, with the steps before
            return "finished", exc
        except WavecosimError as exc:
            exc = named_for_cause(live.scene, exc)
            return exc.status, exc
    return "finished", None


def reference_scenario(scenario):
    """The monolithic reference of a scenario: interface Newton at every macro-step."""
    return scenario.with_master(algorithm="newton")
