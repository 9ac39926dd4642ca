"""The kernel route of the classical masters, as a mixin: the ClassicalKernel (wavecosim/kernel/classical.py)
when `master.fast` allows it, and blocks of macro-steps in one kernel call when the runner asks, through
the same seams as FastDRMaster (fast, can_run_steps, observe, run_steps, step_log). The runner makes
blocks only without an energy guard (their default): the ledger is kept step by step for them."""
import math
import time

from ..kernel.classical import ClassicalKernel, refusal
from ..kernel.drkernel import REASONS
from .base import KernelOwner, StepLog
from .dr_fast import BLOCK_SECONDS


class KernelRoute(KernelOwner):
    """What a classical master with a kernel route adds: `kernel` (a ClassicalKernel, or None and
    the Python reference runs), `fast_note` (why), blocks of macro-steps in one kernel call (the
    runner's run_steps seam, as FastDRMaster's), and their summary and release. The master sets
    the kernel's budget (`configure_kernel`), books its steps on the Subsystems (`book_kernel`) and
    takes a block's last state (`took_block`)."""

    def attach_kernel(self, scene, settings, has_route=True):
        self.kernel, self.fast_note = None, "Python reference (this master has no kernel route)"
        self._step_s = 0.0                     # seconds per macro-step of the last run_steps call
        if has_route:
            self.fast_note = refusal(scene, str(settings.fast).lower())
            if self.fast_note is None:
                explicit = not self.needs_rollback
                self.kernel, self.fast_note = ClassicalKernel(scene, self.G, explicit, self.sequential), "C kernel"

    keeps_ledger = False          # the ledger is kept step by step for these masters

    @property
    def fast(self):
        """Whether the kernel route runs (the runner makes blocks of steps only then)."""
        return self.kernel is not None

    def route(self):
        """This master as its kernel route (base.Route) while the kernel runs."""
        return self if self.kernel is not None else None

    def guards_steps(self):
        return False

    def keep_ledger(self, ledger, traffic, rtol):
        raise NotImplementedError("the classical masters keep the energy ledger step by step")

    def can_run_steps(self, n):
        return self.kernel is not None

    def observe(self, names, steps=0):
        """The variables of each subsystem run_steps reads after every commit (names[i], H_i first),
        with room for blocks of `steps` steps made now; returns an empty BlockLog of the blocks' layout."""
        return self.kernel.base.observe(names, steps)

    def run_steps(self, n0, count, H_cap=math.inf):
        """Macro-steps n0 .. n0 + count - 1 in one kernel call of at most about BLOCK_SECONDS of work,
        stopping early as FastDRMaster.run_steps: (steps done, their BlockLog, the FmuError or None)."""
        if self._step_s > 0.0:
            count = max(1, min(count, int(BLOCK_SECONDS / self._step_s)))
        self.configure_kernel()
        started = time.perf_counter()
        done, log, error = self.kernel.run_steps(n0, count, self.y, H_cap)
        if done:
            self._step_s = (time.perf_counter() - started) / done
            last = n0 + done - 1
            self.book_kernel(last, self.t0 + last * self.dt, int(log.iterations.sum()), done)
            self.took_block(log, done)
        return done, log, error

    def step_log(self, log, j):
        """The StepLog of row j of a BlockLog."""
        return StepLog(iterations=int(log.iterations[j]), residual=float(log.residual[j]),
                       reason=REASONS[int(log.reason[j])])
