"""How a subsystem's frozen port map S_i^n (paper eq. 12) is made, for any FMU.

- `DirectPort`: the FMU's own map is the one the master needs. Our FMUs in wave mode take the
  incident wave a and return b (exact and passive by construction, the fast route); in physical
  mode (physical masters) they take their input and return their output.
- `WaveAdapter`: eq. 12 for an FMU with only a physical port (input u, output y, one doStep). For
  an incident wave a it finds the held input u with e + gamma f = sqrt(2 gamma / dt) a after one
  doStep from x_i^n and returns b = sqrt(dt / (2 gamma)) (e - gamma f). Newton on u through state
  restore: the slope dy/du is estimated once per macro-step (m + 1 doSteps), refined by Broyden
  updates from the evaluations themselves and reused, and each query starts from the previous one,
  so an affine step map costs one doStep per query.

Port variables are oriented: e is the effort variable, f = sign * (the flow variable), so that
e f is the power into the FMU; `probe_signs` finds the sign where the scenario gives none, from a
slope that a larger step confirms (an FMU smooth only to its solver's tolerance reads noise at a small one).
"""
import copy
import math

import numpy as np

from ..kernel import linalg
from ..errors import ConfigError, NumericalError
from ..kernel.linalg import matvec

TOL = 1e-12          # relative residual |e + gamma f - c a| / (|c a| + |e| + gamma |f|) of a solved query
ACCEPT = 1e-4        # a stalled Newton (an FMU smooth only to its solver's tolerance) keeps its best within this
MAX_ITER = 30        # Newton iterations per query
STALL = 3            # iterations in a row without halving the residual make a stall
SLOPE_REL = 1e-5     # input perturbation for the slope estimate, relative to the input's scale
PROBE_REL = 1e-4     # first input perturbation of the orientation probe, relative to 1 + |u|
PROBE_GROWTH = 10.0  # each further probe step is this many times the last
PROBE_STEPS = 6      # probe steps at most (PROBE_REL to 1e5 PROBE_REL), for an FMU noisier than that
AGREE = 0.1          # two slope estimates agree within this fraction of the larger (and in sign)


class DirectPort:
    """The FMU's own map: wave mode (a -> b), or physical mode (oriented input -> oriented output)."""

    def __init__(self, sub, in_scale=None, out_scale=None):
        self.sub, self.in_scale, self.out_scale = sub, in_scale, out_scale

    def query(self, a):
        """The map from x_i^n; the state is discarded."""
        return self._through(self.sub.raw_query, a)

    def advance(self, a):
        """The map from x_i^n; the state is kept."""
        return self._through(self.sub.raw_advance, a)

    def _through(self, step, a):
        if self.in_scale is None:
            return step(a)
        return [s * y for s, y in zip(self.out_scale, step([s * u for s, u in zip(self.in_scale, a)]))]

    def new_step(self):
        """Nothing is cached across queries."""

    def info(self):
        """No adapter figures."""
        return None

    def memory(self):
        """Nothing is kept across queries."""
        return None

    def recall(self, memory):
        """Nothing to put back."""


class AdapterPort:
    """What every wave adapter shares, whichever solves eq. 12 (WaveAdapter here in Python, or
    wavecosim/core/adapter_kernel.py::KernelAdapter in C): orientation, wave weights, the outgoing wave,
    the error of an unsolved query and the figures. A subclass provides `_solve(a) -> (e, f)`."""

    def __init__(self, sub, effort_in, signs):
        self.sub, self.m = sub, sub.m
        self.effort_in, self.sign = [bool(x) for x in effort_in], [float(x) for x in signs]

    def weights(self, gamma):
        """Impedance of the waves: c, k and the residual's weights wu, wy, r(u) = wu u + wy y(u) - c a."""
        self.gamma = float(gamma)
        dt = self.sub.dt
        self.c, self.k = math.sqrt(2.0 * gamma / dt), math.sqrt(dt / (2.0 * gamma))
        self.wu = [1.0 if ein else gamma * s for ein, s in zip(self.effort_in, self.sign)]
        self.wy = [gamma * s if ein else 1.0 for ein, s in zip(self.effort_in, self.sign)]

    def error(self, r, why, step=None, t=None):
        """The NumericalError of an unsolved query (at the subsystem's step unless given)."""
        s = self.sub
        step, t = (s.step_index, s.t) if step is None else (step, t)
        return NumericalError(f"subsystem {s.name}: wave adapter at step {step} (t = {t:.6g}): {why}; "
                              f"residual |e + gamma f - c a| = {math.hypot(*r):.3g}")

    def stage(self, u, y):
        """Oriented (e, f) from the FMU's input and output values."""
        e = [ui if ein else yi for ein, ui, yi in zip(self.effort_in, u, y)]
        f = [s * (yi if ein else ui) for ein, s, ui, yi in zip(self.effort_in, self.sign, u, y)]
        return e, f

    def outgoing(self, e, f):
        """b = sqrt(dt / (2 gamma)) (e - gamma f) per channel (eq. 3)."""
        return [self.k * (ei - self.gamma * fi) for ei, fi in zip(e, f)]

    def query(self, a):
        """S_i^n(a); the state is discarded."""
        return self.outgoing(*self._solve(a))

    def advance(self, a):
        """Phi_i: the solved step is kept as x_i^{n+1}."""
        out = self.outgoing(*self._solve(a))
        self.sub.keep()
        return out

    def info(self):
        """Frozen-map evaluations and the doSteps they took."""
        return {"map_evaluations": self.evaluations, "doSteps": self.doSteps,
                "doSteps_per_evaluation": self.doSteps / self.evaluations if self.evaluations else math.nan,
                "stalled_queries": self.accepted, "worst_stalled_residual": self.worst_accepted}


