"""`master.threads: auto | N`: which thread evaluates which subsystem on a kernel route.

Within one evaluation round (a DR inner iteration, a Jacobi pass, a commit) no subsystem reads
another's new outputs, so the kernel evaluates them on up to min(N, CPUs, subsystems) threads; each
thread writes only its own subsystems' outputs and the caller does all the arithmetic, so the plan
never changes a number. The plan is longest-processing-time first (thread_plan) over the costs the
kernel timed on the first macro-step, timed again about every REMEASURE_S while threads run, and
re-balanced when they drift. `N` uses min(N, CPUs, subsystems) threads at once. `auto` adds threads
one plan at a time, each tried alone on the next macro-step and kept only while it pays: its
round must realise KEEP_SHARE of the gain the costs predict, and every thread must take over at
least PARALLEL_MIN_US per round (below that a hand-off costs more than it saves: a round shorter
than twice that gives no second thread its share, so auto stays serial without planning); when the costs
fall below that later, it gives threads back, and it tries again when they grow or after RETRY_S.
"""
import time

from ..kernel.drkernel import DR_MAX_THREADS, PARALLEL_MIN_US, available_cpus, thread_plan

KEEP_SHARE = 0.3       # auto keeps a plan whose measured round realises this share of its predicted gain
MIN_GAIN = 0.9         # auto tries more threads only where their predicted round is at most this of today's
REMEASURE_S = 1.0      # while threads run, the subsystems' costs are timed again about this often
DRIFT = 1.1            # re-plan when the plan in force predicts a round this much longer than the best
TRIAL_STEPS = 3        # macro-steps a plan is tried on (its best round counts: a preemption hits one)
RETRY_S = 10.0         # auto tries more threads again this long after finding none paying


def makespan(costs, plan, n_threads):
    """The predicted round of a plan: the load of its busiest thread (µs)."""
    load = [0.0] * n_threads
    for c, k in zip(costs, plan):
        load[k] += c
    return max(load)


