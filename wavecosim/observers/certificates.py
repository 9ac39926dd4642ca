"""Sampled certificates before the sampled macro-steps (certificates.Sampling: n % every == 0):
Condition 1 margins of every frozen map S_i^n on random pairs, and a DR fixed point u* = P b*
(eq. 18) for the Theorem 1 residual after the step; NaN in their columns at the other steps."""
import math

import numpy as np

from ..certificates import augmented_residual, fne_margins
from ..linalg import matvec
from ..readings import row_sums
from .fne_watch import FLOOR
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
        self.kernel = master.kernel_certificates(FLOOR)           # in the blocks of steps, when it can
        if self.kernel is not None:
            self.kernel.sample(pace, settings.fne_pairs, settings.fne_scale, self.rng, self.augmented)

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
            centre = self.scene.split(matvec(master.P, master.b))
            self.fne = [fne_margins(s, c, self.settings.fne_pairs, self.rng, self.settings.fne_scale,
                                    self.scene.scenario.dt) for s, c in zip(self.scene.subsystems, centre)]
        self.scene.thaw()

    def after_step(self, n, t, log, reading, row):
        """The step's certificates: from before_step, or from the kernel for a step its block made
        (one the monolithic guard judges after the block)."""
        k = len(self.names) if self.settings.fne_pairs else 0
        made = self.kernel.row_of(n) if self.kernel is not None else None
        if made is not None and self.pace.sampled(n) and k:
            self.fne = made[:k].tolist()
        row[:k] = math.nan
        if self.fne is not None:
            row[:k] = self.fne
            self.min_fne = [min(a, b) for a, b in zip(self.min_fne, self.fne)]
        if self.augmented:
            if made is not None:                          # a redo (the guard's) has no Fejer term
                fejer = float(made[len(self.names)]) if log.reason != "energy-guard" else math.nan
                aug = augmented_residual(sum(reading.H) - self.H_prev, None, None, None, log.a_hat, reading.B, fejer)
            else:
                aug = augmented_residual(sum(reading.H) - self.H_prev, log.u0, log.uK, self.u_star, log.a_hat,
                                         reading.B) if log.u0 is not None and self.u_star is not None else math.nan
            row[k] = aug
            self.max_aug = grow_max_pos(self.max_aug, aug)
        self.H_prev = sum(reading.H)
        self.fne, self.u_star = None, None

    def next_before(self, n):
        """Its sampled steps, unless the kernel computes the certificates inside the blocks."""
        return math.inf if self.kernel is not None else self.pace.next_sampled(n)

    def prepare_block(self, logs, readings):
        """The certificates' kernel made in set-up (not on the first block)."""
        if self.kernel is not None:
            self.kernel.create()

    def after_block(self, n0, logs, readings, rows):
        """The kernel's certificates of the block's steps (without it, no step is sampled: NaN)."""
        H = row_sums(readings.H)
        rows[:] = math.nan
        if self.kernel is not None:
            self._kernel_rows(n0, logs, readings, rows, H)
        self.H_prev = float(H[-1])

    def _kernel_rows(self, n0, logs, readings, rows, H):
        found, k = self.kernel.block_rows(n0, len(rows)), len(self.names) if self.settings.fne_pairs else 0
        sampled = self.pace.rows_of(n0, len(rows))
        rows[:, :k] = found[:, :k]
        for fne in found[sampled, :k].tolist() if k else ():
            self.min_fne = [min(a, b) for a, b in zip(self.min_fne, fne)]
        if self.augmented:                                 # at the sampled steps (the others have no u*)
            a_hat, B = logs.a_hat[sampled], readings.B[sampled]
            supplied = 0.5 * (row_sums(a_hat * a_hat) - row_sums(B * B))
            aug = (H - np.concatenate(([self.H_prev], H[:-1])))[sampled] + found[sampled, len(self.names)] - supplied
            aug[logs.ledger["rounds"][sampled] > 0] = math.nan      # a redo's log has no iterates
            rows[sampled, k] = aug
            for x in aug.tolist():
                self.max_aug = grow_max_pos(self.max_aug, x)

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
