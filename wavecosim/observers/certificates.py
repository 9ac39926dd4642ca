"""Sampled certificates before the sampled macro-steps (certificates.Sampling: n % every == 0):
Condition 1 margins of every frozen map S_i^n on random pairs, and a DR fixed point u* = P b*
(eq. 18) for the Theorem 1 residual after the step; NaN in their columns at the other steps."""
import math

import numpy as np

from ..certificates import augmented_residual, fne_margins
from ..linalg import matvec
from .passivity import grow_max_pos
from . import Observer


class CertificateSampler(Observer):
    """Columns fne_<subsystem> (when fne_pairs > 0) and augmented (when the master gives its DR iterates)."""
    blocks = paced = True

    def __init__(self, scene, master, settings, augmented, pace):
        self.scene, self.master, self.settings, self.pace = scene, master, settings, pace
        self.names = [s.name for s in scene.subsystems]
        self.augmented = augmented and settings.augmented
        self.columns = (*([f"fne_{n}" for n in self.names] if settings.fne_pairs else []),
                        *(["augmented"] if self.augmented else []))
        self.rng = np.random.default_rng(settings.fne_seed)
        self.fne, self.u_star = None, None
        self.min_fne = [math.inf] * len(self.names)
        self.max_aug = math.nan

    def before_step(self, n, t):
        """At x^n of a sampled step: u* by the interface Newton, then the sampled margins; the FMUs are
        left at x^n."""
        self.fne, self.u_star = None, None
        if not self.pace.sampled(n):
            return
        self.scene.freeze(n, t)
        master = self.master
        if self.augmented:
            self.u_star = matvec(master.P, master.fixed_point(n, t))
        if self.settings.fne_pairs:
            centre = self.scene.split(list(np.asarray(master.P) @ np.asarray(master.b)))
            self.fne = [fne_margins(s, c, self.settings.fne_pairs, self.rng, self.settings.fne_scale,
                                    self.scene.scenario.dt) for s, c in zip(self.scene.subsystems, centre)]
        self.scene.thaw()

    def after_step(self, n, t, log, reading, row):
        k = len(self.names) if self.settings.fne_pairs else 0
        row[:k] = math.nan
        if self.fne is not None:
            row[:k] = self.fne
            self.min_fne = [min(a, b) for a, b in zip(self.min_fne, self.fne)]
        if self.augmented:
            aug = augmented_residual(sum(reading.H) - self.H_prev, log.u0, log.uK, self.u_star, log.a_hat,
                                     reading.B) if log.u0 is not None and self.u_star is not None else math.nan
            row[k] = aug
            self.max_aug = grow_max_pos(self.max_aug, aug)
        self.H_prev = sum(reading.H)
        self.fne, self.u_star = None, None

    def next_before(self, n):
        return self.pace.next_sampled(n)

    def after_block(self, n0, logs, readings, rows):
        """Steps between sampled ones: NaN in every column."""
        rows[:] = math.nan
        self.H_prev = sum(readings.H[-1].tolist())

    def start(self, first):
        self.H_prev = sum(first.H)

    def summary(self):
        finite = {n: (v if math.isfinite(v) else math.nan) for n, v in zip(self.names, self.min_fne)}
        known = [v for v in finite.values() if v == v]
        return {"max_augmented_pos": self.max_aug, "min_fne_margin": min(known) if known else math.nan,
                "min_fne_margin_by_subsystem": finite}


class CertificatePace(Observer):
    """Reports in summary.json how the sampled certificates were paced (certificates_every)."""
    blocks = True

    def __init__(self, pace):
        self.pace = pace

    def after_block(self, n0, logs, readings, rows):
        """Nothing per step."""

    def summary(self):
        return self.pace.info()
