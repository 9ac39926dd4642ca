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
from .base import kernel_refusal
from .dr import DRMaster
from .dr_route import DRRoute
from .ledger import RTOL, EnergyLedger
from .steplog import StepLog
from .threads import ThreadPlanner
from .dr_options import STARTS


class FastDRMaster(DRMaster):
    """`master.algorithm: dr`. Algorithm 1 runs in the C kernel when `fast` allows it, otherwise in
    the reference DRMaster.step; the result is the same to the last bit either way.

    `fast` (bool) says which path runs and `fast_note` why; `threads` and `thread_note` tell the
    thread plan once it is chosen (after the first macro-step)."""

    def __init__(self, scene, settings):
        super().__init__(scene, settings)
        self.kernel, self.fast, self.planner, self._route = None, False, None, None
        self._newton = None       # the certificates' interface Newton in C (kernel/newton.py NewtonKernel), when asked
        self._certs = None        # the certificates inside the blocks (kernel/certs.py KernelCertificates), when asked
        # the certificates' C passes need every port to be the FMU's own wave map (no wave adapter)
        self._exact = not any(s.adapter for s in scene.subsystems)
        self.fast_note = self._kernel_refusal(scene, str(settings.fast).lower())
        if self.fast_note is not None:
            return
        self._kernel_scene = scene.kernel_scene()        # what the kernel's bindings know of the scene
        self.kernel = Kernel(self._kernel_scene, self.P, self.J_L)
        self._b = self._own_b                     # b^n from now on in the kernel alone
        self.kernel.configure(self.dt, self.K, self.eps, self.deadline_s)
        self.kernel.set_anchors((settings.energy_guard or self.default_guard) == "ledger")
        self._send_options()
        if isinstance(self.guard, EnergyLedger):       # the kernel keeps L and its traffic from here on
            self.kernel.keep_ledger(0.0, 0.0, RTOL, self.deadline_s)
        self.fast, self.fast_note = True, "C kernel"
        self._route = DRRoute(self)
        self.planner = ThreadPlanner(self.kernel, settings.threads, len(self.subsystems))
        self._redo_seen = 0       # the kernel's count of redo doSteps when _redo_doSteps last looked

    def _send_options(self):
        """The named options to the kernel (it forgets b^{n-1} and the Anderson differences)."""
        s = self.settings
        self.kernel.set_options(self.relaxation, s.anderson, STARTS.index(self.start), s.anderson_memory,
                                s.anderson_extrapolate)

    @staticmethod
    def _kernel_refusal(scene, mode):
        """Why the reference path runs (None: the kernel can run); master.fast: true insists."""
        return kernel_refusal(scene, mode)

    @property
    def _b(self):
        """b^n, one copy: the kernel's while it runs (it commits in C), else the master's own."""
        return self.kernel.b[:] if getattr(self, "kernel", None) is not None else self._own_b

    @_b.setter
    def _b(self, b):
        if getattr(self, "kernel", None) is not None:
            self.kernel.b[:] = [float(x) for x in b]
        else:
            self._own_b = b

    @property
    def _a_before(self):
        """a^{n-1}, one copy: the kernel's while it runs (the start of its next step), else the master's own."""
        return self.kernel.previous() if getattr(self, "kernel", None) is not None else self._own_a_before

    @_a_before.setter
    def _a_before(self, a):
        if getattr(self, "kernel", None) is not None:
            self.kernel.set_previous(None if a is None else [float(x) for x in a])
        else:
            self._own_a_before = a

    def _commit(self, a_hat):
        """A commit made from Python (a guard's redo): the kernel's a_hat, a^{n-1} of its next start, too."""
        super()._commit(a_hat)
        if self.kernel is not None:
            self.kernel.a_hat[:] = [float(x) for x in a_hat]

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
            self._newton = NewtonKernel(self._kernel_scene, self.P, counted=False)     # the certificates' own
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

    def _reserve_time(self, seconds):
        super()._reserve_time(seconds)
        if self.kernel is not None:
            self.kernel.configure(self.dt, self.K, self.eps, self.inner_deadline_s)

    def enable_trace(self, on=True):
        super().enable_trace(on)
        if self.kernel is not None:
            self.kernel.record(max(self.K, 1) if on else 0)
        return True

    def step(self, n, t) -> StepLog:
        """Macro-step n; with the energy ledger and the kernel, iteration, commit, ledger check and redo
        in one kernel call (dr_run_steps of one step, within master.deadline_us as in blocks)."""
        if self.kernel is None or not isinstance(self.guard, EnergyLedger):
            return super().step(n, t)
        log = self._kernel_step(n, t, lambda measure: self._ledger_step(n, measure))
        row = self._ledger_log.ledger_rows[:, 0]
        log.ledger = (row[0], row[1], row[3], row[4], row[5])      # supplied, ledger; scale, action, rounds
        return log

    def make_step(self, n, t) -> StepLog:
        if self.kernel is None:
            return super().make_step(n, t)
        return self._kernel_step(n, t, lambda measure: (self.kernel.macro_step(n, t, measure), 0))

    def _ledger_step(self, n, measure):
        """Macro-step n and the ledger's check and redo in one kernel call: (its DRStep, redo rounds)."""
        _, self._ledger_log, error = self.kernel.run_steps(n, 1, math.inf, measure, observe=False)   # the run reads
        if error is not None:
            raise error
        self.guard.book(self._ledger_log, self._redo_doSteps())
        return self.kernel.io, int(self._ledger_log.ledger["rounds"][0])

    def _kernel_step(self, n, t, call):
        """Macro-step n by the kernel, `call(measure)` giving (its DRStep, the ledger's redo rounds);
        booked as DRMaster.step books it."""
        kernel, b_n, a_n = self.kernel, self._b, self._a_before        # b^n and a^{n-1} before the step
        self.step_started = time.perf_counter()
        measure, timed = self.planner.begin()
        io, redone = call(measure)
        k = io.iterations
        if timed:   # K queries, the commit, the redo
            self.planner.end(measure, (time.perf_counter() - self.step_started) / (k + 1 + redone))
        self._note_kernel_steps(n, t)            # frozen at x^n (saved by the kernel)
        n_ch = kernel.n
        out = kernel.results[:]                  # b^{n+1}, a, u^0, u^K
        self._b_step_start, self._a_step_start = b_n, a_n
        if self._trace is not None:
            self._trace = kernel.recorded(k)
        u0, uK = (None, None) if redone else (out[2 * n_ch:3 * n_ch], out[3 * n_ch:])   # a redo's log has none
        return StepLog(iterations=k, residual=io.residual, reason=REASONS[io.reason], a_hat=out[n_ch:2 * n_ch],
                       u0=u0, uK=uK)

    def _redo_in_kernel(self, supplied, budget, left_s, round_s):
        """The energy ledger's redo of the step just made, by the kernel (kernel/drkernel.py Kernel.redo); b^{n+1}
        becomes the redo's. Returns (s, supply,
        traffic, action, rounds, inputs committed)."""
        if self.kernel is None:
            return None
        done = self.kernel.redo(supplied, budget, left_s, round_s)
        self._note_kernel_steps(self.subsystems[0].step_index, self.subsystems[0].t)
        return (*done, self.kernel.a_hat[:])

    def route(self):
        """Its kernel route (dr_route.DRRoute, a base.Route) while the kernel runs, else None."""
        return self._route

    def _redo_doSteps(self):
        """doSteps of the FMUs in the ledger's redos since the last ask (the kernel counts them: a wave
        adapter's query takes a varying number)."""
        made, self._redo_seen = self._redo_seen, self.kernel.redo_do_steps()
        return self._redo_seen - made

    def _book(self, n0, done, log, b_n, a_n):
        """Book macro-steps n0 .. n0 + done - 1 of the kernel, b_n and a_n the b^n and a^{n-1} of the
        first: the step on the Subsystems, the b^n and a^{n-1} of the last step (for an undo)."""
        if not done:
            return
        last = n0 + done - 1
        self._note_kernel_steps(last, self.t0 + last * self.dt)
        self._b_step_start = log.b[done - 2].tolist() if done > 1 else b_n
        self._a_step_start = log.a_hat[done - 2].tolist() if done > 1 else a_n
        if self._trace is not None:
            self._trace = self.kernel.recorded(int(log.iterations[-1]))

    def _note_kernel_steps(self, n, t):
        """After kernel macro-steps (the last one step n at t) or a ledger redo: where the Subsystems
        are (the kernel counted its FMU calls in the FMUs' counters)."""
        for s in self.subsystems:
            s.note_kernel_step(n, t)

    def run_info(self):
        """For the run summary: which path and thread plan ran."""
        planner = self.planner
        return {**super().run_info(), "fast_path": self.fast, "fast_note": self.fast_note,
                "threads": planner.threads if planner else 1, "thread_note": planner.note if planner else "serial"}

    def close(self):
        if self.kernel is not None:
            self._own_b, self._own_a_before = self.kernel.b[:], self.kernel.previous()   # kept past its release
        for part in (self._certs, self.kernel, self._newton):
            if part is not None:
                part.close()
        self.kernel = self._newton = self._certs = self._route = None
        super().close()
