"""Interface energy ledger: over the run, the interface never supplies net energy.

Per macro-step the interface supplies I^n = sum_i 1/2 (|a_i^n|^2 - |b_i^{n+1}|^2) (wave masters) or
dt sum e.f over the ports (physical masters). A lossless coupling supplies none, so the ledger
L^n = sum_{k<=n} I^k is kept <= tol (roundoff: RTOL times the interface's cumulative traffic; where a
wave adapter had to keep a stalled query, RTOL plus the relative accuracy the frozen maps are solved
to, Scene.map_noise, since below that no supply can be measured). With
Condition 2 every FMU gains at most what its port took in plus the work of its own sources, so
H^N <= H^0 + tol + (work of sources inside the FMUs), for every budget, scene and horizon; no H
and no interface solve are needed. K = 0 keeps the ledger by itself (L^n = -|b^{n+1}|^2 / 2).

A step that would lift L above tol is undone (x^n restored) and its commit redone with the inputs
scaled by s in [0, 1): s = 0 (matched loads, zero power) only dissipates, so it always fits. The
supply of the scaled step is a quadratic in s when the FMUs are affine in their inputs; it is
fitted from the committed step (s = 1) and one probe at s = 0, and s is the largest root of
I(s) = TARGET * budget in [0, 1); the redo at that s is checked, and replaced by s = 0 if it misses.
"""
import math
import time

import numpy as np

from ...masters.base import StepLog
from ..recorder import Labels
from . import Observer

RTOL = 1e-12            # roundoff allowance per unit of energy through the interface
TARGET = 0.9            # the scaled step spends this fraction of the remaining budget (docs/scenes.md)
ACTIONS = ("kept", "scaled", "zero")
SMOOTH = 0.1            # weight of the newest measurement in the running evaluation-round times
STEP_TIME = ("wall time of the step and its guard: inner iterations, commit, ledger check and redo (C kernel: "
             "timed in C, one call per step or block); not the observers (certificates, recorder). Python "
             "guard: from master.step to the end of the redo, the reading of the FMUs after the step included")


def largest_root(q0, qh, q1, target):
    """The largest s in [0, 1) with q(s) = target, q the quadratic through (0, q0), (1/2, qh),
    (1, q1), given q0 <= target < q1; 0 when none is found."""
    alpha = 2.0 * (q1 - 2.0 * qh + q0)
    beta = q1 - q0 - alpha
    gamma = q0 - target
    if abs(alpha) <= 1e-12 * (abs(beta) + abs(gamma)):
        roots = [-gamma / beta] if beta else []
    else:
        disc = max(beta * beta - 4.0 * alpha * gamma, 0.0)
        sq = math.copysign(math.sqrt(disc), beta) if beta else math.sqrt(disc)
        big = -0.5 * (beta + sq)                      # the stable pair of quadratic roots
        roots = [big / alpha] + ([gamma / big] if big else [])
    inside = [r for r in roots if 0.0 <= r < 1.0]
    return max(inside) if inside else 0.0


