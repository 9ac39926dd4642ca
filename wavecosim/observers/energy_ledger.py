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

from ..masters.base import StepLog
from ..readings import row_sums
from .recorder import Labels
from . import Observer

RTOL = 1e-12            # roundoff allowance per unit of energy through the interface
TARGET = 0.9            # the scaled step spends this fraction of the remaining budget (docs/scenes.md)
ACTIONS = ("kept", "scaled", "zero")
SMOOTH = 0.1            # weight of the newest measurement in the running evaluation-round times


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
    (the C kernel books the ledger and stops before a step to redo) are taken whole."""
    redoes = True
    columns = ("interface_energy", "ledger", "scale", "ledger_action")
    formats = {"ledger_action": Labels(ACTIONS)}

    def __init__(self, master):
        self.master = master
        self.n_inputs = master.scene.n_channels
        self.L, self.traffic, self.max_L = 0.0, 0.0, -math.inf
        self.acted, self.extra, self.fallbacks = 0, 0, 0
        self.round_s, self.redo_round_s = 0.0, 0.0      # running time of one evaluation round: master's, redo's
        self.step_times = []                            # realised step times (s), when a deadline is set

    def kernel_state(self):
        """(L, traffic, RTOL): what the C kernel needs to book the ledger itself between guarded steps."""
        return self.L, self.traffic, self.rtol()

    def rtol(self):
        """The allowance per unit of traffic: RTOL, plus the frozen maps' own accuracy (0.0 when exact)."""
        return RTOL + self.master.scene.map_noise()

    def after_block(self, n0, logs, readings, rows):
        """Book a block the kernel made: it stopped before any step this guard would redo, so every
        step is kept; the same sums, in the same order, as after_step step by step."""
        aa, bb = row_sums(logs.a_hat * logs.a_hat), row_sums(logs.b * logs.b)
        supplied, traffic = 0.5 * (aa - bb), 0.5 * (aa + bb)
        L = np.cumsum(np.concatenate([[self.L], supplied]))
        T = np.cumsum(np.concatenate([[self.traffic], traffic]))
        if np.any(L[:-1] + supplied > self.rtol() * (T[:-1] + traffic)):
            raise RuntimeError("energy ledger: the kernel booked a step the guard would redo")
        rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3] = supplied, L[1:], 1.0, 0
        self.L, self.traffic = float(L[-1]), float(T[-1])
        self.max_L = max(self.max_L, float(L[1:].max()))

    def after_step(self, n, t, log, reading, row):
        """Book I^n; redo the commit when the ledger would exceed tol."""
        master, redo = self.master, None
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
            self.step_times.append((time.perf_counter() - master.step_started, action > 0))
        return redo

    def _redo(self, inputs, out_1, supplied_1, budget):
        """Undo the step and commit it again with s * inputs; (s, supply, traffic, action) of the new commit.

        The fitted s needs two evaluation rounds (probe, commit): under a deadline with less time
        left, s = 0 is committed at once (one round)."""
        master = self.master
        master.undo_step()
        if self._time_left() >= 2.0 * self.redo_round_s:
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
        self.round_s = spent if not self.round_s else (1 - SMOOTH) * self.round_s + SMOOTH * spent
        self.redo_round_s = self.redo_round_s or self.round_s
        master.reserve_time(self.round_s + self.redo_round_s)

    def _time_redo(self, seconds, rounds):
        """Track the time per evaluation round of a redo (Python calls: slower than the kernel's)."""
        self.redo_round_s = (1 - SMOOTH) * self.redo_round_s + SMOOTH * seconds / rounds

    def summary(self):
        out = {"energy_guard_steps": self.acted, "energy_guard_extra_doSteps": self.extra,
               "energy_guard_fallbacks": self.fallbacks, "max_ledger": self.max_L, "ledger_final": self.L}
        if self.step_times:
            out["step_time_us"] = spread([t for t, _ in self.step_times])
            out["guarded_step_time_us"] = spread([t for t, acted in self.step_times if acted])
        return out


def spread(seconds):
    """Median, 99th percentile and maximum of a list of times, in µs (empty: {})."""
    if not seconds:
        return {}
    ordered = sorted(seconds)
    return {"median": 1e6 * ordered[len(ordered) // 2], "p99": 1e6 * ordered[int(0.99 * (len(ordered) - 1))],
            "max": 1e6 * ordered[-1], "count": len(ordered)}
