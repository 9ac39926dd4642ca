"""`master.algorithm: dr`: the reference DRMaster with the macro-step run by the C kernel.

With `master.fast: auto` (the default) the kernel (wavecosim/kernel/drkernel.py) runs Algorithm 1 when its
library is built and every FMU can get and set its state; with `fast: false`, or when the kernel
cannot be used, `step` is the Python reference unchanged. Both give the same numbers to the last
bit, and the same FMU call counts.

Threads (`master.threads`, masters/threads.py): the first macro-step runs serially and times one
evaluation of each subsystem; then `N` evaluates the subsystems on min(N, CPUs, subsystems) threads
(longest evaluation first, each onto the least loaded thread) and `auto` adds threads only while
they pay, each plan tried on one macro-step alone; the costs are timed again while threads run and
the plan re-balanced when they drift. Each thread writes only its own subsystems' outputs and the
caller does all the arithmetic, so the thread plan never changes a number.
"""
import math
import time

from ..kernel.drkernel import REASONS, Kernel
from ..kernel.certs import KernelCertificates, supports
from ..kernel.newton import NewtonKernel
from .base import StepLog, kernel_refusal
from .dr import DRMaster
from .threads import ThreadPlanner
from .dr_options import STARTS

BLOCK_SECONDS = 0.25      # run_steps makes about this much work at most, so Ctrl-C and progress stay prompt


