"""The tolerance mode (`master.tolerance`): the macro-step varies, chosen per step from a local error
estimate against the tolerance; a step whose estimate is too large is undone and made again smaller.

`adaptive(cls)` gives a subclass of any master whose step(n, t) is the controlled step: it sets the
step size h on every subsystem, makes the master's own step once (or three times, `doubling`), and
accepts or rejects it. Estimates (docs/masters.md, choosing a tolerance):
  predictor  the watched outputs z^{n+1} (the error columns) against their extrapolation by the
             polynomial of degree p through the last p + 1 accepted points (Milne's device), scaled
             to the step's h^(p+1); p is the master's order (base.error_order). No FMU call of its own.
  coupling   for a master that holds its inputs (explicit, gauss-seidel): half the change in the
             watched outputs that the other end of each FMU's held inputs makes, the FMU made again
             from the step's start with them and put back (one doStep per FMU). `auto` takes it for
             the FMUs set up with a tolerance (their solver keeps its own error below it, so the
             error of a step is the coupling's) and the predictor for the others.
  doubling   two steps of h/2 against one step of h from the same state (Richardson, as MasterSim
             and PyFMI); the step of h is the one committed, so the energy ledger books it as any step.
All are scaled per unit step (times (T - t0) / h), so the error over the run, not of one step,
stays near the tolerance. Iterating masters stop their inner loop once its residual is below
INNER_SHARE of the step's allowance (their `eps`), within the budget K; DR starts it from its waves
extrapolated over the varying step. Each try holds the signals and steps the subsystems without a
port by its h (Scene.begin_step); a rejected try puts them back with the others. A run whose watched
values are all zero at t0 has no size to be relative to: PILOT_STEPS steps of the master's own over
the span give them one first (masters that hold their inputs: one doStep per FMU a step), and
everything is put back.
"""
import copy
import math
from dataclasses import dataclass, replace

from ..errors import ConfigError
from ..kernel.linalg import matvec, matvec_rows
from .base import error_order

SAFETY, SHRINK, GROW = 0.9, 0.2, 5.0          # h_new = h clamp(SAFETY (1/err)^(1/p), SHRINK, GROW)
STARTUP = 0.01                                # the predictor's first p + 1 steps, which have no estimate
                                              # yet: dt x STARTUP, or x the tolerance where it is smaller
INNER_SHARE = 0.1                             # the inner residual allowed, as a share of the step's allowance
ATOL_SHARE = 0.1                              # default atol: this share of tolerance x the largest variable's size
CALIBRATION = 1.0                             # the estimate's weight (measured against the true error)
PILOT_STEPS = 20                              # a run from rest: the sizes of this many steps of (T - t0) / 20
FMU_SHARE = 1e-3                              # fmu_tolerance auto: the FMUs' set-up tolerance, this share of tolerance
STATE = ("y", "y_step_start", "u", "_b", "_b_step_start", "_b_before", "_a_before", "_a_step_start")


@dataclass
class StepRecord:
    """What the controller did in the step just made (the steps.csv columns of run/observers/step_control.py)."""
    dt: float = math.nan
    estimate: float = math.nan
    rejected: int = 0
    inner_eps: float = math.nan


def extrapolate(times, values, t):
    """The polynomial through the points (times[j], values[j]) (lists of floats) at t (Lagrange form)."""
    out = [0.0] * len(values[0])
    for j, (tj, zj) in enumerate(zip(times, values)):
        w = 1.0
        for k, tk in enumerate(times):
            if k != j:
                w *= (t - tk) / (tj - tk)
        out = [o + w * z for o, z in zip(out, zj)]
    return out


