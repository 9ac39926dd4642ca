"""Automatic choice of the scattering impedance gamma (paper Remark 2, gamma-tuning).

With a reciprocal incremental port response de = Z_d df, the frozen port map has the Jacobian
J_S = (Z_d - gamma I)(Z_d + gamma I)^-1, and Condition 1 (FNE) holds locally iff gamma <= lambda_min(Z_d)
(eq. 33). Inside that bound we pick the gamma whose linearized Douglas-Rachford operator
T = 1/2 (I + R_L R_S), R = 2 J - I (paper Section IV-B), has the smallest spectral radius.

Z_d is measured, not assumed: each frozen subsystem is queried at the operating point and at
m perturbed incident waves, and the stage outputs e, f give dE = Z_d dF directly, which does not
depend on gamma (the closure e + gamma f = sqrt(2 gamma / dt) a only selects the point). So one
probe predicts J_S at every gamma: J_S(gamma) = (dE - gamma dF)(dE + gamma dF)^-1.

Modes (YAML `gamma:` or `--gamma`):
- a number: fixed;
- `auto`: chosen once at t = 0, at most SAFETY times the smallest FNE bound, so Theorem 1 keeps holding;
- `auto-retune`: the same, and lowered between macro-steps whenever the bound drops below it
  (the committed wave b is re-scattered to the new gamma); it never goes up again;
- `fast-unsafe`: the gamma with the fastest contraction at any value, usually above the FNE bound
  (near the geometric mean of the port impedances). It leaves Condition 1 and Theorem 1; the
  run warns and reports the augmented residual.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import ConfigError, NumericalError

MODES = ("auto", "auto-retune", "fast-unsafe")
PROVISIONAL = 0.4       # gamma the FMUs are instantiated with before the first probe
SAFETY = 0.9            # auto stays this far inside the FNE bound (Z_d drifts along the trajectory)
RETUNE_ABOVE = 0.95     # auto-retune lowers gamma when it exceeds this fraction of the bound
PROBE_REL = 1e-6        # size of the incident-wave perturbation, relative to the operating point


@dataclass
class PortProbe:
    """Incremental port response of one frozen subsystem around an operating point.

    Column j of dE, dF is the change of the stage effort and flow when incident channel j moves
    by `h`; so dE = Z_d dF, whatever gamma the FMU was probed with."""
    name: str
    dE: np.ndarray
    dF: np.ndarray
    gamma: float

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


def probe_port(sub, centre, rel=PROBE_REL) -> PortProbe:
    """Probe one frozen subsystem at incident wave `centre` (m + 1 queries); its state is unchanged."""
    names = list(sub.port.effort) + list(sub.port.flow)
    m = sub.m
    centre = np.asarray(centre, float)
    b0 = np.asarray(sub.query(list(centre)))
    ef0 = np.asarray(sub.read(names))
    h = rel * (float(np.abs(centre).max()) + float(np.abs(b0).max())) or rel * math.sqrt(sub.dt)
    dE, dF = np.zeros((m, m)), np.zeros((m, m))
    for j in range(m):
        a = centre.copy()
        a[j] += h
        sub.query(list(a))
        d = (np.asarray(sub.read(names)) - ef0) / h
        dE[:, j], dF[:, j] = d[:m], d[m:]
    sub.thaw()
    return PortProbe(sub.name, dE, dF, float(sub.fmu.get_real(sub.fmu.vrs(["gamma"]))[0])
                     if "gamma" in sub.fmu.variables else float("nan"))


def probe_scene(scene, b, n, t, P=None):
    """Freeze every subsystem at x^n, probe it around u^0 = P b^n, and put it back at x^n."""
    P = scene.wave_map().P if P is None else P
    centre = scene.split(list(np.asarray(P, float) @ np.asarray(b, float)))
    probes = []
    for s, c in zip(scene.subsystems, centre):
        s.freeze(n, t)
        probes.append(probe_port(s, c))
    return probes


def dr_rate(scene, probes, gamma):
    """Spectral radius of the linearized DR operator T = 1/2 (I + R_L R_S) at `gamma`."""
    n = scene.n_channels
    J_S = np.zeros((n, n))
    for p, off, s in zip(probes, scene.offsets, scene.subsystems):
        J_S[off:off + s.m, off:off + s.m] = p.jacobian(gamma)
    J_L = scene.wave_map(gamma).J_L
    T = 0.5 * (np.eye(n) + (2.0 * J_L - np.eye(n)) @ (2.0 * J_S - np.eye(n)))
    return float(np.abs(np.linalg.eigvals(T)).max())


@dataclass
class GammaChoice:
    """One decision: the gamma, the FNE bound it respects (or not), and the predicted DR rate."""
    gamma: float
    mode: str
    bound: float
    bound_subsystem: str
    rate: float
    guaranteed: bool
    bounds: dict = field(default_factory=dict)


def choose_gamma(scene, probes, mode, where="gamma", secant=None):
    """The gamma of `mode` for these probes (see the module docstring); `secant` ({subsystem: Z})
    caps each subsystem's bound by the impedance the last inner loop really met."""
    bounds = {p.name: min(p.fne_bound(), (secant or {}).get(p.name, math.inf)) for p in probes}
    culprit = min(bounds, key=bounds.get)
    bound = bounds[culprit]
    if not bound > 0:
        raise ConfigError(f"{where}: {mode}: subsystem {culprit} has no positive incremental port impedance "
                          f"(lambda_min(Z_d) = {bound:.3g}), so no gamma satisfies Condition 1; give gamma a number")
    if math.isinf(bound):
        raise ConfigError(f"{where}: {mode}: no subsystem port moves under a wave perturbation, so there is no "
                          f"impedance to tune to; give gamma a number")
    if mode == "fast-unsafe":
        scales = [p.scale() for p in probes]
        hi = max(s for s in scales if math.isfinite(s)) if any(math.isfinite(s) for s in scales) else bound
        grid = np.geomspace(bound * 1e-3, max(hi, bound) * 1e3, 121)
    else:
        grid = np.geomspace(SAFETY * bound * 1e-3, SAFETY * bound, 31)
    rates = [dr_rate(scene, probes, g) for g in grid]
    best = min(range(len(grid)), key=lambda k: (round(rates[k], 12), -grid[k]))
    g = float(grid[best])
    return GammaChoice(gamma=g, mode=mode, bound=bound, bound_subsystem=culprit, rate=rates[best],
                       guaranteed=g <= bound, bounds=bounds)


