"""Automatic choice of the scattering impedances (paper Remark 2, gamma-tuning).

With a reciprocal incremental port response de = Z_d df, the frozen port map has the Jacobian
J_S = (Z_d - gamma I)(Z_d + gamma I)^-1, and Condition 1 (FNE) holds locally iff gamma <= lambda_min(Z_d)
(eq. 26). The condition is per subsystem, and the wave map P stays orthogonal for any positive
impedance on each channel (Remark 1), so each subsystem i gets its own gamma_i <= lambda_min(Z_d,i);
among those we pick the gammas whose linearized Douglas-Rachford operator
T = 1/2 (I + R_L R_S), R = 2 J - I (Section IV-B), has the smallest spectral radius.

Z_d is measured, not assumed: each frozen subsystem is queried at the operating point and at
m perturbed incident waves, and the stage outputs e, f give dE = Z_d dF directly, which does not
depend on gamma (the closure e + gamma f = sqrt(2 gamma / dt) a only selects the point). So one
probe predicts J_S at every gamma: J_S(gamma) = (dE - gamma dF)(dE + gamma dF)^-1.
The probe gamma is chosen from is checked against a step PROBE_GROWTH times larger and taken
from larger steps when the two disagree (an FMU smooth only to its solver's tolerance).

Modes (YAML `gamma:` or `--gamma`; they override per-subsystem `gamma:` keys):
- a number: fixed;
- `auto`: chosen once at t = 0, every gamma_i at most SAFETY times its subsystem's FNE bound, so
  Theorem 1 keeps holding;
- `auto-retune`: the same, and lowered between macro-steps whenever a bound drops below its gamma
  (the committed wave b is re-scattered to the new gammas); gammas never go up again;
- `fastest`: like `auto`, but each gamma_i up to FASTEST_SAFETY times its FNE bound, found by a
  coordinate grid before Nelder-Mead, for the fastest contraction of the DR operator with the
  relaxation in force (`master.relaxation`; with `auto`, the best lambda for each candidate);
- `fast-unsafe`: one common gamma with the fastest contraction at any value, usually above the
  smaller FNE bound (near the geometric mean of the port impedances). It leaves Condition 1 and
  Theorem 1; the run warns and reports the augmented residual.
"""
import hashlib
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import interconnection as ic
from . import simplex
from .waves import outgoing_wave
from ..errors import ConfigError, NumericalError
from ..kernel.build import cache_dir

MODES = ("auto", "auto-retune", "fast-unsafe", "fastest")       # the one list of gamma modes
PROBE_GAMMA = 0.4       # the gamma FMUs start at (when the scenario gives no number) before a mode probes them
SAFETY = 0.9            # auto stays this far inside the FNE bound (Z_d drifts along the trajectory)
RETUNE_ABOVE = 0.95     # auto-retune lowers gamma when it exceeds this fraction of the bound
PROBE_REL = 1e-6        # size of the incident-wave perturbation, relative to the operating point
PROBE_GROWTH = 10.0     # a checked probe: each further incident-wave step is this many times the last
PROBE_STEPS = 6         # a checked probe: steps at most (PROBE_REL to 1e5 PROBE_REL)
AGREE = 1e-3            # two probes agree when their J_S at the probe's gamma differ by at most this
FASTEST_SAFETY = 0.99   # fastest stays this far inside the FNE bound
GRID_POINTS = 25        # fastest: log-spaced gammas per subsystem in each coordinate sweep
RELAX_GRID = tuple(0.05 * i for i in range(1, 40))      # relaxation: auto tries lambda = 0.05 .. 1.95
RELAX_GAIN = 0.98       # relaxation: auto keeps lambda = 1 unless the predicted rate falls below this fraction


def parse_gamma(value, where="gamma"):
    """A gamma as given on the command line or in the API: a number > 0 or one of MODES."""
    if isinstance(value, str) and value in MODES:
        return value
    try:
        gamma = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: must be a number > 0 or {', '.join(MODES)}; got {value!r}") from None
    if not (gamma > 0 and math.isfinite(gamma)):
        raise ConfigError(f"{where}: must be > 0, got {value}")
    return gamma


