"""The kernel route of the classical masters, as a mixin: the ClassicalKernel (wavecosim/kernel/classical.py)
when `master.fast` allows it, and blocks of macro-steps in one kernel call when the runner asks, through
the same seams as FastDRMaster (fast, can_run_steps, observe, run_steps, step_log). There is a route
only without an energy guard (their default): the ledger is kept step by step for them."""
import math
import time

from ..kernel.classical import ClassicalKernel
from ..kernel.drkernel import REASONS
from .base import KernelOwner, StepLog, kernel_refusal
from .dr_route import BLOCK_SECONDS
from .threads import ThreadPlanner


class KernelRoute(KernelOwner):
    """What a classical master with a kernel route adds: `kernel` (a ClassicalKernel, or None and
    the Python reference runs), `fast_note` (why), blocks of macro-steps in one kernel call (the
    runner's run_steps seam, as FastDRMaster's), and their summary and release. The master sets
    the kernel's budget (`configure_kernel`), books its steps on the Subsystems (`book_kernel`) and
    takes a block's last state (`took_block`)."""

    def attach_kernel(self, scene, settings, blocks=True):
        """The kernel when master.fast allows it; blocks: it makes whole macro-steps (else only the
        passes, the master's update staying in Python)."""
        self.kernel, self.blocks, self.planner = None, blocks, None      # planner: masters/threads.py
        self._step_s = 0.0                     # seconds per macro-step of the last run_steps call
        self.fast_note = kernel_refusal(scene, str(settings.fast).lower())
        if self.fast_note is None:
            explicit = not self.needs_rollback
            self.kernel = ClassicalKernel(scene.kernel_scene(), self.G, explicit, self.sequential)
            self.fast_note = "C kernel" if blocks else "C kernel passes, the update in Python"
            self.planner = ThreadPlanner(self.kernel.base, settings.threads, len(self.subsystems),
                                         independent=not self.sequential)

    def run_info(self):
        """The route and the thread plan of its passes (serial on the Python reference)."""
        threads, note = (self.planner.threads, self.planner.note) if self.planner else (1, "serial")
        return {**super().run_info(), "threads": threads, "thread_note": note}

    def planned(self, step):
        """step(measure) -> (io, ...), a kernel macro-step made under the thread plan: timed when the
        planner asks (its evaluations, or its round for a plan on trial)."""
        measure, timed = self.planner.begin()
        started = time.perf_counter()
        out = step(measure)
        if timed:
            self.planner.end(measure, (time.perf_counter() - started) / (out[0].iterations + 1))
        return out

    def block_iterations(self, log):
        """The inner iterations of a block of kernel steps, all steps together."""
        return int(log.iterations.sum())

    @property
    def fast(self):
        """Whether the kernel route runs (the runner makes blocks of steps only then)."""
        return self.kernel is not None

    def route(self):
        """This master as its kernel route (base.Route) while the kernel makes its macro-steps."""
        return self if self.kernel is not None and self.blocks and self.guard is None else None

    def can_run_steps(self, n):
        """The kernel runs and no thread plan is on trial (it is timed on one macro-step, alone)."""
        return self.kernel is not None and self.blocks and not self.planner.on_trial

    def observe(self, names, steps=0, bound=None):
        """The variables of each subsystem run_steps reads after every commit (names[i], H_i first),
        with room for blocks of `steps` steps made now, and the growth bound on some of them; returns
        an empty BlockLog of the blocks' layout."""
        return self.kernel.base.observe(names, steps, bound)

    def set_passes(self, passes):
        """The passes run_steps makes as the kernel logs the steps (kernel/drkernel.py, Kernel.set_passes)."""
        self.kernel.base.set_passes(passes)

    def run_steps(self, n0, count, H_cap=math.inf, passes=False):
        """Macro-steps n0 .. n0 + count - 1 in one kernel call of at most about BLOCK_SECONDS of work,
        stopping early as FastDRMaster.run_steps: (steps done, their BlockLog, the FmuError or None);
        a stopped call's last step has its StepLog in the log's `last`."""
        if self._step_s > 0.0:
            count = max(1, min(count, int(BLOCK_SECONDS / self._step_s)))
        self.configure_kernel()
        measure, timed = self.planner.begin()
        started = time.perf_counter()
        done, log, error = self.kernel.run_steps(n0, count, self.y, H_cap, measure, passes)
        if done:
            self._step_s = (time.perf_counter() - started) / done
            iterations = self.block_iterations(log)
            if timed:
                self.planner.end(measure, self._step_s * done / (done + iterations))
            last = n0 + done - 1
            self.book_kernel(last, self.t0 + last * self.dt)
            self.took_block(log, done)
            if log.stopped:
                log.last = self.step_log(log, done - 1)
        return done, log, error

    def step_in_progress(self):
        return self.kernel.base.step_in_progress()

    def salvage(self, n0):
        """The steps from n0 the kernel call in progress logged before a fault."""
        made = self.kernel.base.step_in_progress() - n0
        return made, self.kernel.base.joined_log(made, False)

    def step_log(self, log, j):
        """The StepLog of row j of a BlockLog."""
        return StepLog(iterations=int(log.iterations[j]), residual=float(log.residual[j]),
                       reason=REASONS[int(log.reason[j])])