class Controller:
    """Tolerances, step bounds and the next step size from an estimate (err <= 1: accepted)."""

    def __init__(self, settings, dt, span, order):
        self.rtol, self.atol, self.order, self.span = settings.tolerance, settings.atol, order, span
        self.h_min = settings.dt_min or dt / 1000.0
        self.h_max = settings.dt_max or span / 10.0
        self.h = min(max(dt, self.h_min), self.h_max)
        self.size = None                      # each interface variable's largest size so far

    def observe(self, z):
        """Take the accepted values z into each variable's size."""
        self.size = [abs(v) for v in z] if self.size is None else [max(s, abs(v)) for s, v in zip(self.size, z)]

    def error(self, diff, h):
        """The scaled estimate of a step of h whose local error is `diff` per variable, per unit step."""
        floor = self.atol if self.atol is not None else ATOL_SHARE * self.rtol * max(self.size, default=0.0)
        worst = max((abs(d) / (floor + self.rtol * s) if floor + self.rtol * s > 0 else 0.0
                     for d, s in zip(diff, self.size)), default=0.0)
        return CALIBRATION * worst * self.span / h

    def next(self, h, err):
        """The step after one of h with estimate err (NaN: no estimate, h kept)."""
        if err != err:
            return h
        factor = GROW if err <= 0.0 else min(GROW, max(SHRINK, SAFETY * err ** (-1.0 / self.order)))
        return min(self.h_max, max(self.h_min, h * factor))

    def inner_eps(self, size, h):
        """The inner loop's stop: INNER_SHARE of the step's allowance on a variable of this size."""
        return INNER_SHARE * self.rtol * size * math.sqrt(h / self.span) if size > 0 else None


def check_tolerance_mode(scene, settings, source):
    """Refuse what the tolerance mode cannot drive, in one line."""
    fixed = [s.name for s in scene.subsystems + scene.signal_only if not getattr(s.fmu, "variable_steps", True)]
    if fixed:
        raise ConfigError(f"{source}: master.tolerance: subsystem {fixed[0]}'s FMU cannot change its communication "
                          f"step size (canHandleVariableCommunicationStepSize=\"false\"); run it with a fixed dt")
    everyone = scene.subsystems + (scene.signal_only if settings.estimate == "coupling" else [])
    if settings.estimate in ("doubling", "coupling") and not all(s.fmu.can_save_state for s in everyone):
        raise ConfigError(f"{source}: master.estimate: {settings.estimate} needs every FMU to get and set its state")


def holds_inputs(master):
    """Whether the master holds each FMU's inputs over the step without iterating (explicit,
    gauss-seidel): its error is the coupling's where the FMUs integrate accurately."""
    return not master.wave and not master.needs_rollback


def coupled(master, settings):
    """The watched subsystems whose estimate is `coupling` (module docstring), by name."""
    if settings.estimate == "coupling" and not holds_inputs(master):
        raise ConfigError(f"{master.scene.scenario.source}: master.estimate: coupling needs a master that holds its "
                          f"inputs over the step (explicit, gauss-seidel), not {master.settings.algorithm}")
    if settings.estimate not in ("auto", "coupling") or not holds_inputs(master) or not master.can_reject:
        return set()                     # each step's snapshot, which the estimate makes again from, is saved
    return {s.name for s, _ in master.watched if s in master.subsystems         # a port's inputs to vary
            and (settings.estimate == "coupling" or s.fmu.tolerance is not None)}


def watched(scene):
    """[(subsystem, variable names)] the estimate watches: the scenario's error columns (those the
    true error is measured on), else every recorded output; Real variables of any subsystem, not a
    wave port's outgoing wave (it scales with sqrt(h)). An FMU's port stage values are
    not watched: several FMUs give them at the middle of the step, not at its end."""
    sc = scene.scenario
    refs = [scene.outputs[c] for c in (sc.error or list(scene.outputs)) if c in scene.outputs]
    out = []
    for s in scene.subsystems + scene.signal_only:
        names = [ref.split(".", 1)[1] for ref in refs if ref.split(".", 1)[0] == s.name]
        names = [v for v in names if s.fmu.kind(v) == s.fmu.real_type and v not in s.port.wave_out]
        if names:
            out.append((s, names))
    if not out:
        raise ConfigError(f"{sc.source}: master.tolerance: no Real output to estimate the error on (error: or "
                          f"outputs:)")
    return out