def initial_gammas(scenario):
    """{subsystem: gamma} the FMUs are instantiated with. The one precedence rule: a subsystem's own
    `gamma` wins over the scenario's number; with a mode (auto, ...) the tuner then replaces every
    one, starting from these (PROBE_GAMMA where no number is given)."""
    default = scenario.gamma if not isinstance(scenario.gamma, str) else PROBE_GAMMA
    return {s.name: float(s.gamma if s.gamma is not None else default) for s in scenario.subsystems}


@dataclass
class PortProbe:
    """Incremental port response of one frozen subsystem around an operating point.

    Column j of dE, dF is the change of the stage effort and flow when incident channel j moves
    by `h`; so dE = Z_d dF, whatever gamma the FMU was probed with."""
    name: str
    dE: np.ndarray
    dF: np.ndarray
    gamma: float
    step: float = math.nan          # the incident-wave step h
    checked: dict = None            # with probe_port(check=True): how a larger step confirmed it

    def impedance(self):
        """Z_d = dE dF^-1 (inf where the port does not move, e.g. a clamped channel)."""
        try:
            return self.dE @ np.linalg.inv(self.dF)
        except np.linalg.LinAlgError:
            return np.full_like(self.dE, np.inf)

    def fne_bound(self):
        """Largest gamma with Condition 1 here: min over df of <df, Z_d df> / |df|^2 = lambda_min(sym Z_d).

        Computed as a generalized eigenvalue on the range of dF, so infinite impedance directions
        (df = 0) impose no bound."""
        A = 0.5 * (self.dF.T @ self.dE + self.dE.T @ self.dF)
        M = self.dF.T @ self.dF
        w, V = np.linalg.eigh(M)
        keep = w > 1e-20 * max(float(w.max()), 1e-300)
        if not keep.any():
            return math.inf
        W = V[:, keep] / np.sqrt(w[keep])
        return float(np.linalg.eigvalsh(W.T @ A @ W).min())

    def scale(self):
        """A representative impedance magnitude |Z_d| (for the unconstrained search range)."""
        Z = self.impedance()
        finite = np.abs(Z[np.isfinite(Z)])
        return float(finite.max()) if finite.size and finite.max() > 0 else math.inf

    def jacobian(self, gamma):
        """J_S(gamma) = (dE - gamma dF)(dE + gamma dF)^-1, the frozen map's slope at this gamma."""
        return np.linalg.solve((self.dE + gamma * self.dF).T, (self.dE - gamma * self.dF).T).T

    def fne_margin(self, gamma):
        """Scale-free tangent FNE margin min_v (<J v, v> - |J v|^2) / |v|^2 (>= 0 under Condition 1)."""
        J = self.jacobian(gamma)
        return float(np.linalg.eigvalsh(0.5 * (J + J.T) - J.T @ J).min())


def _columns(sub, centre, ef0, h):
    """dE, dF of one forward-difference probe: incident channel j moved by h from `centre`."""
    m = sub.m
    dE, dF = np.zeros((m, m)), np.zeros((m, m))
    for j in range(m):
        a = centre.copy()
        a[j] += h
        sub.query(list(a))
        d = (np.asarray(sub.stage()) - ef0) / h
        dE[:, j], dF[:, j] = d[:m], d[m:]
    return dE, dF


def _checked(sub, centre, ef0, h, first):
    """The first probe if a PROBE_GROWTH times larger step confirms it (the two predict J_S at the probe's
    gamma within AGREE), with the port map's memory put back, so an exact FMU ends as if unchecked; else
    larger steps until two successive ones agree (an FMU smooth only to its solver's tolerance reads
    noise at a small step), or the largest. Records step, check step and their difference in `checked`."""
    memory = sub.map.memory()
    probes = [first]
    for k in range(1, PROBE_STEPS):
        step = h * PROBE_GROWTH ** k
        probes.append(PortProbe(sub.name, *_columns(sub, centre, ef0, step), sub.gamma, step))
        diff = float(np.abs(probes[-2].jacobian(sub.gamma) - probes[-1].jacobian(sub.gamma)).max())
        if diff <= AGREE:
            break
    agreed = diff <= AGREE
    chosen = probes[-2] if agreed else probes[-1]
    chosen.checked = {"step": chosen.step, "check_step": probes[-1].step, "jacobian_difference": diff,
                      "agreed": agreed, "steps_tried": len(probes)}
    if agreed and len(probes) == 2:
        sub.map.recall(memory)
    return chosen


