"""One run while it runs (LiveRun): set up the parts, step them, summarise.

    live = LiveRun(scenario, ...)        scene, master, sampler, observers, recorder tables
    live.start()                         reading at t = 0, first rows
    for n in range(N): live.step(n)      before_step, master.step, after_step, one row
    live.finish(status, error)           summary.json, metadata.json, the RunResult

When the master has a route (the C kernel's run_steps) and every observer takes many steps at once
(Observer.after_block), `advance` makes blocks of up to BLOCK_STEPS steps (run/blockrun.py): the
same numbers as step by step, to the last bit, without crossing into Python at every step.
"""
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import WavecosimError
from ..fmi.fmu import CALLS                # the FMU calls a run counts (fmu_calls)
from ..fmi.values import BOOLEAN, INTEGER, category
from ..kernel.drkernel import REASONS as KERNEL_REASONS
from ..kernel.linalg import total
from ..masters.base import REASONS
from .bounds import Bounds
from .durable import TextLog
from .observers import Observer
from .observers.errors import ErrorTracker
from .recorder import BLOCK, Labels, Table, Texts, ints
from ..core.quirks import RestoreWatch
from ..core.readings import Sampler
from ..fmi.messages import LogFile
from .blockrun import BlockSteps
from .closing import RunFiles
from .parts import STEP_COLUMNS, make_observers, open_parts, _warn_stderr
from .result import grid_clock

BLOCK_STEPS = BLOCK                    # macro-steps per call of the master, at most a table block (1: step by step)
assert REASONS[:len(KERNEL_REASONS)] == KERNEL_REASONS     # the kernel's reason codes are the runner's


