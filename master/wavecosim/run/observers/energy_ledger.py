"""Interface energy ledger: over the run, the interface never supplies net energy.

Per macro-step the interface supplies I^n = sum_i 1/2 (|a_i^n|^2 - |b_i^{n+1}|^2) (wave masters) or
dt sum e.f over the ports (physical masters). A lossless coupling supplies none, so the ledger
L^n = sum_{k<=n} I^k is kept <= tol (roundoff: RTOL times the interface's cumulative traffic; where a
wave adapter had to keep a stalled query, RTOL plus the relative accuracy the frozen maps are solved
to, Scene.map_noise, since below that no supply can be measured). With
Condition 2 every FMU gains at most what its port took in plus the work of its own sources, so
H^N <= H^0 + tol + (work of sources inside the FMUs), for every budget, scene and horizon; no H
and no interface solve are needed. K = 0 keeps the ledger by itself (L^n = -|b^{n+1}|^2 / 2).

A step that would lift L above tol is undone (x^n restored) and made again, spending budget
before accuracy, each stage only when the one before does not fit (I <= the allowance, tol - L),
every commit checked (docs/energy.md):
1. `iterated`: the inner iteration goes on from where it stopped (tolerance or deadline) to the
   rest of its budget K, and commits anew (Master.remaining_iterations, iterate_on);
2. `projected`: a_hat moves against the gradient of the step's supply to where a model of it
   reaches TARGET * allowance (projected; the model's slopes from the secant to the last query);
3. `blended`: the commit moves from a_hat towards an anchor, a query of the step whose supply is
   known and fits (Master.anchors: the last query, or the latest with supply <= 0); along the
   segment the outputs are interpolated from the two known ones, the supply is a quadratic in the
   fraction s, and the anchor whose crossing lies nearest a_hat is taken (best_anchor);
4. `anchored`: that anchor's own input (its outputs, and so its supply, are known: it fits);
5. `scaled`: the inputs scaled by s in [0, 1) towards zero, s fitted from one probe at zero inputs
   as in stage 3 (what the classical masters, which have no anchors, do first);
6. `zero`: zero inputs, which only dissipate, so they always fit (the last resort).
Under a deadline a stage runs only when the rounds it needs are left (stage 1: three evaluation
rounds; 2, 3 and 5: two; the redo's own rounds counted), so a step ends within about a round of it.
"""
import math
import time

import numpy as np

from ...kernel.drkernel import LEDGER_ACTIONS
from ...kernel.linalg import distance, dot
from ...masters.base import StepLog
from ..recorder import Labels
from . import Observer

RTOL = 1e-12            # roundoff allowance per unit of energy through the interface
TARGET = 0.9            # a fitted correction spends this fraction of the remaining budget (docs/energy.md)
ACTIONS = LEDGER_ACTIONS                     # codes: drkernel.h DRLedgerAction
KEPT, SCALED, ZERO, ITERATED, PROJECTED, BLENDED, ANCHORED = range(len(ACTIONS))
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


def blend(q, a, s):
    """q + s (a - q): the input a fraction s of the way from an anchor q to a."""
    return [qj + s * (aj - qj) for qj, aj in zip(q, a)]


def segment_root(supply, q, a, y_q, y_a, supplied_a, target):
    """The fraction s in [0, 1) where the supply of blend(q, a, s) reaches target, the outputs
    interpolated between y_q (at q) and y_a (at a): the largest root of that quadratic."""
    def model(s):
        return supply(blend(q, a, s), blend(y_q, y_a, s))[0]
    return largest_root(model(0.0), model(0.5), supplied_a, target)


def best_anchor(supply, anchors, a, y_a, supplied_a, target):
    """(s, anchor) of the anchors (inputs, outputs, supply) whose supply fits target: the one whose
    crossing of target lies nearest a, the first of equals; None when none fits."""
    best = None
    for q in anchors:
        if not q[2] <= target:
            continue
        s = segment_root(supply, q[0], a, q[1], y_a, supplied_a, target)
        d = (1.0 - s) * distance(a, q[0])
        if best is None or d < best[0]:
            best = (d, s, q)
    return None if best is None else best[1:]