def probe_port(sub, centre, rel=PROBE_REL, check=False) -> PortProbe:
    """Probe one frozen subsystem at incident wave `centre` (m + 1 queries); its state is unchanged.
    With `check`, the probe is confirmed against larger steps (_checked)."""
    centre = np.asarray(centre, float)
    b0 = np.asarray(sub.query(list(centre)))
    ef0 = np.asarray(sub.stage())
    h = rel * (float(np.abs(centre).max()) + float(np.abs(b0).max())) or rel * math.sqrt(sub.dt)
    probe = PortProbe(sub.name, *_columns(sub, centre, ef0, h), sub.gamma, h)
    if check:
        probe = _checked(sub, centre, ef0, h, probe)
    sub.thaw()
    return probe


def probe_scene(scene, b, n, t, P=None, check=False, u0=None):
    """Freeze every subsystem at x^n, probe it around u^0 = P b^n (or the stacked u0 given), and put
    it back at x^n."""
    P = scene.wave_map().P if P is None else P
    centre = scene.split(list(np.asarray(P, float) @ np.asarray(b, float)) if u0 is None else u0)
    probes = []
    for s, c in zip(scene.subsystems, centre):
        s.freeze(n, t)
        probes.append(probe_port(s, c, check=check))
    return probes


def _reflections(scene, probes, gammas):
    """(R_L, R_S) = (2 J_L - I, 2 J_S - I) of the linearized DR iteration with impedance gammas[i]
    on the channels of subsystem i (P and J_L compiled for those impedances)."""
    n = scene.n_channels
    J_S = np.zeros((n, n))
    for p, off, s, g in zip(probes, scene.offsets, scene.subsystems, gammas):
        J_S[off:off + s.m, off:off + s.m] = p.jacobian(g)
    channel = [g for g, s in zip(gammas, scene.subsystems) for _ in range(s.m)]
    J_L = ic.compile_wave_map(scene.E, scene.F, channel).J_L
    return 2.0 * J_L - np.eye(n), 2.0 * J_S - np.eye(n)


def dr_rate(scene, probes, gammas):
    """Spectral radius of the linearized DR operator T = 1/2 (I + R_L R_S)."""
    R_L, R_S = _reflections(scene, probes, gammas)
    T = 0.5 * (np.eye(len(R_L)) + R_L @ R_S)
    return float(np.abs(np.linalg.eigvals(T)).max())


def relaxed_rate(mu, lam):
    """Spectral radius of the relaxed DR operator I + lam/2 (R_L R_S - I), from the eigenvalues mu of R_L R_S."""
    return float(np.abs(1.0 + 0.5 * lam * (mu - 1.0)).max())


def best_relaxation(mu):
    """(lambda, rate): the lambda of RELAX_GRID with the fastest predicted contraction, or 1 (the paper's
    update) unless that beats it by RELAX_GAIN."""
    plain = relaxed_rate(mu, 1.0)
    lam = min(RELAX_GRID, key=lambda x: (relaxed_rate(mu, x), abs(x - 1.0)))
    best = relaxed_rate(mu, lam)
    return (lam, best) if best < RELAX_GAIN * plain else (1.0, plain)


def dr_eigenvalues(scene, probes, gammas):
    """Eigenvalues of R_L R_S, the reflected operator whose averages are (relaxed) DR."""
    R_L, R_S = _reflections(scene, probes, gammas)
    return np.linalg.eigvals(R_L @ R_S)


def choose_relaxation(scene, b, P):
    """`master.relaxation: auto`: probe the frozen maps at x^0 around u^0 = P b, predict the contraction
    of each lambda from the linearized operator and pick the fastest (best_relaxation)."""
    probes = probe_scene(scene, b, 0, scene.scenario.start_time, P)
    mu = dr_eigenvalues(scene, probes, [scene.gammas[s.name] for s in scene.subsystems])
    lam, rate = best_relaxation(mu)
    return {"relaxation": lam, "rate_plain": relaxed_rate(mu, 1.0), "rate_relaxed": rate}


def _fastest_rate(scene, probes):
    """The objective of gamma: fastest: the predicted rate with master.relaxation (auto: the best lambda)."""
    lam = scene.scenario.master.relaxation
    if lam == "auto":
        return lambda g: best_relaxation(dr_eigenvalues(scene, probes, g))[1]
    return lambda g: relaxed_rate(dr_eigenvalues(scene, probes, g), float(lam))