class FastDRMaster(DRMaster):
    """`master.algorithm: dr`. Algorithm 1 runs in the C kernel when `fast` allows it, otherwise in
    the reference DRMaster.step; the result is the same to the last bit either way.

    `fast` (bool) says which path runs and `fast_note` why; `threads` and `thread_note` tell the
    thread plan once it is chosen (after the first macro-step)."""

    def __init__(self, scene, settings):
        super().__init__(scene, settings)
        self.kernel, self.fast, self.planner = None, False, None
        self.guarded = None       # the kernel's BlockLog of the last step when step() made the ledger's guard too
        self._guarding = False    # keep_ledger was called: step() makes iteration, commit and redo in one call
        self._newton = None       # the certificates' interface Newton in C (kernel/newton.py NewtonKernel), when asked
        self._certs = None        # the certificates inside the blocks (kernel/certs.py KernelCertificates), when asked
        # the certificates' C passes need every port to be the FMU's own wave map (no wave adapter)
        self._exact = not any(s.adapter for s in scene.subsystems)
        self.fast_note = self._kernel_refusal(scene, str(settings.fast).lower())
        if self.fast_note is not None:
            return
        self._kernel_scene = scene.kernel_scene()        # what the kernel's bindings know of the scene
        self.kernel = Kernel(self._kernel_scene, self.P, self.J_L)
        self.kernel.configure(self.dt, self.K, self.eps, self.deadline_s)
        self.kernel.set_anchors((settings.energy_guard or self.default_guard) == "ledger")
        self._send_options()
        self.fast, self.fast_note = True, "C kernel"
        self.planner = ThreadPlanner(self.kernel, settings.threads, len(self.subsystems))
        self._step_s = 0.0        # seconds per macro-step of the last run_steps call
        self._call = 0            # n0 of the last kernel call (salvage after a fault inside it)
        self._redo_seen = 0       # the kernel's count of redo doSteps when redo_doSteps last looked

    def _send_options(self):
        """The named options to the kernel (it forgets b^{n-1} and the Anderson differences)."""
        s = self.settings
        self.kernel.set_options(self.relaxation, s.anderson, STARTS.index(self.start), s.anderson_memory,
                                s.anderson_extrapolate)

    @staticmethod
    def _kernel_refusal(scene, mode):
        """Why the reference path runs (None: the kernel can run); master.fast: true insists."""
        return kernel_refusal(scene, mode)

    def _set_b(self, b):
        super()._set_b(b)
        if self.kernel is not None:
            self.kernel.b[:] = [float(x) for x in b]

    def commit(self, a_hat):
        """A commit made from Python (a guard's redo): the kernel's a_hat, a^{n-1} of its next start, too."""
        super().commit(a_hat)
        if self.kernel is not None:
            self.kernel.a_hat[:] = [float(x) for x in a_hat]

    def undo_step(self):
        """x^n, b^n and a^{n-1} back (the kernel's start too)."""
        super().undo_step()
        if self.kernel is not None:
            self.kernel.set_previous(self._a_before)

    def _compile(self):
        super()._compile()
        if getattr(self, "kernel", None) is not None:
            self.kernel.set_maps(self.P, self.J_L)
        if getattr(self, "_newton", None) is not None:
            self._newton.set_map(self.P)

    def fixed_point(self, n, t):
        """b* in C (newton.c: nt_solve, the reference's Newton to the last bit) when the kernel runs a
        scene without wave adapters (their Python maps keep figures the C route would not book)."""
        if self.kernel is None or not self._exact:
            return super().fixed_point(n, t)
        return self._newton_kernel().solve(n, t, self._b)

    def _newton_kernel(self):
        if self._newton is None:
            self._newton = NewtonKernel(self._kernel_scene, self.P)
        return self._newton

    def kernel_certificates(self, floor):
        """The certificates inside this master's blocks (kernel/certs.py KernelCertificates; the watch keeps
        pairs above `floor`), made on the first ask; None where the blocks cannot compute them."""
        if self._certs is None and self.kernel is not None and self._exact and supports(self._kernel_scene):
            self._certs = KernelCertificates(self.kernel, self._newton_kernel(), self._kernel_scene, floor)
        return self._certs

    def retune(self, b):
        super().retune(b)
        if self.kernel is not None:
            self._send_options()                                   # b^{n-1} and the Anderson memory forgotten

    def reserve_time(self, seconds):
        super().reserve_time(seconds)
        if self.kernel is not None:
            self.kernel.configure(self.dt, self.K, self.eps, self.inner_deadline_s)

    def enable_trace(self, on=True):
        super().enable_trace(on)
        if self.kernel is not None:
            self.kernel.record(max(self.K, 1) if on else 0)
        return True

    def step(self, n, t) -> StepLog:
        if self.kernel is None:
            return super().step(n, t)
        kernel = self.kernel
        self.step_started = time.perf_counter()
        measure, timed = self.planner.begin()
        io, redone = self._kernel_step(n, t, measure)
        k = io.iterations
        if timed:   # K queries, the commit, the redo
            self.planner.end(measure, (time.perf_counter() - self.step_started) / (k + 1 + redone))
        self._note_kernel_steps(n, t, k, 1, redone)   # frozen at x^n (saved by the kernel), calls counted
        n_ch = kernel.n
        out = kernel.results[:]                  # b^{n+1}, a, u^0, u^K
        self._b_step_start, self._b = self._b, out[:n_ch]
        self._a_step_start, self._a_before = self._a_before, out[n_ch:2 * n_ch]
        if self._trace is not None:
            self._trace = kernel.recorded(k)
        u0, uK = (None, None) if redone else (out[2 * n_ch:3 * n_ch], out[3 * n_ch:])   # a redo's log has none
        return StepLog(iterations=k, residual=io.residual, reason=REASONS[io.reason], a_hat=out[n_ch:2 * n_ch],
                       u0=u0, uK=uK)

    def _kernel_step(self, n, t, measure):
        """Macro-step n in one kernel call: (its DRStep, the ledger's redo rounds). With the ledger kept
        (keep_ledger) the call is dr_run_steps of one step: iteration, commit, ledger check and redo,
        within master.deadline_us as in blocks, and its BlockLog goes to self.guarded."""
        if not self._guarding:
            self.guarded = None
            return self.kernel.macro_step(n, t, measure), 0
        _, self.guarded, error = self.kernel.run_steps(n, 1, math.inf, measure)
        if error is not None:
            raise error
        return self.kernel.io, int(self.guarded.ledger["rounds"][0])

    def redo_in_kernel(self, supplied, budget, left_s, round_s):
        """The energy ledger's redo of the step just made, by the kernel (kernel/drkernel.py Kernel.redo); its
        rounds are booked on the Subsystems and b^{n+1} becomes the redo's. Returns (s, supply,
        traffic, action, rounds, inputs committed)."""
        if self.kernel is None:
            return None
        done = self.kernel.redo(supplied, budget, left_s, round_s)
        self._b, self._a_before = self.kernel.b[:], self.kernel.a_hat[:]
        self._note_kernel_steps(self.subsystems[0].step_index, self.subsystems[0].t, 0, 0, done[4])
        return (*done, self.kernel.a_hat[:])

    keeps_ledger = True

    def route(self):
        """This master as its kernel route (base.Route) while the kernel runs."""
        return self if self.fast else None

    def can_run_steps(self, n):
        """Whether run_steps may make macro-step n: the kernel runs and no thread plan is on trial
        (threads=auto times each on one macro-step, alone)."""
        return self.kernel is not None and not self.planner.on_trial

    def observe(self, names, steps=0, bound=None):
        """The variables of each subsystem run_steps reads after every commit (names[i], H_i first),
        with room for blocks of `steps` steps made now, and the growth bound on some of them; returns
        an empty BlockLog of the blocks' layout."""
        return self.kernel.observe(names, steps, bound)

    def set_passes(self, passes):
        """The passes run_steps makes as the kernel logs the steps (kernel/drkernel.py, Kernel.set_passes)."""
        self.kernel.set_passes(passes)

    def guards_steps(self):
        """Whether step() can keep the energy ledger in the kernel (keep_ledger): whenever the kernel runs
        (it reads the wave adapters' accuracy, the ledger's tol, at each step)."""
        return self.kernel is not None

    def keep_ledger(self, ledger, traffic, rtol):
        """The energy ledger's state for the kernel's next steps and blocks, which it keeps within
        master.deadline_us (see kernel/drkernel.py Kernel.keep_ledger)."""
        self.kernel.keep_ledger(ledger, traffic, rtol, self.deadline_s)
        self._guarding = True

    def run_steps(self, n0, count, H_cap=math.inf, passes=False):
        """Macro-steps n0 .. n0 + count - 1 in one kernel call, stopping early after a step whose H
        may exceed H_cap or whose observed values are not finite (kernel/drkernel.py Kernel.run_steps), and
        making no more than about BLOCK_SECONDS of work: (steps done, their BlockLog, the FmuError
        of the step after them or None); passes: the kernel makes its passes (set_passes) as it goes.
        b^n and b^{n+1} of the last step done become the master's, so undo_step works as after step()."""
        if not self.planner.started:
            return self._first_steps(n0, count, H_cap, passes)
        return self._kernel_steps(n0, count, H_cap, passes)

    def _first_steps(self, n0, count, H_cap, passes):
        """The first call: macro-step n0 alone and timed picks the thread plan, then the others
        follow in a second call unless a plan goes on trial (on the next step, alone)."""
        done, first, error = self._kernel_steps(n0, 1, H_cap, passes)
        if not done or first.stopped or self.planner.on_trial or count == 1:
            return done, first, error
        done, rest, error = self._kernel_steps(n0 + 1, count - 1, H_cap, passes, at=1)    # logged after the first
        return done + 1, self.kernel.joined_log(done + 1, rest.stopped), error

    def _kernel_steps(self, n0, count, H_cap, passes, at=0):
        """One call of the kernel, of at most about BLOCK_SECONDS at the last call's pace, booked; it
        logs after the last call's first `at` steps (kernel/drkernel.py Kernel.run_steps). The thread planner
        may have it time the evaluations."""
        if self._step_s > 0.0:
            count = max(1, min(count, int(BLOCK_SECONDS / self._step_s)))
        measure, _ = self.planner.begin()
        started = time.perf_counter()
        if self._certs is not None:
            self._certs.arm(n0, count)
        self._call = n0
        done, log, error = self.kernel.run_steps(n0, count, H_cap, measure, at, passes)
        if self._certs is not None:
            error = self._certs.disarm(done) or error
        if done:
            self._step_s = (time.perf_counter() - started) / done
            rounds = 1.0 + float(log.iterations.mean()) + float(log.ledger["rounds"].mean())
            self.planner.end(measure, self._step_s / rounds)
        self._book(n0, done, log)
        return done, log, error

    def step_in_progress(self):
        return self.kernel.step_in_progress()

    def salvage(self, n0):
        """The steps from n0 the kernel call in progress (begun at self._call) logged before a fault."""
        made = self.kernel.step_in_progress()
        if self._certs is not None:
            self._certs.disarm(made - self._call)
        return made - n0, self.kernel.joined_log(made - n0, False)

    def redo_doSteps(self):
        """doSteps of the FMUs in the ledger's redos since the last ask (the kernel counts them: a wave
        adapter's query takes a varying number)."""
        made, self._redo_seen = self._redo_seen, self.kernel.redo_do_steps()
        return self._redo_seen - made

    def _book(self, n0, done, log):
        """Book macro-steps n0 .. n0 + done - 1 of the kernel: calls and step on the Subsystems, b^n, b^{n+1}."""
        if not done:
            return
        last = n0 + done - 1
        iterations, redone = int(log.iterations.sum()), int(log.ledger["rounds"].sum())
        self._note_kernel_steps(last, self.t0 + last * self.dt, iterations, done, redone)
        self._b_step_start = log.b[done - 2].tolist() if done > 1 else self._b
        self._b = self.kernel.b[:]
        self._a_step_start = log.a_hat[done - 2].tolist() if done > 1 else self._a_before
        self._a_before = self.kernel.a_hat[:]
        if self._trace is not None:
            self._trace = self.kernel.recorded(int(log.iterations[-1]))

    def _note_kernel_steps(self, n, t, iterations, steps=1, redone=0):
        """Book `steps` kernel macro-steps (the last one step n at t) and `redone` ledger redo rounds
        on the Subsystems; a wave adapter's FMU calls are its own count (its queries take a varying
        number of doSteps)."""
        for s in self.subsystems:
            if s.adapter:
                s.note_kernel_step(n, t, 0, 0)
                s.map.book()
            else:
                s.note_kernel_step(n, t, iterations, steps, redone)

    def step_log(self, log, j):
        """The StepLog of row j of a BlockLog (without u^0 and u^K)."""
        return StepLog(iterations=int(log.iterations[j]), residual=float(log.residual[j]),
                       reason=REASONS[int(log.reason[j])], a_hat=log.a_hat[j].tolist())

    @property
    def threads(self):
        """Threads evaluating the subsystems now (1 on the Python reference)."""
        return self.planner.threads if self.planner is not None else 1

    @property
    def thread_note(self):
        """Why that many (masters/threads.py)."""
        return self.planner.note if self.planner is not None else "serial"

    @property
    def costs_us(self):
        """µs per evaluation of each subsystem, as last timed (None before)."""
        return self.planner.costs if self.planner is not None else None

    def run_info(self):
        """For the run summary: which path and thread plan ran."""
        return {**super().run_info(), "fast_path": self.fast, "fast_note": self.fast_note, "threads": self.threads,
                "thread_note": self.thread_note}

    def close(self):
        for part in (self._certs, self.kernel, self._newton):
            if part is not None:
                part.close()
        self.kernel = self._newton = self._certs = None
        super().close()