def projected(spans, a, y, last, supplied, target):
    """a moved against the gradient g = a - J^T y of the step's supply to where a model of that supply
    reaches target. J is a scalar rho per subsystem (spans: each one's channels as (offset, count)),
    the secant between a and the last query (u, S(u)) clamped to [0, 1] (an FNE map's slopes), so the
    supply along a - t g is supplied - t |g|^2 + t^2 / 2 sum (1 - rho^2) g^2, and t is its smaller
    root. Exact for maps affine with such slopes (one channel per subsystem); None without a root."""
    u, b = last[0], last[1]
    g, q = [], []
    for off, m in spans:
        da = [a[off + j] - u[off + j] for j in range(m)]
        den = dot(da, da)
        rho = dot(da, [y[off + j] - b[off + j] for j in range(m)]) / den if den > 0.0 else 0.0
        rho = min(max(rho, 0.0), 1.0)
        for j in range(off, off + m):
            g.append(a[j] - rho * y[j])
            q.append(1.0 - rho * rho)
    curve, slope = 0.5 * dot([qj * gj for qj, gj in zip(q, g)], g), -dot(g, g)
    excess = supplied - target
    if not slope < 0.0:
        return None
    disc = slope * slope - 4.0 * curve * excess
    if not disc >= 0.0:
        return None
    t = 2.0 * excess / (math.sqrt(disc) - slope)
    return [aj - t * gj for aj, gj in zip(a, g)]


class Redo:
    """One redo: its allowance, the step it corrects (inputs a, outputs y, supply), the rounds made,
    and each commit checked against the allowance."""

    def __init__(self, master, budget, a, y, supplied, left, round_s):
        self.master, self.budget, self.rounds = master, budget, 0
        self.a, self.y, self.supplied = a, y, supplied
        self.left_s, self.round_s = left, round_s

    def has(self, rounds):
        """Whether `rounds` evaluation rounds are left before the deadline (the redo's own counted)."""
        return self.left_s - self.rounds * self.round_s >= rounds * self.round_s

    def commit(self, inputs, s, action):
        """Commit `inputs` (None: zeros) after an undo; the redo's result if it fits (zeros always do),
        else None with the step undone again."""
        inputs = [0.0] * self.master.scene.n_channels if inputs is None else inputs
        out = self.master.recommit(inputs)
        self.rounds += 1
        return self.kept(s, inputs, out, action)

    def kept(self, s, inputs, out, action):
        """The result when the commit just made fits (or is zero), else None with the step undone and
        that commit the one the next stages correct."""
        supplied, traffic = self.master.supply(inputs, out)
        if supplied <= self.budget or action == ZERO:
            return s, supplied, traffic, action, self.rounds, inputs
        self.master.undo_step()
        if action == ITERATED:
            self.a, self.y, self.supplied = inputs, out, supplied
        return None