def _coordinate_grid(rate, lo, hi, start):
    """Two sweeps over the subsystems, each gamma_i over GRID_POINTS log-spaced values in [lo_i, hi_i]."""
    g = list(start)
    for _ in range(2):
        for i in range(len(g)):
            g[i] = min(np.geomspace(lo[i], hi[i], GRID_POINTS), key=lambda x: rate(g[:i] + [float(x)] + g[i + 1:]))
            g[i] = float(g[i])
    return g


@dataclass
class GammaChoice:
    """One decision: the impedance of each subsystem's port, the FNE bounds it respects (or not),
    and the predicted contraction rate of the inner iteration."""
    gammas: dict
    mode: str
    bounds: dict
    rate: float
    guaranteed: bool

    @property
    def violations(self):
        """{subsystem: (gamma, bound)} where gamma is above the FNE bound."""
        return {k: (g, self.bounds[k]) for k, g in self.gammas.items() if g > self.bounds[k]}


def _search(rate, lo, hi, starts):
    """Minimize rate(gammas) over the box [lo_i, hi_i]: the best start, then Nelder-Mead in log gamma
    (the spectral radius has kinks where eigenvalues cross, which coordinate searches stall on)."""
    lo, hi = np.log(lo), np.log(hi)

    def f(x):
        return rate([float(v) for v in np.exp(np.clip(x, lo, hi))])
    x0 = min((np.clip(np.log(s), lo, hi) for s in starts), key=f)
    if np.all(hi - lo <= 0):
        return [float(v) for v in np.exp(x0)], f(x0)
    vertices = np.vstack([x0] + [x0 - 0.5 * np.eye(len(x0))[i] for i in range(len(x0))])
    xmin, fmin, _ = simplex.nelder_mead(f, vertices, xatol=1e-4, fatol=1e-9, maxfev=300 * len(x0))
    x = np.clip(xmin, lo, hi) if fmin <= f(x0) else x0
    return [float(v) for v in np.exp(x)], f(x)


def _fast_unsafe(rate, probes, finite, ref, count):
    """One common gamma, the fastest contraction at any value (usually above the bound)."""
    top = max([p.scale() for p in probes if math.isfinite(p.scale())] + finite)
    grid = np.geomspace(1e-3 * ref, 1e3 * top, 121)
    rates = [rate([g] * count) for g in grid]
    k = min(range(len(grid)), key=lambda j: (round(rates[j], 12), -grid[j]))
    common, best = _search(lambda g: rate(g * count), [grid[max(k - 1, 0)]],
                           [grid[min(k + 1, len(grid) - 1)]], [[grid[k]]])
    return common * count, best


_CHOICES = {}            # recent choose_gamma results by their inputs (a run's lockstep reference repeats the search)
CHOICES_KEPT = 8
CACHE_FILES_KEPT = 256   # choices kept on disk (the oldest go first)


def _choice_key(scene, probes, mode, secant, ceiling):
    """A hash of everything choose_gamma reads, and of the code that reads it."""
    h = hashlib.sha256(repr((mode, scene.E.shape, tuple(scene.sizes), str(scene.scenario.master.relaxation),
                             tuple(sorted((secant or {}).items())), tuple(sorted((ceiling or {}).items())),
                             [(p.name, p.gamma) for p in probes], np.__version__)).encode())
    for part in (scene.E, scene.F, *[m for p in probes for m in (p.dE, p.dF)]):
        h.update(np.ascontiguousarray(part, dtype=np.float64).tobytes())
    for source in (__file__, ic.__file__, simplex.__file__):
        h.update(Path(source).read_bytes())
    return h.hexdigest()[:32]


def _cached_choice(key):
    """A choice stored by an earlier process (the gamma folder of the build cache), or None."""
    try:
        d = json.loads((cache_dir() / "gamma" / f"{key}.json").read_text(encoding="utf-8"))
        return GammaChoice(d["gammas"], d["mode"], d["bounds"], d["rate"], d["guaranteed"])
    except (OSError, ValueError, KeyError):
        return None