class LiveRun(BlockSteps, RunFiles):
    """One run while it runs; it owns its parts and closes them."""

    def __init__(self, scenario, out_dir=None, label=None, certificates=True, warn=None, file_suffix=True,
                 output_interval=1, formats=("csv",), share=None):
        self.scenario, self.warn = scenario, warn or _warn_stderr
        settings = scenario.master
        self.label = label or f"{settings.algorithm}_K{settings.K}"
        self.scene, self.master, tuner = open_parts(scenario, self.warn, share)
        self.observers = make_observers(scenario, self.scene, self.master, tuner, certificates, self.warn)
        self.guard_mode = (settings.energy_guard or self.master.default_guard) if self.master.guardable else "n/a"
        self.guard = self.master.guard                 # its figures go into summary.json
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
        self.durable, self.memory = False, None             # a supervised run; the folder of its tables' memory
        self.texts = None                                   # its String outputs' TextLog
        self.write_error = None                             # an OutputError met while finishing
        self.calls_at_start = self.excluded = None          # set by start(): a run that failed before has none

    def more(self, n):
        """Whether steps are left after n: the fixed grid's count, or the varying step's end time."""
        return self.master.more(n) if self.master.variable else n < self.n_steps

    def add_observer(self, observer: Observer):
        """Before start(): one more observer (e.g. the error tracker), acting last."""
        self.observers.append(observer)

    def _tables(self):
        rows = self.n_steps // self.every + 2
        path = (lambda kind: self.out_dir / f"{kind}{self.suffix}.csv") if self.out_dir else (lambda kind: None)
        shared = (lambda kind: self.memory / kind) if self.memory else (lambda kind: None)
        self.trajectory = Table(["time", *self.columns], path("trajectory"), expected_rows=rows,
                                formats=self._output_formats(), durable=shared("trajectory"))
        obs_cols = [c for o in self.observers for c in o.columns]
        formats = {"iterations": ints, "reason": Labels(REASONS)}
        for o in self.observers:
            formats.update(o.formats)
        self.steps = Table([*STEP_COLUMNS, *obs_cols], path("steps"), expected_rows=rows, formats=formats,
                           durable=shared("steps"))
        texts = {j: f.texts for j, f in enumerate(self.trajectory.formats) if isinstance(f, Texts)}
        self.texts = TextLog(self.memory / "texts.jsonl", texts) if self.memory and texts else None
        self._describe_rows()
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
        self._commit_trajectory()
        self.bounds.start(first, self.time_of)
        self.first = {"H": total(first.H), "error": next((o.first for o in self.observers
                                                        if isinstance(o, ErrorTracker)), math.nan)}
        self.bracket = any(type(o).before_step is not Observer.before_step for o in self.observers)
        self.after = list(zip(self.observers, self.slices))
        self.recent = {0: first.outputs}
        self._plan_blocks()
        self.restores = RestoreWatch(self.scene, self.master.needs_rollback and self.durable)
        self.calls_at_start = self._counts()
        self.loop_started = time.perf_counter()

    def step(self, n):
        """Macro-step n: observers before, the master (its guard may redo the step), observers after,
        one row; returns the Reading of the FMUs after it."""
        t = self.time_of(n) if self.master.variable else self.t0 + n * self.dt
        if not self.master.variable:                 # a varying step holds them per try (masters/adaptive.py)
            self.scene.begin_step(n, t)              # signals held, signal-only subsystems stepped
        before = self._counts() if self.bracket else None
        for o in self.observers:
            o.before_step(n, t)
        if before is not None:                       # observers' own FMU calls are not the master's
            self._exclude(before)
        t0 = time.perf_counter()
        log = self.master.step(n, t)
        self.master_time += time.perf_counter() - t0
        reading = self._after_master(n, t, log)
        if self.scene.ended is not None:            # an FMU ended the simulation with this step
            raise self.scene.ended
        return reading

    def _after_master(self, n, t, log, reading=None):
        """After the master made step n: read the FMUs (unless the reading is given), the observers, one row."""
        reading = self.sampler.read() if reading is None else reading
        for o, row in self.after:
            o.after_step(n, t, log, reading, row)
        self._record(n, log, reading)
        self.bounds.check(reading, n)
        self.loop_time = time.perf_counter() - self.loop_started
        return reading

    def block_size(self, n):
        """How many macro-steps advance(n, ...) may make in one call of the master."""
        if self._alone(n):
            return 1
        end = min(self.n_steps, self.restores.next)              # a block ends where the restore is checked
        return min([BLOCK_STEPS, end - n] + [o.next_before(n) - n for o in self.paced])

    def _alone(self, n):
        """Whether macro-step n is made by step(): no block can run now, a paced observer acts before
        it, or BLOCK_STEPS is 1 (every step alone). Otherwise even a last single step is a block."""
        return (BLOCK_STEPS == 1 or not (self.blocks and self.route.can_run_steps(n))
                or any(o.next_before(n) <= n for o in self.paced))

    def make_durable(self, folder):
        """A supervised run (before start): its tables' rows live in memory mapped from files in `folder`
        (the run's channel), described in rows.json there, so the parent writes every committed row
        when the process is killed outright (run/salvage.py). Its restores are re-checked."""
        self.durable, self.memory = True, Path(tempfile.mkdtemp(prefix="rows-", dir=folder))

    def _describe_rows(self, late=()):
        """rows.json of a durable run: its two tables (late: the steps' columns filled only after a block)."""
        if self.memory is None or self.trajectory.shared is None or self.steps.shared is None:
            return
        described = {"trajectory": self.trajectory.described(), "steps": self.steps.described(late)}
        part = self.memory / "rows.json.part"
        part.write_text(json.dumps(described))
        part.replace(self.memory / "rows.json")

    def advance(self, n, count):
        """Macro-steps from n on: up to `count` in one call of the master where a block can run, else
        step(n); then the restore re-checked where it is due; returns how many were made."""
        if count == 1 and self._alone(n):
            self.step(n)
            done = 1
        else:
            done = self.step_block(n, count)
        self._recheck_restores(n + done)
        return done

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

    def _recheck_restores(self, n):
        """After n steps: the restore re-checked where it is due (RestoreWatch), its FMU calls, the
        run's own check, left out of fmu_calls as the observers' are."""
        if n != self.restores.next:
            return
        before = self._counts()
        try:
            self.restores.after(n)
        finally:
            self._exclude(before)

    def _exclude(self, before):
        """Leave the FMU calls made since the counts were `before` out of fmu_calls."""
        now = self._counts()
        if now != before:
            self.excluded = [tuple(x + a - b for x, a, b in zip(*c)) for c in zip(self.excluded, now, before)]

    def _counts(self):
        """Each FMU's calls so far (CALLS, its own counters), one tuple per subsystem: those with a port,
        then those stepped alone."""
        return [tuple(s.fmu.calls) for s in self.scene.subsystems + self.scene.signal_only]

    def fmu_calls_by_subsystem(self):
        """{subsystem: its FMU calls (CALLS) from the first step on}, observers' probes excluded."""
        now = self._counts()
        start = now if self.calls_at_start is None else self.calls_at_start     # before the first step: none yet
        excluded = [(0,) * len(CALLS)] * len(now) if self.excluded is None else self.excluded
        return {s.name: {k: a - b - x for k, a, b, x in zip(CALLS, c, b0, x0)}
                for s, c, b0, x0 in zip(self.scene.subsystems + self.scene.signal_only, now, start, excluded)}

    def hand_over(self):
        """The rows booked so far to the writer threads now (the loop does every second)."""
        for table in (getattr(self, "steps", None), getattr(self, "trajectory", None)):
            if table is not None:
                table.hand_over()

    def step_in_progress(self):
        """The macro-step being made now (inside a kernel call: the one the kernel is at)."""
        if self.in_block is not None:
            return self.route.step_in_progress()
        return self.steps_done

    def salvage(self):
        """After a fault inside a kernel call (which never returned): book the steps it made before it."""
        n0, self.in_block = self.in_block, None
        if n0 is None:
            return
        done, log = self.route.salvage(n0)
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
        self._commit_trajectory()

    def _commit_trajectory(self):
        """Commit the trajectory's row filled; a durable run notes the texts it holds first."""
        if self.texts is not None:
            self.texts.note()
        self.trajectory.commit_row()

    def _simulated(self, n):
        """The simulated time of n steps."""
        return self.time_of(n) - self.t0 if self.master is not None and self.master.variable else n * self.dt

    def fmu_calls(self):
        """The FMU calls (CALLS) the run made, over every FMU (observers' probes excluded)."""
        by = self.fmu_calls_by_subsystem().values()
        return {k: sum(c[k] for c in by) for k in CALLS}

    def close(self):
        """Release the master and the FMUs (idempotent)."""
        if self.master is not None:
            self.master.close()
            self.scene.close()
            self.master = None