class EnergyLedger(Observer):
    """First of the observers: it may redo the step before anyone reads it. Wave masters' blocks
    (the C kernel books the ledger and makes the redo itself) are taken whole."""
    redoes = True
    columns = ("interface_energy", "ledger", "scale", "ledger_action", "ledger_rounds")
    formats = {"ledger_action": Labels(ACTIONS)}
    when = "the energy ledger: `master.energy_guard: ledger` (DR's default) on a master that rolls back"
    described = {
        "interface_energy": ("Iⁿ, the energy the interface supplied in the step: Σᵢ ½(‖âᵢ‖² − ‖bᵢⁿ⁺¹‖²) on the "
                             "wave masters, Δt Σ e·f on the physical ones (after a redo: the redone step's)", "J"),
        "ledger": ("Lⁿ = Σ_{k≤n} Iᵏ, the energy the interface has supplied since the start; kept at or below "
                   "roundoff (10⁻¹² of the interface's traffic)", "J"),
        "scale": ("s, where the redone step's inputs lie on the segment from the correction's anchor (s = 0) to "
                  "the inputs first committed (s = 1); 1 when the step was kept", "1"),
        "ledger_action": (f"{', '.join(ACTIONS)}: the step as committed, or the redo stage that made it (the "
                          "rest of the inner budget, a projection against the supply's gradient, a blend towards "
                          "or the input of an anchor, a scaling towards zero, zero inputs)", "text"),
        "ledger_rounds": ("evaluation rounds (every subsystem's doStep once) the redo made; 0 when the step "
                          "was kept", "1"),
    }

    def __init__(self, master):
        self.master = master
        self.n_inputs = master.scene.n_channels
        self.L, self.traffic, self.max_L = 0.0, 0.0, -math.inf
        self.acted, self.extra = 0, 0
        self.actions = [0] * len(ACTIONS)               # steps per action
        self.round_s, self.redo_round_s = 0.0, 0.0      # running time of one evaluation round: master's, redo's
        self.step_times = []            # under a deadline, per step: (wall, acted, round it may overrun by, CPU) s

    def kernel_state(self):
        """(L, traffic, RTOL): what the C kernel needs to keep the ledger itself (blocks); it adds the
        wave adapters' noise (map_noise) at each step itself, as rtol() does here."""
        return self.L, self.traffic, RTOL

    def rtol(self):
        """The allowance per unit of traffic: RTOL, plus the frozen maps' own accuracy (0.0 when exact)."""
        return RTOL + self.master.scene.map_noise()

    def after_block(self, n0, logs, readings, rows, at=None):
        """Book a block the kernel made: it kept the ledger itself, redoing steps as _redo does, bit
        for bit (drkernel.c, ledger_step), and logged each step's I^n, L^n, s, action and redo rounds."""
        led, logged = logs.ledger, logs.ledger_rows
        rows[:, :2], rows[:, 2:] = logged[0:2].T, logged[3:6].T      # supplied, ledger; scale, action, rounds
        action = led["action"]
        acted = int(np.count_nonzero(action))
        if acted:
            self.acted += acted
            self.extra += self.master.redo_doSteps()
            for code in range(1, len(ACTIONS)):
                self.actions[code] += int(np.count_nonzero(action == code))
        self.actions[KEPT] += len(action) - acted
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
        s, action, rounds = 1.0, KEPT, 0
        if self.L + supplied > tol:
            calls = master.scene.do_step_calls()
            s, supplied, traffic, action, rounds, committed = self._redo(log, inputs, outputs, supplied, tol - self.L)
            self.acted, self.extra = self.acted + 1, self.extra + master.scene.do_step_calls() - calls
            redo = StepLog(iterations=log.iterations, residual=log.residual, reason="energy-guard",
                           a_hat=committed if log.a_hat is not None else None)
        self.actions[action] += 1
        self.L += supplied
        self.traffic += traffic
        self.max_L = max(self.max_L, self.L)
        row[0], row[1], row[2], row[3], row[4] = supplied, self.L, s, action, rounds
        if master.deadline_s is not None:
            self.step_times.append((time.perf_counter() - master.step_started, action > 0, self.redo_round_s, math.nan))
        return redo

    def _redo(self, log, inputs, out_1, supplied_1, budget):
        """Undo the step and make it again by the stages of the module docstring; (s, supply, traffic,
        action, rounds, inputs committed). A master with a kernel makes the redo in C."""
        master, left, started = self.master, self._time_left(), time.perf_counter()
        done = master.redo_in_kernel(supplied_1, budget, left, self.redo_round_s)
        if done is not None:                            # the same operations, in C (drkernel.c ledger_redo)
            self._time_redo(time.perf_counter() - started, done[4])
            return done
        redo = Redo(master, budget, inputs, out_1, supplied_1, left, self.redo_round_s)
        master.undo_step()
        done = (self._iterated(redo, log) or self._projected(redo) or self._anchored(redo) or self._scaled(redo)
                or redo.commit(None, 0.0, ZERO))
        self._time_redo(time.perf_counter() - started, done[4])
        return done

    def _iterated(self, redo, log):
        """Stage 1: the rest of the inner budget (three rounds of the deadline left), committed."""
        more = self.master.remaining_iterations(log)
        if more <= 0 or not redo.has(3):
            return None
        deadline = time.perf_counter() + redo.left_s - 2.0 * redo.round_s if math.isfinite(redo.left_s) else None
        new, made = self.master.iterate_on(log, more, deadline)
        redo.rounds += made + 1
        return redo.kept(1.0, self.master.committed_inputs(new), self.master.committed_outputs, ITERATED)

    def _projected(self, redo):
        """Stage 2: against the supply's gradient (energy_ledger.projected; two rounds left)."""
        anchors = self.master.anchors()
        if not anchors or not redo.has(2):
            return None
        scene = self.master.scene
        a = projected([(off, sub.m) for sub, off in zip(scene.subsystems, scene.offsets)], redo.a, redo.y, anchors[0], redo.supplied, TARGET * redo.budget)
        if a is None:
            return None
        return redo.commit(a, 1.0 - distance(a, redo.a) / math.sqrt(dot(redo.a, redo.a)), PROJECTED)

    def _anchored(self, redo):
        """Stages 3 and 4: towards the best anchor (two rounds left), else, or on a miss, the anchor."""
        best = best_anchor(self.master.supply, self.master.anchors(), redo.a, redo.y, redo.supplied,
                           TARGET * redo.budget)
        if best is None:
            return None
        s, q = best
        if redo.has(2):
            done = redo.commit(blend(q[0], redo.a, s), s, BLENDED)
            if done is not None:
                return done
        return redo.commit(q[0], 0.0, ANCHORED)

    def _scaled(self, redo):
        """Stage 5: probe s = 0, fit the quadratic supply I(s), commit at its largest root of TARGET *
        budget (two rounds left)."""
        if not redo.has(2):
            return None
        zero = [0.0] * self.n_inputs
        out_0 = self.master.probe(zero)
        redo.rounds += 1
        s = segment_root(self.master.supply, zero, redo.a, out_0, redo.y, redo.supplied, TARGET * redo.budget)
        return redo.commit(blend(zero, redo.a, s), s, SCALED)

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
               "energy_guard_actions": dict(zip(ACTIONS, self.actions)), "max_ledger": self.max_L,
               "ledger_final": self.L, "ledger_tolerance": self.rtol() * self.traffic}
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