class ThreadPlanner:
    """The thread plan of one kernel (drkernel.Kernel: set_threads, costs). The master calls
    `begin()` before each macro-step or block (whether the kernel times every evaluation) and
    `end()` after it with its seconds per round, which hands the costs over (`measured`) or the
    round of a plan on trial (`tried`); it runs no block while a plan is on trial (`on_trial`).
    `threads`, `plan` and `note` say what is in force and why."""

    def __init__(self, kernel, mode, n_sub, independent=True):
        self.kernel, self.auto = kernel, str(mode) == "auto"
        asked = n_sub if self.auto else int(mode)
        self.cpus = available_cpus()
        self.limit = max(1, min(asked, self.cpus, n_sub, DR_MAX_THREADS)) if independent else 1
        self.threads, self.plan, self._costs = 1, [0] * n_sub, None
        self.round_s = None            # the measured round of the plan in force (s)
        self.trial = None              # (threads, plan, predicted ratio, rounds so far) on trial
        self.refused_at = None         # (total cost, perf_counter()) when auto last found no more threads paying
        self._note = None              # why: a text, or a function making it when read (note)
        self._next_measure = None      # perf_counter() of the next timing (None: the first macro-step)
        self.note = "serial" if independent else "serial: each subsystem reads its predecessors' new outputs"
        self._asked = "as set" if asked == self.limit else \
            f"threads: {asked} capped at {self.limit}: {self.cpus} CPUs, {n_sub} subsystems"
        if independent and self.limit == 1 and asked > 1:
            self.note = f"serial ({self._asked})" if not self.auto else f"serial: {self.cpus} CPU"

    @property
    def costs(self):
        """µs per evaluation of each subsystem, as last timed (None before); after a round too short to
        share they are read from the kernel when first asked for."""
        if callable(self._costs):
            self._costs = list(self._costs())
        return self._costs

    @costs.setter
    def costs(self, costs):
        self._costs = costs

    @property
    def note(self):
        """Why this many threads (a serial reason quoting the timed costs is written when read)."""
        return self._note() if callable(self._note) else self._note

    @note.setter
    def note(self, why):
        self._note = why

    @property
    def on_trial(self):
        return self.trial is not None

    @property
    def started(self):
        """Whether the first macro-step was timed (or there is nothing to plan)."""
        return self.limit == 1 or self._next_measure is not None

    def wants_measure(self):
        """Whether the kernel should time the evaluations of the next macro-step or block."""
        if self.limit == 1 or self.trial is not None:
            return False
        return self._next_measure is None or (
            (self.threads > 1 or self.auto) and time.perf_counter() >= self._next_measure)

    def begin(self):
        """Before a macro-step or block: (measure: the kernel times every evaluation, timed: its
        round is to be handed to `end`)."""
        measure = self.wants_measure()
        return measure, measure or self.trial is not None

    def end(self, measure, round_s):
        """After a macro-step or block begun with `begin`: its seconds per evaluation round."""
        if measure and self._too_short(round_s):
            self._stay_serial(round_s)
        elif measure:
            self.measured(self.kernel.costs(), round_s)
        elif self.trial is not None:
            self.tried(round_s)

    def _too_short(self, round_s):
        """auto, serial: the whole round is too short for a second thread to take PARALLEL_MIN_US of it,
        whatever the costs (so they are not read)."""
        return self.auto and self.threads == 1 and 1e6 * round_s < 2 * PARALLEL_MIN_US

    def _stay_serial(self, round_s):
        """Serial on a round too short to share (auto looks again in REMEASURE_S)."""
        now = time.perf_counter()
        self._next_measure, self.round_s, self.costs = now + REMEASURE_S, round_s, self.kernel.costs
        self.refused_at = (1e6 * round_s, now)
        self.note = self._short_round

    def _short_round(self):
        """The note of _stay_serial."""
        return f"serial: a round takes {1e6 * self.round_s:.3g} µs, a second thread pays from {2 * PARALLEL_MIN_US:g} µs"

    def measured(self, costs_us, round_s):
        """After a timed macro-step or block: µs per evaluation of each subsystem, seconds per round."""
        first = self._next_measure is None
        self._next_measure = time.perf_counter() + REMEASURE_S
        self.costs, self.round_s = list(costs_us), round_s
        if first and not self.auto:
            self._apply(self.limit, self._asked)
        elif self.auto and self._shed():
            return
        elif self.threads > 1:
            self._rebalance()
        if self.auto and self._may_try():
            self._try_more()

    def _may_try(self):
        """auto: whether to look for more threads (first, or the costs grew, or RETRY_S went by)."""
        if self.refused_at is None:
            return True
        cost, when = self.refused_at
        return sum(self.costs) > DRIFT * cost or time.perf_counter() > when + RETRY_S

    def _refuse(self):
        self.refused_at = (sum(self.costs), time.perf_counter())

    def tried(self, round_s):
        """After a macro-step on trial; after the last one, keep its plan if it paid, and try the next,
        else go back."""
        n_threads, plan, ratio, rounds = self.trial
        rounds.append(round_s)
        if len(rounds) < TRIAL_STEPS:
            return
        round_s, self.trial = min(rounds), None
        threshold = 1.0 - KEEP_SHARE * (1.0 - ratio)
        timing = (f"{1e6 * self.round_s:.3g} µs per round on {self.threads}, "
                  f"{1e6 * round_s:.3g} µs on {n_threads}")
        if round_s <= threshold * self.round_s:
            self.round_s = round_s
            self._set(n_threads, plan, f"auto, {timing}")
            self._try_more()
            return
        self.kernel.set_threads(self.plan)
        self._refuse()
        kept = "serial" if self.threads == 1 else f"{self.threads} threads"
        self.note = f"{kept}: {n_threads} threads were not faster here ({timing})"

    def _try_more(self):
        """auto: put the next plan that should pay on trial (the next macro-step), if any."""
        current = makespan(self.costs, self.plan, self.threads)
        for n_threads in range(self.threads + 1, self.limit + 1):
            plan, load = thread_plan(self.costs, n_threads)
            if min(load) < PARALLEL_MIN_US:
                break
            if max(load) <= MIN_GAIN * current:
                if self.kernel.set_threads(plan):
                    self.trial = (n_threads, plan, max(load) / current, [])
                else:
                    self.note = f"{self.note}; a worker thread could not be started"
                return
        self._refuse()
        if self.threads == 1 and self.limit > 1:
            self.note = self._serial_reason

    def _serial_reason(self):
        plan, load = thread_plan(self.costs, 2)
        return (f"serial: a second thread would take over {min(load):.3g} µs per round "
                f"(< {PARALLEL_MIN_US:g} µs)")

    def _shed(self):
        """auto: fewer threads when the costs fell so that a thread no longer takes PARALLEL_MIN_US."""
        n_threads = self.threads
        while n_threads > 1 and min(thread_plan(self.costs, n_threads)[1]) < PARALLEL_MIN_US:
            n_threads -= 1
        if n_threads == self.threads:
            return False
        self._apply(n_threads, "auto, fewer threads as the costs fell")
        return True

    def _rebalance(self):
        """The same threads, the subsystems moved when the plan in force drifted from the best."""
        plan, load = thread_plan(self.costs, self.threads)
        if makespan(self.costs, self.plan, self.threads) > DRIFT * max(load):
            self._apply(self.threads, "re-balanced as the costs drifted")

    def _apply(self, n_threads, why):
        plan = thread_plan(self.costs, n_threads)[0] if n_threads > 1 else [0] * len(self.plan)
        if self.kernel.set_threads(plan):
            self._set(n_threads, plan, why)
        else:
            self.kernel.set_threads([0] * len(self.plan))
            self._set(1, [0] * len(self.plan), "serial: a worker thread could not be started")

    def _set(self, n_threads, plan, why):
        self.threads, self.plan = n_threads, plan
        if n_threads == 1:
            self.note = why if why.startswith("serial") else f"serial ({why})"
            return
        costs = ", ".join(f"{c:.3g}" for c in self.costs)
        self.note = f"{n_threads} threads ({why}): subsystems on threads {plan} (µs per evaluation: {costs})"