class EnergyLedger(Observer):
    """First of the observers: it may redo the step before anyone reads it. Wave masters' blocks
    (the C kernel books the ledger and makes the redo itself) are taken whole."""
    redoes = True
    columns = ("interface_energy", "ledger", "scale", "ledger_action")
    formats = {"ledger_action": Labels(ACTIONS)}

    def __init__(self, master):
        self.master = master
        self.n_inputs = master.scene.n_channels
        self.L, self.traffic, self.max_L = 0.0, 0.0, -math.inf
        self.acted, self.extra, self.fallbacks = 0, 0, 0
        self.round_s, self.redo_round_s = 0.0, 0.0      # running time of one evaluation round: master's, redo's
        self.step_times = []            # under a deadline, per step: (wall, acted, round it may overrun by, CPU) s

    def kernel_state(self):
        """(L, traffic, RTOL): what the C kernel needs to keep the ledger itself (blocks); it adds the
        wave adapters' noise (map_noise) at each step itself, as rtol() does here."""
        return self.L, self.traffic, RTOL

    def rtol(self):
        """The allowance per unit of traffic: RTOL, plus the frozen maps' own accuracy (0.0 when exact)."""
        return RTOL + self.master.scene.map_noise()

    def after_block(self, n0, logs, readings, rows):
        """Book a block the kernel made: it kept the ledger itself, redoing steps as _redo does, bit
        for bit (drkernel.c, ledger_step), and logged each step's I^n, L^n, s, action and redo rounds."""
        led, logged = logs.ledger, logs.ledger_rows
        rows[:, :2], rows[:, 2:] = logged[0:2].T, logged[3:5].T      # supplied, ledger; scale, action
        acted, rounds = int(np.count_nonzero(led["action"])), led["rounds"]     # actions: 0 kept, 1 scaled, 2 zero
        if acted:                                                          # only a redone step has rounds
            self.acted += acted
            self.extra += self.master.redo_doSteps()
            self.fallbacks += int(np.count_nonzero(rounds == 3))
        self.L, self.traffic = float(led["ledger"][-1]), float(led["traffic"][-1])
        self.max_L = max(self.max_L, float(led["ledger"].max()))
        if self.master.deadline_s is not None:
            self.round_s = self.redo_round_s = float(led["round_s"][-1])
            self.step_times.extend(zip(led["step_s"].tolist(), (led["action"] > 0).tolist(),
                                       led["round_s"].tolist(), led["cpu_s"].tolist()))

    def after_step(self, n, t, log, reading, row):
        """Book I^n; redo the commit when the ledger would exceed tol (unless the master's kernel made
        step and guard in one call: its one-step log is then booked as a block's, and log is the redo's)."""
        master, redo = self.master, None
        if getattr(master, "guarded", None) is not None:
            self.after_block(n, master.guarded, None, row[None, :])
            return None
        inputs, outputs = master.committed_inputs(log), master.committed_outputs
        supplied, traffic = master.supply(inputs, outputs)
        self._time_round(log)
        tol = self.rtol() * (self.traffic + traffic)
        s, action = 1.0, 0
        if self.L + supplied > tol:
            calls = master.scene.do_step_calls()
            s, supplied, traffic, action = self._redo(inputs, outputs, supplied, tol - self.L)
            self.acted, self.extra = self.acted + 1, self.extra + master.scene.do_step_calls() - calls
            redo = StepLog(iterations=log.iterations, residual=log.residual, reason="energy-guard",
                           a_hat=[s * x for x in inputs] if log.a_hat is not None else None)
        self.L += supplied
        self.traffic += traffic
        self.max_L = max(self.max_L, self.L)
        row[0], row[1], row[2], row[3] = supplied, self.L, s, action
        if master.deadline_s is not None:
            self.step_times.append((time.perf_counter() - master.step_started, action > 0, self.redo_round_s, math.nan))
        return redo

    def _redo(self, inputs, out_1, supplied_1, budget):
        """Undo the step and commit it again with s * inputs; (s, supply, traffic, action) of the new commit.

        The fitted s needs two evaluation rounds (probe, commit): under a deadline with less time
        left, s = 0 is committed at once (one round). A master with a kernel makes the redo in C."""
        master, fitted = self.master, self._time_left() >= 2.0 * self.redo_round_s
        started = time.perf_counter()
        done = master.redo_in_kernel(supplied_1, budget, fitted)
        if done is not None:                            # the same operations, in C (drkernel.c ledger_redo)
            self._time_redo(time.perf_counter() - started, done[4])
            self.fallbacks += done[4] == 3
            return done[:4]
        master.undo_step()
        if fitted:
            s, supplied, traffic = self._scaled(inputs, out_1, supplied_1, budget)
            if supplied <= budget:
                return s, supplied, traffic, 1
            self.fallbacks += 1
            master.undo_step()
        started = time.perf_counter()
        out = master.recommit([0.0] * self.n_inputs)
        self._time_redo(time.perf_counter() - started, 1)
        return (0.0, *master.supply([0.0] * self.n_inputs, out), 2)

    def _scaled(self, inputs, out_1, supplied_1, budget):
        """Probe s = 0, fit the quadratic supply I(s), commit at its largest root of TARGET * budget."""
        started = time.perf_counter()
        out_0, supply = self.master.probe([0.0] * self.n_inputs), self.master.supply

        def model(s):
            return supply([s * x for x in inputs], [y0 + s * (y1 - y0) for y0, y1 in zip(out_0, out_1)])[0]
        s = largest_root(model(0.0), model(0.5), supplied_1, TARGET * budget)
        out = self.master.recommit([s * x for x in inputs])
        self._time_redo(time.perf_counter() - started, 2)
        return (s, *supply([s * x for x in inputs], out))

    def _time_left(self):
        """Seconds to master.deadline_us from now (infinite without a deadline)."""
        master = self.master
        if master.deadline_s is None:
            return math.inf
        return master.step_started + master.deadline_s - time.perf_counter()

    def _time_round(self, log):
        """Track the master's time per evaluation round; its inner loop stops two rounds early (its
        last iteration may overrun by one, the commit takes one), so an s = 0 redo ends within one
        round of master.deadline_us."""
        master = self.master
        if master.deadline_s is None:
            return
        spent = (time.perf_counter() - master.step_started) / (log.iterations + 1)
        self.round_s = smoothed(self.round_s, spent)
        self.redo_round_s = self.redo_round_s or self.round_s
        master.reserve_time(self.round_s + self.redo_round_s)

    def _time_redo(self, seconds, rounds):
        """Track the time per evaluation round of a redo (Python calls: slower than the kernel's)."""
        self.redo_round_s = smoothed(self.redo_round_s, seconds / rounds)

    def summary(self):
        out = {"energy_guard_steps": self.acted, "energy_guard_extra_doSteps": self.extra,
               "energy_guard_fallbacks": self.fallbacks, "max_ledger": self.max_L, "ledger_final": self.L}
        if self.step_times:
            out["step_time_us"] = spread([t for t, _, _, _ in self.step_times])
            out["guarded_step_time_us"] = spread([t for t, acted, _, _ in self.step_times if acted])
            out["deadline_bound"] = deadline_bound(self.step_times, self.master.settings.deadline_us)
        return out