def set_fmu_gamma(scene, gamma):
    """Set the tunable parameter gamma of every FMU (only between macro-steps) and the scene's gamma."""
    for s in scene.subsystems:
        if "gamma" not in s.fmu.variables:
            raise ConfigError(f"{scene.scenario.source}: subsystems.{s.name}.fmu: {s.fmu.path.name} has no tunable "
                              f"parameter gamma, so gamma cannot be tuned")
        s.fmu.set_real(s.fmu.vrs(["gamma"]), [gamma])
    scene.gamma = float(gamma)


def rescatter(scene, gamma_new):
    """The committed wave b^n at a new gamma, from the stage port values (e, f) of the last step.

    Each FMU computes b = sqrt(dt / (2 gamma)) (e - gamma f) from its stage e, f (fmus/layer,
    fmi2DoStep), so b at gamma' is the same formula with gamma'; this equals converting b with
    the old gamma to (e, f) through eq. (6) (with the incident a) and back through eq. (5)."""
    k = math.sqrt(scene.scenario.dt / (2.0 * gamma_new))
    b = []
    for s in scene.subsystems:
        v = s.read(list(s.port.effort) + list(s.port.flow))
        b.extend(k * (e - gamma_new * f) for e, f in zip(v[:s.m], v[s.m:]))
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

    def observe(self, secant):
        """The secant impedances the last macro-step's inner loop met (fne_watch.trace_impedances):
        the tangent probe at u^0 alone can overestimate the bound when Z_d changes along the iterates."""
        self.secant = dict(secant)

    def initial(self, b0):
        """Probe at x^0 (twice: the second probe runs at the first choice, where it is best
        conditioned), set the FMUs' gamma and return the choice."""
        choice = None
        for _ in range(2):
            probes = probe_scene(self.scene, b0, 0, 0.0)
            choice = choose_gamma(self.scene, probes, self.mode, self.where)
            set_fmu_gamma(self.scene, choice.gamma)
        self.choices.append((0, choice))
        if not choice.guaranteed:
            self.warn(f"gamma: fast-unsafe chose gamma = {choice.gamma:.4g}, above the FNE bound "
                      f"{choice.bound:.4g} of subsystem {choice.bound_subsystem}: Condition 1 and Theorem 1 no "
                      f"longer hold; the augmented residual is reported (max_augmented_pos)")
        return choice

    def between_steps(self, master, n, t):
        """auto-retune: before macro-step n, re-probe at x^n and lower gamma (re-scattering b^n) when it
        exceeds RETUNE_ABOVE times the FNE bound, the smaller of the tangent bound at u^0 and the
        secant impedances the last inner loop met.

        gamma only goes down: the impedance of a nonlinear port can swing within one macro-step by
        more than any estimate from the last one shows (measured on the stiff Duffing at dt = 0.1:
        raising gamma to follow the bound up broke Condition 1 a few steps later)."""
        if not self.retune or n == 0:
            return None
        g = self.scene.gamma
        probes = probe_scene(self.scene, master.b, n, t, master.P)
        bound = min(min(p.fne_bound(), self.secant.get(p.name, math.inf)) for p in probes)
        if g <= RETUNE_ABOVE * bound:
            return None
        try:
            choice = choose_gamma(self.scene, probes, self.mode, self.where, self.secant)
        except ConfigError as exc:
            raise NumericalError(f"{exc} (at step {n}, t = {t:.6g})") from None
        if choice.gamma >= g:
            return None
        b_new = rescatter(self.scene, choice.gamma)
        set_fmu_gamma(self.scene, choice.gamma)
        master.set_gamma(choice.gamma, b_new)
        self.choices.append((n, choice))
        return choice

    def summary(self, gammas):
        first = self.choices[0][1]
        g = np.asarray(gammas, float)
        return {
            "gamma_mode": self.mode,
            "gamma_initial": first.gamma,
            "gamma_final": float(self.scene.gamma),
            "gamma_min": float(g.min()) if g.size else first.gamma,
            "gamma_max": float(g.max()) if g.size else first.gamma,
            "gamma_changes": len(self.choices) - 1,
            "gamma_fne_bound": first.bound,
            "gamma_fne_bounds": first.bounds,
            "gamma_rate_estimate": first.rate,
            "gamma_guaranteed": all(c.guaranteed for _, c in self.choices),
        }