class AdaptiveStep:
    """Mixin over a master: its step(n, t) is the controlled step (module docstring)."""
    variable = True

    def __init__(self, scene, settings):
        super().__init__(scene, replace(settings, fast="false"))       # the Python route, step by step
        check_tolerance_mode(scene, settings, scene.scenario.source)
        if settings.start == "auto" and hasattr(self, "start"):
            self.start = "extrapolated"          # DR's start over the varying step (_start_iterate)
        sc = scene.scenario
        self.end, self.span, self.t0 = sc.T, sc.T - sc.start_time, sc.start_time
        self.every = settings.output_step
        self.p = error_order(self)
        self.control = Controller(settings, sc.dt, self.span, self.p)
        self.doubling = settings.estimate == "doubling"
        self.alone = scene.signal_only          # stepped with each try's h after the signals are held
        self.can_reject = all(s.fmu.can_save_state for s in scene.subsystems + self.alone)
        self.snapshots = self.doubling or not self.needs_rollback
        self.times, self.points = [sc.start_time], []
        self.h_set, self.h_made, self.wave_size = sc.dt, sc.dt, 0.0     # h now; h of the step that gave b^n
        self.watched = watched(scene)
        self.coupled = coupled(self, settings)
        self.predicted = any(s.name not in self.coupled for s, _ in self.watched)    # needs p + 1 points first
        self.step_record = StepRecord()
        self.accepted = self.rejected = 0
        self.piloted = False

    def time_at(self, k):
        """The time after k accepted steps."""
        return self.times[k]

    def more(self, n):
        """Whether the run has steps left after n accepted ones."""
        return self.times[n] < self.end

    def _stage(self):
        """The values the estimate watches, at the end of the step just made."""
        return [float(v) for s, names in self.watched for v in s.read(names)]

    def _set_h(self, h):
        """Every subsystem steps by h; committed waves are rescaled to it (waves carry sqrt(h))."""
        if h == self.h_set:
            return
        ratio = math.sqrt(h / self.h_set)
        if self.wave:
            for name in STATE[3:]:
                value = getattr(self, name, None)
                if value is not None:
                    setattr(self, name, [v * ratio for v in value])
        for s in self.subsystems + self.alone:
            s.set_step(h)
        self.dt, self.h_set = h, h

    def _save(self):
        """The step's start: every FMU's state (snapshots; the rollback masters' own freeze serves
        otherwise), the step size the waves are scaled to, the master's committed values, the ledger's
        figures and DR's Anderson differences."""
        snap = self.can_reject or self.doubling
        for s in ((self.subsystems if self.snapshots else []) + self.alone) if snap else []:
            s.snapshot()
        values = {k: getattr(self, k).copy() for k in STATE if getattr(self, k, None) is not None}
        return {"h": self.h_set, "values": values, "ledger": self._ledger_state(), "snapshots": snap,
                "h_made": self.h_made, "anderson": copy.deepcopy(getattr(self, "anderson", None))}

    def _ledger_state(self):
        """The energy ledger's running figures (L and its traffic), in Python and in the kernel, so a
        rejected try books nothing: [(holder, attribute, value)]."""
        kernel = getattr(self, "kernel", None)
        holders = [(self.guard, ("L", "traffic"))] + ([(kernel.io, ("ledger", "traffic"))] if kernel else [])
        return [(h, a, getattr(h, a)) for h, names in holders for a in names if hasattr(h, a)]

    def _restore(self, saved):
        """Everything back at the step's start (_save)."""
        for s in self.subsystems:
            if self.snapshots:
                s.back_to_snapshot()
            else:
                s.restore_frozen()
        for s in self.alone if saved["snapshots"] else []:
            s.back_to_snapshot()
        for s in self.subsystems + self.alone:
            s.set_step(saved["h"])
        self.scene.ended = None
        self.dt = self.h_set = saved["h"]
        self.h_made = saved["h_made"]
        for k, v in saved["values"].items():
            setattr(self, k, v.copy())
        for holder, name, value in saved["ledger"]:
            setattr(holder, name, value)
        if saved["anderson"] is not None:       # DR's Anderson differences kept across steps (anderson_memory)
            self.anderson = copy.deepcopy(saved["anderson"])

    def _start_iterate(self):
        """DR's start `extrapolated` over a varying step: P (b^n + r (b^n - b^{n-1})), r the ratio of this
        step to the one that gave b^n (the fixed grid's P (2 b^n - b^{n-1}) when they are equal)."""
        if getattr(self, "start", None) != "extrapolated" or self._b_before is None:
            return super()._start_iterate()
        r = self.h_set / self.h_made
        u, self._b_before = matvec(self.P, [b + r * (b - bp) for b, bp in zip(self.b, self._b_before)]), self.b
        return u

    def _target(self, t):
        """Where the step from t must end at the latest: T, or the next output time (output_step)."""
        if self.every is None:
            return self.end
        k = math.floor((t - self.t0) / self.every * (1.0 + 1e-12)) + 1
        return min(self.end, self.t0 + k * self.every)

    def _fit(self, t, h):
        """h cut so the step ends on T (or the next output time), without leaving a sliver of a step."""
        left = self._target(t) - t
        if h >= left * (1.0 - 1e-9):
            return left
        return left / 2.0 if h > left / 2.0 else h

    def _inner_eps(self, h):
        """The iterating masters' inner stop for a step of h."""
        if not self.needs_rollback:
            return None
        if self.wave:
            self.wave_size = max(self.wave_size, max((abs(b) for b in self._b), default=0.0) / math.sqrt(self.h_set))
            return self.control.inner_eps(self.wave_size * math.sqrt(h), h)
        return self.control.inner_eps(max(self.control.size or [0.0]), h)

    def _make(self, n, t, h):
        """The master's own step of h from t, after the signals are held and the signal-only
        subsystems stepped by h (Scene.begin_step)."""
        self._set_h(h)
        self.scene.begin_step(n, t)
        log = super().step(n, t)
        self.h_made = h
        return log

    def _attempt(self, n, t, h, saved):
        """One try of a step of h from the saved state: (its StepLog, the scaled estimate)."""
        eps = self._inner_eps(h)
        if eps is not None and hasattr(self, "eps"):
            self.eps = eps
        self.step_record.inner_eps = math.nan if eps is None else eps
        if self.doubling:
            self._make(n, t, h / 2.0)
            self._make(n, t + h / 2.0, h / 2.0)
            half = self._stage()
            self._restore(saved)
            log = self._make(n, t, h)
            gain = 2.0 ** self.p / (2.0 ** self.p - 1.0)
            return log, self.control.error([gain * (a - b) for a, b in zip(half, self._stage())], h)
        log = self._make(n, t, h)
        if self.predicted and len(self.points) <= self.p:
            return log, math.nan
        diff = self._predictor_diff(t, h) if self.predicted else None
        parts, at = [], 0
        for sub, names in self.watched:
            parts += (self._coupling_diff(saved, sub, names) if sub.name in self.coupled else diff[at:at + len(names)])
            at += len(names)
        return log, self.control.error(parts, h)

    def _predictor_diff(self, t, h):
        """The watched values against their extrapolation through the last p + 1 accepted points,
        scaled to the step's h^(p+1) (Milne's device)."""
        nodes = self.times[-1 - self.p:]
        guess = extrapolate(nodes, self.points[-1 - self.p:], t + h)
        weight = h ** (self.p + 1) / math.prod(t + h - tj for tj in nodes)      # z^(p+1) h^(p+1) / (p+1)!
        return [weight * (a - b) for a, b in zip(self._stage(), guess)]

    def _coupling_diff(self, saved, sub, names):
        """Half the change in `names` that the other end of the subsystem's held inputs makes over the
        step just made (its FMU made again from the step's start with them, then put back)."""
        off = self.scene.offsets[self.subsystems.index(sub)]
        start = matvec_rows(self.G, saved["values"]["y"], off, off + sub.m)
        end = matvec_rows(self.G, self.y, off, off + sub.m)
        other = [a + b - u for a, b, u in zip(start, end, self.held[off:off + sub.m])]
        return [(a - b) / 2.0 for a, b in zip(sub.response(other, names), sub.read(names))]

    def _pilot(self, n, t):
        """Each watched variable's size over PILOT_STEPS steps of the master's own step across the
        span, for a run whose watched values are all zero at t0; everything is then put back."""
        flags = [(s, s.no_prior, s.alone_no_prior) for s in self.subsystems + self.alone]
        for s, _, _ in flags:                   # the pilot's doSteps do not promise to stay ahead of t0
            s.snapshot()
            s.no_prior = s.alone_no_prior = 0
        saved, snapshots, h = self._save(), self.snapshots, self.span / PILOT_STEPS
        sizes = [abs(v) for v in self._stage()]
        for k in range(PILOT_STEPS):
            self._make(n + k, t + k * h, h)
            sizes = [max(a, abs(v)) for a, v in zip(sizes, self._stage())]
        self.snapshots = True
        self._restore(saved)
        self.snapshots = snapshots
        for s, no_prior, alone in flags:
            s.no_prior, s.alone_no_prior = no_prior, alone
        self.control.observe(sizes)
        self.piloted = True

    def step(self, n, t):
        if self.points:                     # the last accepted step as committed (an energy guard may redo it)
            self.points[-1] = self._stage()
        elif self.can_reject and holds_inputs(self) and not any(self._stage()):
            self._pilot(n, t)
        self.control.observe(self.points[-1] if self.points else self._stage())
        saved, rejected = self._save(), 0
        startup = self.predicted and len(self.points) <= self.p
        first = self.control.h * min(STARTUP, self.control.rtol)           # unchecked: small for the tolerance
        h = self._fit(t, max(self.control.h_min, first) if startup else self.control.h)
        while True:
            log, err = self._attempt(n, t, h, saved)
            if not err > 1.0 or h <= self.control.h_min or not self.can_reject:
                break
            rejected += 1
            self._restore(saved)
            h = self._fit(t, self.control.next(h, err))
        target = self._target(t)
        self.times.append(target if h == target - t else t + h)
        self.points = self.points[-self.p:] + [self._stage()]      # the accepted steps' values, t0 not among them
        self.control.h = self.control.next(h, err) if err == err else self.control.h
        self.step_record.dt, self.step_record.estimate, self.step_record.rejected = h, err, rejected
        self.accepted, self.rejected = self.accepted + 1, self.rejected + rejected
        return log

    def _estimate_name(self):
        """The estimate as run: doubling, predictor, coupling, or which subsystems take coupling."""
        if self.doubling or not self.coupled:
            return "doubling" if self.doubling else "predictor"
        if not self.predicted:
            return "coupling"
        return f"coupling ({', '.join(sorted(self.coupled))}), predictor (the others)"

    def run_info(self):
        return {**super().run_info(), "tolerance": self.control.rtol, "estimate": self._estimate_name(),
                "pilot": self.piloted,
                "dt_smallest": min(b - a for a, b in zip(self.times, self.times[1:])) if self.accepted else math.nan,
                "dt_largest": max(b - a for a, b in zip(self.times, self.times[1:])) if self.accepted else math.nan}


def fmu_tolerance_cap(settings):
    """The largest set-up tolerance of an FMU that has one (settings.fmu_tolerance; None: as given)."""
    if settings.fmu_tolerance == "auto":
        return FMU_SHARE * settings.tolerance if settings.tolerance is not None else None
    return settings.fmu_tolerance


def adaptive(cls, settings):
    """The master class a run uses: cls itself without a tolerance, else cls under step control."""
    if settings.tolerance is None:
        return cls
    return type(f"Adaptive{cls.__name__}", (AdaptiveStep, cls), {})