def smoothed(estimate, sample):
    """A running time after a new sample, taken at most at twice the estimate so that a step the
    machine descheduled does not shorten the next inner loops (drkernel.c track_round)."""
    return (1 - SMOOTH) * estimate + SMOOTH * min(sample, 2.0 * estimate) if estimate else sample


def rank(ordered, q):
    """The q-quantile of a sorted list by nearest rank."""
    return ordered[max(math.ceil(q * len(ordered)) - 1, 0)]


def spread(seconds):
    """Median, 99th percentile and maximum of a list of times, in µs (empty: {})."""
    if not seconds:
        return {}
    ordered = sorted(seconds)
    return {"median": 1e6 * rank(ordered, 0.5), "p99": 1e6 * rank(ordered, 0.99), "max": 1e6 * ordered[-1],
            "count": len(ordered)}


def deadline_bound(step_times, deadline_us):
    """The bound a step keeps, deadline + one evaluation round (every subsystem's doStep once, as the
    guard measured it at that step; the median given); the share of all steps, of guarded steps and
    of the steps the machine left on the CPU (wall - CPU time below a round; kernel blocks) within it."""
    within = [1e6 * t <= deadline_us + 1e6 * r for t, _, r, _ in step_times]
    guarded = [w for w, (_, acted, _, _) in zip(within, step_times) if acted]
    on_cpu = [w for w, (t, _, r, cpu) in zip(within, step_times) if t - cpu < r]
    round_us = 1e6 * rank(sorted(r for _, _, r, _ in step_times), 0.5)
    return {"step_time": STEP_TIME, "deadline_us": deadline_us, "round_us": round_us,
            "bound_us": deadline_us + round_us,
            "within": share(within), "guarded_within": share(guarded), "on_cpu_within": share(on_cpu),
            "on_cpu_steps": len(on_cpu)}


def share(flags):
    """The fraction of true flags (None for none)."""
    return sum(flags) / len(flags) if flags else None
