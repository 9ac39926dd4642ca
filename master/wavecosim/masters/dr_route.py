"""The kernel route of `master.algorithm: dr` (a base.Route): blocks of macro-steps in one call of the
C kernel, each guarded as FastDRMaster.step guards it, bit for bit its Python reference made step
by step. FastDRMaster makes one when its kernel runs and gives it from route()."""
import math
import time

from ..kernel.drkernel import REASONS
from .ledger import EnergyLedger
from .steplog import StepLog

BLOCK_SECONDS = 0.25      # run_steps makes about this much work at most, so Ctrl-C and progress stay prompt


class DRRoute:
    """The route of a FastDRMaster whose kernel runs: it drives the master's kernel, thread planner and
    guard, and books each call's steps on the master (FastDRMaster._book)."""

    def __init__(self, master):
        self.master = master
        self._step_s = 0.0        # seconds per macro-step of the last run_steps call
        self._call = 0            # n0 of the last kernel call (salvage after a fault inside it)

    def can_run_steps(self, n):
        """Whether run_steps may make macro-step n: the kernel runs and no thread plan is on trial
        (threads=auto times each on one macro-step, alone)."""
        return self.master.kernel is not None and not self.master.planner.on_trial

    def observe(self, names, steps=0, bound=None):
        """The variables of each subsystem run_steps reads after every commit (names[i], H_i first),
        with room for blocks of `steps` steps made now, and the growth bound on some of them; returns
        an empty BlockLog of the blocks' layout."""
        return self.master.kernel.observe(names, steps, bound)

    def set_passes(self, passes):
        """The passes run_steps makes as the kernel logs the steps (kernel/drkernel.py, Kernel.set_passes)."""
        self.master.kernel.set_passes(passes)

    def run_steps(self, n0, count, H_cap=None, passes=False):
        """Macro-steps n0 .. n0 + count - 1 in one kernel call, stopping early after a step whose H
        may exceed H_cap (None: the monolithic guard's cap) or whose observed values are not finite
        (kernel/drkernel.py Kernel.run_steps), and making no more than about BLOCK_SECONDS of work: (steps
        done, their BlockLog, the FmuError of the step after them or None); passes: the kernel makes
        its passes (set_passes) as it goes. The energy ledger is kept inside the call; a step it
        stopped after otherwise has its guard's verdict in the log's `last`. b^n and b^{n+1} of the
        last step done become the master's, so _undo_step works as after step()."""
        m = self.master
        ledger = isinstance(m.guard, EnergyLedger)
        if H_cap is None:
            H_cap = getattr(m.guard, "cap", math.inf)
        if not m.planner.started:
            done, log, error = self._first_steps(n0, count, H_cap, passes)
        else:
            done, log, error = self._kernel_steps(n0, count, H_cap, passes)
        if ledger and done:
            m.guard.book(log, m._redo_doSteps())
        elif log.stopped and done:
            log.last = self._judged(n0 + done - 1, self.step_log(log, done - 1))
        return done, log, error

    def _judged(self, n, log):
        """The StepLog of step n after its guard's verdict (the guard may redo it)."""
        m = self.master
        return log if m.guard is None else m.guard.after_commit(n, m.t0 + n * m.dt, log)

    def _first_steps(self, n0, count, H_cap, passes):
        """The first call: macro-step n0 alone and timed picks the thread plan, then the others
        follow in a second call unless a plan goes on trial (on the next step, alone)."""
        m = self.master
        done, first, error = self._kernel_steps(n0, 1, H_cap, passes)
        if not done or first.stopped or m.planner.on_trial or count == 1:
            return done, first, error
        done, rest, error = self._kernel_steps(n0 + 1, count - 1, H_cap, passes, at=1)    # logged after the first
        return done + 1, m.kernel.joined_log(done + 1, rest.stopped), error

    def _kernel_steps(self, n0, count, H_cap, passes, at=0):
        """One call of the kernel, of at most about BLOCK_SECONDS at the last call's pace, booked; it
        logs after the last call's first `at` steps (kernel/drkernel.py Kernel.run_steps). The thread planner
        may have it time the evaluations."""
        m = self.master
        if self._step_s > 0.0:
            count = max(1, min(count, int(BLOCK_SECONDS / self._step_s)))
        measure, _ = m.planner.begin()
        started = time.perf_counter()
        if m._certs is not None:
            m._certs.arm(n0, count)
        self._call, b_n, a_n = n0, m._b, m._a_before
        done, log, error = m.kernel.run_steps(n0, count, H_cap, measure, at, passes)
        if m._certs is not None:
            error = m._certs.disarm(done) or error
        if done:
            self._step_s = (time.perf_counter() - started) / done
            rounds = 1.0 + float(log.iterations.mean()) + float(log.ledger["rounds"].mean())
            m.planner.end(measure, self._step_s / rounds)
        m._book(n0, done, log, b_n, a_n)
        return done, log, error

    def step_in_progress(self):
        """The macro-step the kernel is making now (asked from another thread during run_steps)."""
        return self.master.kernel.step_in_progress()

    def salvage(self, n0):
        """The steps from n0 the kernel call in progress (begun at self._call) logged before a fault."""
        m = self.master
        made = m.kernel.step_in_progress()
        if m._certs is not None:
            m._certs.disarm(made - self._call)
        log = m.kernel.joined_log(made - n0, False)
        if isinstance(m.guard, EnergyLedger) and made > n0:
            m.guard.book(log, m._redo_doSteps())
        return made - n0, log

    def step_log(self, log, j):
        """The StepLog of row j of a BlockLog (without u^0 and u^K)."""
        return StepLog(iterations=int(log.iterations[j]), residual=float(log.residual[j]),
                       reason=REASONS[int(log.reason[j])], a_hat=log.a_hat[j].tolist())