def _store_choice(key, choice):
    folder = cache_dir() / "gamma"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        old = sorted(folder.glob("*.json"), key=lambda f: f.stat().st_mtime)
        for f in old[:max(0, len(old) - CACHE_FILES_KEPT + 1)]:
            f.unlink(missing_ok=True)
        tmp = folder / f".{key}.{os.getpid()}.tmp"
        tmp.write_text(json.dumps({"gammas": choice.gammas, "mode": choice.mode, "bounds": choice.bounds,
                                   "rate": choice.rate, "guaranteed": choice.guaranteed}))
        os.replace(tmp, folder / f"{key}.json")
    except OSError:
        pass                           # a read-only cache only costs the search next time


def choose_gamma(scene, probes, mode, where="gamma", secant=None, ceiling=None):
    """_choose_gamma, remembered for the same inputs (the scene's coupling, the probes, the mode): it
    is a pure function of them, so a run and its lockstep reference, probed alike at x^0, search once,
    and a later process with the same FMUs and scene reads the choice from the build cache (JSON keeps
    every float exactly) instead of searching."""
    key = _choice_key(scene, probes, mode, secant, ceiling)
    if key not in _CHOICES:
        choice = _cached_choice(key)
        if choice is None:
            choice = _choose_gamma(scene, probes, mode, where, secant, ceiling)
            _store_choice(key, choice)
        if len(_CHOICES) >= CHOICES_KEPT:
            _CHOICES.pop(next(iter(_CHOICES)))
        _CHOICES[key] = choice
    choice = _CHOICES[key]
    return GammaChoice(dict(choice.gammas), choice.mode, dict(choice.bounds), choice.rate, choice.guaranteed)


def _choose_gamma(scene, probes, mode, where, secant, ceiling):
    """Each subsystem's gamma for `mode` (see the module docstring). Condition 1 is per subsystem
    (gamma_i <= lambda_min(Z_d,i)) and P stays orthogonal for any positive channel impedances
    (paper Remark 1), so auto searches every gamma_i in (0, SAFETY * bound_i] for the fastest
    contraction, starting from the common gamma SAFETY * min_i bound_i. `secant` ({subsystem: Z})
    caps a bound by the impedance the last inner loop really met; `ceiling` ({subsystem: gamma})
    keeps every gamma at or below it (auto-retune only lowers)."""
    names = [p.name for p in probes]
    bounds = {p.name: min(p.fne_bound(), (secant or {}).get(p.name, math.inf)) for p in probes}
    culprit = min(bounds, key=bounds.get)
    if not bounds[culprit] > 0:
        raise ConfigError(f"{where}: {mode}: subsystem {culprit} has no positive incremental port impedance "
                          f"(lambda_min(Z_d) = {bounds[culprit]:.3g}), so no gamma satisfies Condition 1; give gamma "
                          f"a number")
    finite = [b for b in bounds.values() if math.isfinite(b)]
    if not finite:
        raise ConfigError(f"{where}: {mode}: no subsystem port moves under a wave perturbation, so there is no "
                          f"impedance to tune to; give gamma a number")
    ref = min(finite)
    cap = {k: (b if math.isfinite(b) else 1e3 * max(finite)) for k, b in bounds.items()}
    rate = (lambda g: dr_rate(scene, probes, g))
    if mode == "fast-unsafe":
        gammas, best = _fast_unsafe(rate, probes, finite, ref, len(names))
    elif mode == "fastest":
        rate = _fastest_rate(scene, probes)
        hi = [FASTEST_SAFETY * cap[k] for k in names]
        lo = [1e-3 * h for h in hi]
        common = min(FASTEST_SAFETY * ref, *hi)
        gammas, best = _search(rate, lo, hi, [[common] * len(names), hi, _coordinate_grid(rate, lo, hi, hi)])
    else:
        hi = [min(SAFETY * cap[k], (ceiling or {}).get(k, math.inf)) for k in names]
        lo = [1e-3 * h for h in hi]
        common = min(SAFETY * ref, *hi)
        gammas, best = _search(rate, lo, hi, [[common] * len(names), hi])
    chosen = dict(zip(names, gammas))
    return GammaChoice(gammas=chosen, mode=mode, bounds=bounds, rate=best,
                       guaranteed=all(chosen[k] <= bounds[k] for k in names))