def singular_why(y=()):
    """Why the Newton matrix is singular: a non-finite output y of the FMU (a NaN it gave, not the port's
    slope), else the port's slope."""
    bad = next((v for v in y if not math.isfinite(v)), None)
    if bad is not None:
        return f"its FMU gave a non-finite output ({bad}) at the held input, so the port's slope is not finite"
    return "the port's slope makes the Newton matrix singular (is the port's sign right?)"


def stalled_why(rel):
    return f"no convergence in {MAX_ITER} Newton iterations (best relative residual {rel:.3g} > {ACCEPT:g})"


class WaveAdapter(AdapterPort):
    """Eq. 12 through the FMU's physical port: S_i^n(a) by Newton on the held input (module docstring).
    The arithmetic is explicit loops in a fixed order (wavecosim/kernel/linalg.py), mirrored operation by
    operation in C (kernel/c/adapter.c), so both give the same numbers to the last bit."""

    def __init__(self, sub, effort_in, signs, gamma):
        super().__init__(sub, effort_in, signs)
        self.u = [0.0] * self.m                # warm start: the last solved input, kept across macro-steps
        self.y = self.D = None                 # output at u and slope dy/du (rows), valid within one macro-step
        self.J_inv = None                      # the Newton matrix's inverse, for D
        self.h2 = 0.0                          # |input step|^2 D was estimated with
        self.u_scale = 1.0                     # the input's scale in this macro-step (sum over channels)
        self.evaluations = self.doSteps = self.accepted = 0
        self.worst_accepted = 0.0              # largest relative residual kept after a stall
        self.set_gamma(gamma)

    def set_gamma(self, gamma):
        """A new impedance (between macro-steps); the Newton matrix follows."""
        self.weights(gamma)
        if self.D is not None:
            self._invert()

    def new_step(self):
        """x_i^n changed: the cached output and slope no longer hold."""
        self.y = self.D = None

    MEMORY = ("u", "y", "D", "J_inv", "h2", "u_scale", "evaluations", "doSteps", "accepted", "worst_accepted")

    def memory(self):
        """Warm start, slope and figures, to put back after queries that must leave no trace (a probe's check)."""
        return {k: copy.deepcopy(getattr(self, k)) for k in self.MEMORY}

    def recall(self, memory):
        """Back to what memory() saved."""
        for k, v in memory.items():
            setattr(self, k, v)

    def _eval(self, u):
        self.doSteps += self.sub.substeps
        return self.sub.raw_query(u)

    def _residual(self, u, y, target):
        return [wu * ui + wy * yi - ti for wu, ui, wy, yi, ti in zip(self.wu, u, self.wy, y, target)]

    def _invert(self):
        """The Newton matrix diag(wu) + diag(wy) D, inverted once per slope."""
        J = [[(wu if i == j else 0.0) + wy * dij for j, dij in enumerate(row)]
             for i, (wu, wy, row) in enumerate(zip(self.wu, self.wy, self.D))]
        inverse = linalg.inverse(J)
        if not all(math.isfinite(x) for row in inverse for x in row):
            raise self.error(self._residual(self.u, self.y, [0.0] * self.m), singular_why(self.y))
        self.J_inv = inverse

    def _estimate_slope(self, target):
        """dy/du at the warm start by forward differences (m + 1 doSteps from x_i^n)."""
        u = self.u
        self.y = y = self._eval(u)
        self.D = [[0.0] * self.m for _ in range(self.m)]
        self.h2 = self.u_scale = 0.0
        for j in range(self.m):
            scale = abs(u[j]) + (abs(target[j]) + abs(self.wy[j] * y[j])) / abs(self.wu[j])
            scale = scale if scale > 0 else 1.0
            self.u_scale += scale
            h = SLOPE_REL * scale
            self.h2 += h * h
            du = list(u)
            du[j] += h
            for row, yj, y0 in zip(self.D, self._eval(du), y):
                row[j] = (yj - y0) / h
        self._invert()

    def _secant(self, du, dy):
        """Broyden update of D from one step, unless it is shorter than the slope's own step
        (then it would carry more roundoff than D)."""
        du2 = linalg.dot(du, du)
        if du2 >= self.h2:
            miss = [p - q for p, q in zip(dy, matvec(self.D, du))]
            for row, mi in zip(self.D, miss):
                for j, dj in enumerate(du):
                    row[j] += mi * dj / du2
            self._invert()

    def _solve(self, a):
        """The held input for incident wave a; the FMU is left at Phi(x_i^n, u). Returns (e, f)."""
        self.evaluations += 1
        target = [self.c * float(x) for x in a]
        if self.D is None:
            self._estimate_slope(target)
        u, y = self.u, self.y
        best, stalled = None, 0
        for _ in range(MAX_ITER):
            u_new = [ui - s for ui, s in zip(u, matvec(self.J_inv, self._residual(u, y, target)))]
            y_new = self._eval(u_new)
            r = self._residual(u_new, y_new, target)
            rel = self._relative(r, u_new, y_new, target)
            if rel > TOL:
                self._secant([p - q for p, q in zip(u_new, u)], [p - q for p, q in zip(y_new, y)])
            self.u, self.y = u, y = u_new, y_new
            if rel <= TOL:
                return self.stage(u, y)
            stalled = stalled + 1 if best is not None and rel > 0.5 * best[0] else 0
            if best is None or rel < best[0]:
                best = (rel, u, y)
            if stalled >= STALL:
                break
        return self._accept(best, r)

    def _relative(self, r, u, y, target):
        """The residual relative to the terms it balances, or the next Newton correction relative
        to the input's scale (near rest, where the terms themselves vanish): the smaller."""
        size = 0.0
        for t, wu, ui, wy, yi in zip(target, self.wu, u, self.wy, y):
            size += abs(t) + abs(wu * ui) + abs(wy * yi)
        norm = linalg.norm1(r)
        step = linalg.norm1(matvec(self.J_inv, r)) / self.u_scale
        return min(norm / size if size > 0 else (0.0 if norm == 0 else math.inf), step)

    def _accept(self, best, r):
        """Newton stalled (an FMU whose step map is smooth only to its own solver's tolerance): the
        best point is kept when within ACCEPT, and the FMU put there; otherwise the query fails."""
        rel, u, y = best
        if rel > ACCEPT:
            raise self.error(r, stalled_why(rel))
        self.accepted += 1
        self.worst_accepted = max(self.worst_accepted, rel)
        if u is not self.u:
            self.u, self.y = u, self._eval(u)
        return self.stage(self.u, self.y)


