"""Sampled certificates before the sampled macro-steps (certificates.Sampling: n % every == 0):
Condition 1 margins of every frozen map S_i^n on random pairs, and a DR fixed point u* = P b*
(eq. 18) for the Theorem 1 residual after the step; NaN in their columns at the other steps."""
import math

import numpy as np

from ...kernel import blocks, cvalues
from ...core.certificates import augmented_residual, fne_margins
from ...kernel.drkernel import LEDGER_LOG
from ...kernel.linalg import matvec, total
from ...core.readings import row_sums
from .fne_watch import FLOOR
from .passivity import grow_max_pos
from . import Observer


class CertificateSampler(Observer):
    """Columns fne_<subsystem> (when fne_pairs > 0) and augmented (when the master gives its DR iterates)."""
    blocks = paced = True
    when = "wave masters with the certificates on (`augmented`: iterating masters, every FMU giving H)"
    described = {
        "fne_<subsystem>": ("Condition 1: the smallest FNE margin of the subsystem's frozen map over "
                            "`certificates.fne_pairs` random pairs, divided by |Δa|² (≥ 0: firmly nonexpansive); "
                            "NaN at the steps not sampled (`certificates.every`)", "1"),
        "augmented": ("Theorem 1's augmented residual ΔH + ½‖uᴷ − u*‖² − ½‖u⁰ − u*‖² − ½(‖â‖² − ‖bⁿ⁺¹‖²) (≤ 0 "
                      "when the theorem holds); NaN at the steps not sampled", "J"),
    }

    def __init__(self, scene, master, settings, augmented, pace):
        self.scene, self.master, self.settings, self.pace = scene, master, settings, pace
        self.names = [s.name for s in scene.subsystems]
        self.augmented = augmented and settings.augmented
        self.columns = (*([f"fne_{n}" for n in self.names] if settings.fne_pairs else []),
                        *(["augmented"] if self.augmented else []))
        self.rng = np.random.default_rng(settings.fne_seed)
        self.fne, self.u_star, self.call = None, None, None
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
                aug = augmented_residual(total(reading.H) - self.H_prev, None, None, None, log.a_hat, reading.B, fejer)
            else:
                aug = augmented_residual(total(reading.H) - self.H_prev, log.u0, log.uK, self.u_star, log.a_hat,
                                         reading.B) if log.u0 is not None and self.u_star is not None else math.nan
            row[k] = aug
            self.max_aug = grow_max_pos(self.max_aug, aug)
        self.H_prev = total(reading.H)
        self.fne, self.u_star = None, None

    def next_before(self, n):
        """Its sampled steps, unless the kernel computes the certificates inside the blocks."""
        return math.inf if self.kernel is not None else self.pace.next_sampled(n)

    def prepare_block(self, logs, readings):
        """The certificates' kernel and its C pass's fixed arguments made in set-up (not on the first block)."""
        if self.kernel is not None:
            self.kernel.create()
            self.call = self._block_call(logs, readings)

    def _block_call(self, logs, readings):
        """sampled_block's fixed arguments (kernel/c/blocks.c): the kernel log's rows it reads (a_hat,
        B, H_i, the ledger's rounds) and the running figures (min_fne, max_aug, H_prev)."""
        at, k, ints = logs.observed_at, len(self.names), blocks.ints
        b = [at + r for r in readings.rows("B")]
        fig = cvalues.doubles(k + 2)
        place = (lambda i: cvalues.element(fig, i))
        call = blocks.SampledBlock(k=k, n=len(logs.a_rows), nb=len(b), every=self.pace.every,
                                   fne=int(bool(self.settings.fne_pairs)), augmented=int(self.augmented),
                                   rounds=logs.ledger_at + LEDGER_LOG.index("rounds"), a=ints(logs.a_rows),
                                   b=ints(b), h=ints([at + r for r in readings.rows("H")]),
                                   min_fne=place(0), max_aug=place(k), H_prev=place(k + 1))
        return call, cvalues.ref(call), fig

    def after_block(self, n0, logs, readings, rows, at=None):
        """The kernel's certificates of the block's steps, in one C pass (a redo's log has no iterates:
        NaN); without the kernel no step is sampled: NaN."""
        if self.kernel is None:
            rows[:] = math.nan
            self.H_prev = float(row_sums(readings.H)[-1])
            return
        if self.call is None:
            self.call = self._block_call(logs, readings)
        call, ref, fig = self.call
        k = len(self.names)
        fig[:k], fig[k], fig[k + 1] = self.min_fne, self.max_aug, self.H_prev
        found = self.kernel.block_rows(n0, len(rows))
        call.count, call.first = len(rows), (-n0) % self.pace.every
        (call.log, call.ld), (call.out, call.ldo) = (logs.address, logs.ld), at or blocks.columns(rows)
        call.certs, call.ldc = found.ctypes.data, found.strides[0] // 8
        blocks.library().sampled_block(ref)
        self.min_fne, self.max_aug, self.H_prev = fig[:k], fig[k], fig[k + 1]

    def start(self, first):
        self.H_prev = total(first.H)

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

    def after_block(self, n0, logs, readings, rows, at=None):
        """Nothing per step."""

    def summary(self):
        return self.pace.info()
