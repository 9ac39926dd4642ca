"""Blocks of macro-steps: what LiveRun adds to make many steps in one call of its master's route,
with the same rows and figures as step by step, to the last bit."""
import math
import time

import numpy as np

from ..kernel import blocks
from ..kernel.drkernel import PASSES_CACHED, PASSES_EACH
from .observers import Observer
from .recorder import BLOCK

from .result import grid_inverse


class BlockSteps:
    """LiveRun's blocks: planned in set-up (_plan_blocks), made by step_block, booked by _after_block."""

    def _plan_blocks(self):
        """Blocks when the master can make them, every observer takes them and nothing acts before a
        step (a paced observer: before the steps it names; blocks stop before them)."""
        self.route = self.master.route()                 # chosen once, by the master
        self.blocks = (self.route is not None
                       and all(o.paced or type(o).before_step is Observer.before_step for o in self.observers)
                       and all(o.blocks for o, _ in self.after)
                       and not self.scene.steps_in_python and self.sampler.whole and blocks.library() is not None)
        self.paced = [o for o in self.observers if o.paced]          # blocks stop before their steps
        if self.blocks:
            layout = self.route.observe(self.sampler.observed, BLOCK,
                                         (self.bounds.limit, self.bounds.bounded(self.sampler.rows("outputs"))))
            self.block_observers = [(o, self.spans[id(o)]) for o in self.observers]
            self._prepare_blocks(layout)

    def _prepare_blocks(self, layout):
        """The C passes built in set-up, from an empty log of the blocks' layout, so the first block
        costs no more than the others; with every row kept the kernel makes them as it logs the steps
        (a durable run's after every step: the rows pass, the last, counts each row as it is written)."""
        readings = self.sampler.block(layout.observed)
        self.rows_pass = self._rows_pass(layout, readings)
        for o, _ in self.block_observers:
            o.prepare_block(layout, readings)
        self.observer_passes = [(o.block_pass(), span) for o, span in self.block_observers
                                if o.block_pass() is not None]
        self.passes = self.observer_passes + [(self.rows_pass, None)]
        self.python_observers = [(o, span) for o, span in self.block_observers if o.block_pass() is None]
        self.handing = [o for o, _ in self.block_observers if o.block_pass() is not None and (
            type(o).before_passes is not Observer.before_passes or type(o).after_passes is not Observer.after_passes)]
        self.column_passes = [(p, span) for p, span in self.observer_passes if span.stop > span.start]
        self.rows_pass.args.lds, self.rows_pass.args.ldt = self.steps.ld, self.trajectory.ld
        for p, _ in self.column_passes:
            p.args.ldo = self.steps.ld
        self.kernel_passes = (PASSES_EACH if self.durable else PASSES_CACHED) if self.every == 1 else 0
        if self.kernel_passes:
            self.route.set_passes([p for p, _ in self.passes])
            self._describe_rows([j for _, span in self.python_observers for j in range(span.start, span.stop)])

    def step_block(self, n0, count):
        """Macro-steps n0 .. n0 + count - 1 in one call of the master; the master stops early after a
        step its guard must judge (or with a non-finite value), which is then recorded as in step()
        (the ledger is kept, and redone, in the kernel: such a step is in the block, and a non-finite
        value ends the run after it). Returns the steps made; raises the FmuError of the step after them."""
        if self.kernel_passes:
            self._aim(self.steps.reserve_at(count), self.trajectory.reserve_at(count), counted=True)
        for o in self.handing:
            o.before_passes()
        t0 = time.perf_counter()
        self.in_block = n0
        done, log, error = self.route.run_steps(n0, count, passes=self.kernel_passes)
        self.in_block = None
        self.master_time += time.perf_counter() - t0
        self.block_steps += done
        whole = done - 1 if log.last is not None else done      # the ledger's kernel books every step
        if whole:
            self._after_block(n0, log.first(whole))
        if whole < done:
            n = n0 + whole
            self._after_master(n, self.t0 + n * self.dt, log.last)
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
        for o in self.handing:
            o.after_passes()
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

    def _aim(self, steps_at, trajectory_at, counted=False):
        """The C passes of a block at its first row of the steps and of the trajectory (addresses; the
        tables' ld between columns): the observers' columns are spans of the steps'. counted: at the
        tables' own rows, which a durable table's record counts as the rows pass writes them."""
        args, ld = self.rows_pass.args, self.steps.ld
        args.steps, args.trajectory = steps_at, trajectory_at
        for j, table in enumerate((self.steps, self.trajectory)):
            shared = table.shared if counted else None
            args.counted[j], args.base[j] = (shared.address, table.rows) if shared is not None else (None, 0)
        for p, span in self.column_passes:
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