def agree(p, q):
    """Two finite-difference estimates tell the same: one sign, and within AGREE of the larger."""
    return p * q > 0 and abs(p - q) <= AGREE * max(abs(p), abs(q))


def _probe_slope(sub, u0, y0, j):
    """dy_j/du_j by forward differences at steps h, PROBE_GROWTH h, ...: the first estimate the next
    step confirms (agree). An exact FMU is confirmed at once; one smooth only to its solver's tolerance
    reads noise at a small step and is retried with larger ones. Returns (slope, {step, check}) or
    (None, the slopes read at each step)."""
    h = PROBE_REL * (1.0 + abs(u0[j]))
    steps, slopes = [], []
    for k in range(PROBE_STEPS):
        steps.append(h * PROBE_GROWTH ** k)
        u = u0.copy()
        u[j] += steps[-1]
        slopes.append((sub.raw_query(list(u))[j] - y0[j]) / steps[-1])
        if not math.isfinite(slopes[-1]):
            break
        if k and agree(slopes[-2], slopes[-1]):
            return slopes[-2], {"step": steps[-2], "slope": slopes[-2], "check_step": steps[-1],
                                "check_slope": slopes[-1], "steps_tried": k + 1}
    return None, list(zip(steps, slopes))


def probe_signs(sub, where, t0=0.0):
    """The sign of dy/du over one doStep (at the start time t0) from the restored initial state, per
    channel: the sign that makes the port passive (FACTS.md, port orientation). Returns (signs,
    slopes, what was probed)."""
    u0 = np.asarray(sub.read(sub.port.physical_in), float)
    sub.freeze(0, t0)
    y0 = np.asarray(sub.raw_query(list(u0)))
    signs, slopes, probed = [], [], []
    for j in range(sub.m):
        slope, info = _probe_slope(sub, u0, y0, j)
        if slope is None:
            sub.thaw()
            name = f"d{sub.port.physical_out[j]}/d{sub.port.physical_in[j]}"
            read = ", ".join(f"{d:.3g} at step {h:.3g}" for h, d in info)
            raise ConfigError(f"{where}.sign: cannot find the orientation of channel {j} by probing (one doStep "
                              f"gives {name} = {read}: no two successive steps agree in sign and within "
                              f"{AGREE:g}); give the sign")
        signs.append(1.0 if slope > 0 else -1.0)
        slopes.append(slope)
        probed.append(info)
    sub.thaw()
    return signs, slopes, probed