def rescatter(scene, gammas):
    """The committed wave b^n at new impedances ({subsystem: gamma}), from the stage (e, f) of the last step.

    Each FMU computes b = sqrt(dt / (2 gamma)) (e - gamma f) from its stage e, f (fmus/layer,
    fmi2DoStep), so b at gamma' is the same formula with gamma'; this equals converting b with
    the old gamma to (e, f) through eq. (4) (with the incident a) and back through eq. (3)."""
    b = []
    for s in scene.subsystems:
        g = gammas[s.name]
        v = s.stage()
        b.extend(outgoing_wave(e, f, g, scene.scenario.dt) for e, f in zip(v[:s.m], v[s.m:]))
    return b


class GammaTuner:
    """Resolves `gamma: auto | auto-retune | fast-unsafe` for one run and keeps the log of gamma."""

    def __init__(self, scene, mode, warn=None):
        self.scene, self.mode = scene, mode
        self.where = f"{scene.scenario.source}: gamma"
        self.warn = warn or (lambda msg: None)
        self.choices = []          # (step, GammaChoice) whenever gamma was (re)chosen
        self.retune = mode == "auto-retune"
        self.secant = {}           # {subsystem: smallest secant impedance of the last inner loop}
        self.probed = {}           # {subsystem: PortProbe.checked of the probe gamma was chosen from}

    def observe(self, secant):
        """The secant impedances the last macro-step's inner loop met (fne_watch.trace_impedances):
        the tangent probe at u^0 alone can overestimate the bound when Z_d changes along the iterates."""
        self.secant = dict(secant)

    def initial(self, b0):
        """Probe at x^0 (twice: the second probe runs at the first choice, where it is best
        conditioned), set the FMUs' gammas and return the choice."""
        choice = None
        for _ in range(2):
            probes = probe_scene(self.scene, b0, 0, self.scene.scenario.start_time, check=True)
            choice = choose_gamma(self.scene, probes, self.mode, self.where)
            self.scene.set_gammas(choice.gammas)
        self.choices.append((0, choice))
        self.probed = {p.name: p.checked for p in probes}
        for name, (g, bound) in choice.violations.items():
            self.warn(f"gamma: fast-unsafe chose gamma = {g:.4g} for subsystem {name}, above its FNE bound "
                      f"{bound:.4g}: Condition 1 and Theorem 1 no longer hold; the augmented residual is reported "
                      f"(max_augmented_pos)")
        return choice

    def between_steps(self, master, n, t):
        """auto-retune: before macro-step n, re-probe at x^n; when a subsystem's gamma exceeds
        RETUNE_ABOVE times its FNE bound (the smaller of the tangent bound at u^0 and the secant
        impedances the last inner loop met), choose again below the current gammas, re-scatter
        b^n to the new ones and hand both to the master.

        Gammas only go down: the impedance of a nonlinear port can swing within one macro-step by
        more than any estimate from the last one shows (measured on the stiff Duffing at dt = 0.1:
        raising gamma to follow the bound up broke Condition 1 a few steps later)."""
        if not self.retune or n == 0:
            return None
        now = dict(self.scene.gammas)
        probes = probe_scene(self.scene, master.b, n, t, master.P)
        bounds = {p.name: min(p.fne_bound(), self.secant.get(p.name, math.inf)) for p in probes}
        if all(now[k] <= RETUNE_ABOVE * bounds[k] for k in now):
            return None
        try:
            choice = choose_gamma(self.scene, probes, self.mode, self.where, self.secant, ceiling=now)
        except ConfigError as exc:
            raise NumericalError(f"{exc} (at step {n}, t = {t:.6g})") from None
        if choice.gammas == now:
            return None
        b_new = rescatter(self.scene, choice.gammas)
        self.scene.set_gammas(choice.gammas)
        master.retune(b_new)                          # P, J_L for the new gammas, b^n re-scattered
        self.choices.append((n, choice))
        return choice

    def summary(self, gamma_min):
        """Summary fields; `gamma_min` is {subsystem: smallest gamma used} over the steps run."""
        first = self.choices[0][1]
        return {
            "gamma_mode": self.mode,
            "gamma_initial": first.gammas,
            "gamma_final": dict(self.scene.gammas),
            "gamma_min": gamma_min or first.gammas,
            "gamma_changes": len(self.choices) - 1,
            "gamma_fne_bounds": first.bounds,
            "gamma_probe": self.probed,
            "gamma_rate_estimate": first.rate,
            "gamma_guaranteed": all(c.guaranteed for _, c in self.choices),
        }
