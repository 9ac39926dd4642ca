"""Condition 1 watch: a cheap online estimate of each frozen port map's FNE margin (paper eq. 24).

Per macro-step and subsystem, the scale-free margin (<dS, da> - |dS|^2) / |da|^2 (>= 0 when S_i^n
is FNE; rho - rho^2 for b = rho a) comes from:
- the DR iterates themselves, for free: consecutive queries (u^k, S(u^k)) of the inner loop are
  pairs of incident and outgoing waves of the same frozen map (secant margins);
- otherwise (K < 2, a master that does not expose its queries, or iterates too close to tell
  apart) one finite-difference probe of the frozen map (m + 1 queries, gamma_tuning.probe_port),
  giving the tangent margin lambda_min(sym J_S - J_S^T J_S).
The first failure (margin < -TOL) is reported once, naming the step, the time and the subsystem.
"""
import math

import numpy as np

from . import gamma_tuning as gt

TOL = 1e-6      # margins above -TOL count as FNE (roundoff of the FMUs' inner solves)
FLOOR = 1e-5    # a pair is used only when |da| > FLOOR (|a| + |b|): below, roundoff dominates


def _pairs(scene, trace):
    """(subsystem, da, dS) of consecutive inner-loop queries (u, S(u)) that roundoff does not swamp."""
    for k in range(1, len(trace)):
        (u0, b0), (u1, b1) = trace[k - 1], trace[k]
        for s, a0, a1, s0, s1 in zip(scene.subsystems, scene.split(u0), scene.split(u1), scene.split(b0),
                                     scene.split(b1)):
            a0, a1, s0, s1 = (np.asarray(x, float) for x in (a0, a1, s0, s1))
            da = a1 - a0
            size = float(np.abs(a0).max() + np.abs(s0).max()) if a0.size else 0.0
            norm = float(np.sqrt(da @ da))
            if norm > 0.0 and norm > FLOOR * size:
                yield s, da, s1 - s0


def trace_impedances(scene, trace, gamma):
    """{subsystem: smallest secant port impedance} seen by the inner loop at `gamma`.

    Along a pair, <de, df> / |df|^2 = gamma (|da|^2 - |dS|^2) / |da - dS|^2 (eq. 6): a Rayleigh
    quotient of Z_d over the range the iterates really visited, so Condition 1 needs gamma below it."""
    out = {}
    for s, da, ds in _pairs(scene, trace):
        dd = da - ds
        den = float(dd @ dd)
        if den > 0.0:
            z = gamma * (float(da @ da) - float(ds @ ds)) / den
            out[s.name] = min(out.get(s.name, math.inf), z)
    return out


def trace_margins(scene, trace):
    """{subsystem: smallest secant margin} over consecutive inner-loop queries (u, S(u))."""
    out = {}
    for s, da, ds in _pairs(scene, trace):
        margin = (float(ds @ da) - float(ds @ ds)) / float(da @ da)
        out[s.name] = min(out.get(s.name, math.inf), margin)
    return out


class FneWatch:
    """Online Condition 1 monitor of one run; `warn` gets one line, the first time it fails."""

    def __init__(self, scene, warn=None, tol=TOL):
        self.scene, self.tol = scene, tol
        self.warn = warn or (lambda msg: None)
        self.names = [s.name for s in scene.subsystems]
        self.min_margin = {n: math.inf for n in self.names}
        self.first = None
        self.failed_steps = 0
        self.probed_steps = 0

    def probe(self, b, n, t, P=None):
        """Margins from one finite-difference probe of every frozen map at x^n (state unchanged)."""
        self.probed_steps += 1
        g = self.scene.gamma
        return {p.name: p.fne_margin(g) for p in gt.probe_scene(self.scene, b, n, t, P)}

    def record(self, n, t, margins):
        """Book this step's margins; returns the smallest (NaN when nothing could be estimated)."""
        if not margins:
            return float("nan")
        for name, m in margins.items():
            self.min_margin[name] = min(self.min_margin[name], m)
        name = min(margins, key=margins.get)
        worst = margins[name]
        if worst < -self.tol:
            self.failed_steps += 1
            if self.first is None:
                self.first = {"step": n, "t": t, "subsystem": name, "margin": worst, "gamma": self.scene.gamma}
                self.warn(f"Condition 1 (FNE) fails at step {n} (t = {t:.6g}) in subsystem {name}: margin "
                          f"{worst:.3g} < 0 at gamma = {self.scene.gamma:.4g}; Theorem 1 and DR convergence are not "
                          f"guaranteed (lower gamma; gamma: auto-retune follows the bound down)")
        return worst

    def summary(self):
        return {
            "fne_watch_ok": self.first is None,
            "fne_watch_first_failure": self.first,
            "fne_watch_failed_steps": self.failed_steps,
            "fne_watch_min_margin": {k: (v if math.isfinite(v) else float("nan")) for k, v in self.min_margin.items()},
            "fne_watch_probed_steps": self.probed_steps,
        }
