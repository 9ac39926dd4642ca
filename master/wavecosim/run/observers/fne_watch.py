"""Condition 1 watch: a cheap online estimate of each frozen port map's FNE margin (paper eq. 22).

Per macro-step and subsystem, the scale-free margin (<dS, da> - |dS|^2) / |da|^2 (>= 0 when S_i^n
is FNE; rho - rho^2 for b = rho a) comes from:
- the DR iterates themselves, for free: consecutive queries (u^k, S(u^k)) of the inner loop are
  pairs of incident and outgoing waves of the same frozen map (secant margins; O(log K) pairs
  per step, see pair_indices); a step whose iterates roundoff cannot tell apart (it started at
  its fixed point) gets no estimate (NaN);
- otherwise (K < 2, or a master that does not expose its queries) one finite-difference probe of
  the frozen map (m + 1 queries, gamma_tuning.probe_port), giving the tangent margin
  lambda_min(sym J_S - J_S^T J_S), at the sampled steps only (certificates.Sampling).
The first failure (margin < -TOL) is reported once, naming the step, the time and the subsystem.
"""
import math

import numpy as np

from ...kernel import blocks, cvalues
from ...core import gamma as gt
from ...kernel.linalg import matvec
from ...core.readings import row_dots
from . import Observer

TOL = 1e-6      # margins above -TOL count as FNE (roundoff of the FMUs' inner solves)
FLOOR = 1e-5    # a pair is used only when |da| > FLOOR (|a| + |b|): below, roundoff dominates
NOISE_FLOOR = 1e3   # ... and |da| > NOISE_FLOOR noise (|a| + |b|) for a map smooth only to `noise` (pair_floor)


def pair_indices(n):
    """k of the pairs (k - 1, k) read from n queries: 1, 2, 3, 4, 6, 9, 13, 19, 28, ... and the last,
    so both the large first moves and the slope near the fixed point are seen at O(log n) cost."""
    ks, k = [], 1
    while k < n:
        ks.append(k)
        k = max(k + 1, (3 * k) // 2)
    if n >= 2 and ks[-1] != n - 1:
        ks.append(n - 1)
    return ks


def pair_floor(sub):
    """Smallest |da| / (|a| + |b|) of a usable pair: FLOOR, or for a wave adapter over an FMU smooth only
    to its solver's tolerance NOISE_FLOOR times the worst relative residual it kept (a margin read from
    a pair is off by about that noise over |da|: the dcmotor machine's 8e-6 made a pair at 1.4e-4 read
    -0.027 for a true +0.025). Exact maps keep no residual: FLOOR."""
    return max(FLOOR, NOISE_FLOOR * sub.map.worst_accepted) if sub.adapter else FLOOR


def _pairs(scene, trace):
    """(subsystem, da, dS) per subsystem: rows are pairs of inner-loop queries (u, S(u)) at
    pair_indices(), keeping those that roundoff does not swamp."""
    ks = pair_indices(len(trace))
    if not ks:
        return
    if hasattr(trace, "as_array"):                                  # the fast path's trace
        arr, idx = trace.as_array(), np.asarray(ks)
        before, after = arr[idx - 1], arr[idx]                      # (pairs, 2, channels)
    else:
        rows = {j: trace[j] for k in ks for j in (k - 1, k)}
        before = np.asarray([rows[k - 1] for k in ks], float)
        after = np.asarray([rows[k] for k in ks], float)
    U, B = before[:, 0, :], before[:, 1, :]
    dU, dB = after[:, 0, :] - U, after[:, 1, :] - B
    for s, off in zip(scene.subsystems, scene.offsets):
        cols = slice(off, off + s.m)
        da, ds = dU[:, cols], dB[:, cols]
        size = np.abs(U[:, cols]).max(axis=1) + np.abs(B[:, cols]).max(axis=1)
        norm = np.sqrt(row_dots(da, da))
        keep = (norm > 0.0) & (norm > pair_floor(s) * size)
        if keep.any():
            yield s, da[keep], ds[keep]


def trace_impedances(scene, trace, gammas):
    """{subsystem: smallest secant port impedance} seen by the inner loop at `gammas` ({subsystem: gamma}).

    Along a pair, <de, df> / |df|^2 = gamma (|da|^2 - |dS|^2) / |da - dS|^2 (eq. 4): a Rayleigh
    quotient of Z_d over the range the iterates really visited, so Condition 1 needs gamma below it."""
    out = {}
    for s, da, ds in _pairs(scene, trace):
        dd = da - ds
        den = row_dots(dd, dd)
        ok = den > 0.0
        if ok.any():
            z = gammas[s.name] * (row_dots(da, da) - row_dots(ds, ds))[ok] / den[ok]
            out[s.name] = float(z.min())
    return out


def trace_margins(scene, trace):
    """{subsystem: smallest secant margin} over consecutive inner-loop queries (u, S(u)); sums in a
    fixed order, as kernel/c/certs.c makes them in blocks."""
    out = {}
    for s, da, ds in _pairs(scene, trace):
        m = (row_dots(ds, da) - row_dots(ds, ds)) / row_dots(da, da)
        out[s.name] = float(m.min())
    return out


class FneWatch(Observer):
    """Online Condition 1 monitor of one run; `warn` gets one line, the first time it fails.
    Column fne_watch: the smallest margin estimated at each step (NaN when none could be)."""
    columns = ("fne_watch",)
    when = "iterating masters, with `fne_watch: true` and the certificates on"
    described = {"fne_watch": ("the Condition 1 watch: the smallest FNE margin estimated in the step, from the "
                               "inner iterates (or a probe at the sampled steps when K < 2), divided by |Δa|² "
                               "(≥ 0 when every frozen map is firmly nonexpansive); NaN when none could be",
                               "1")}

    def __init__(self, scene, master, pace, warn=None, tol=TOL):
        self.scene, self.master, self.pace, self.tol = scene, master, pace, tol
        self.warn = warn or (lambda msg: None)
        self.names = [s.name for s in scene.subsystems]
        self.min_margin = {n: math.inf for n in self.names}
        self.first = None
        self.failed_steps = 0
        self.probed_steps = 0
        self.probed, self.call = None, None
        self.needs_trace = master.K >= 2                   # the secant margins, every step
        self.blocks = self.paced = not self.needs_trace    # the probe, at the sampled steps
        self.kernel = master.kernel_certificates(FLOOR)
        if self.kernel is not None and not self.needs_trace and not self.kernel.probe(pace, gt.PROBE_REL):
            self.kernel = None                             # a port of many channels: the probe in Python
        if self.kernel is not None:                        # the margins in the blocks (certs_path)
            if self.needs_trace:
                self.kernel.watch()
            self.blocks = self.paced = True

    def next_before(self, n):
        """K < 2: its sampled steps (the probe, unless the kernel makes it); K >= 2 acts before no step."""
        return math.inf if self.needs_trace or self.kernel is not None else self.pace.next_sampled(n)

    def prepare_block(self, logs, readings):
        """The certificates' kernel and its C pass's fixed arguments made in set-up (not on the first block)."""
        if self.kernel is not None:
            self.kernel.create()
            self.call = blocks.WatchBlock(k=len(self.names), tol=self.tol,
                                          min_margin=cvalues.doubles(len(self.names)))

    def after_block(self, n0, logs, readings, rows, at=None):
        """The kernel's secant margins of each step, in one C pass (record() of every step at once),
        unless one fails, is NaN or a signed zero: then step by step; K < 2, steps between sampled ones:
        no estimate (NaN)."""
        if self.kernel is None:
            rows[:] = math.nan
            return
        if self.call is None:
            self.prepare_block(logs, readings)
        found, call = self.kernel.block_rows(n0, len(rows)), self.call
        call.count, call.probed = len(rows), 0
        call.first, call.every = (0, 1) if self.needs_trace else ((-n0) % self.pace.every, self.pace.every)
        call.certs, call.ldc, call.out = found.ctypes.data, found.strides[0] // 8, (at or blocks.columns(rows))[0]
        for i, name in enumerate(self.names):
            call.min_margin[i] = self.min_margin[name]
        if blocks.library().watch_block(cvalues.ref(call)):
            self._step_by_step(n0, rows, found, range(call.first, len(rows), call.every))
            return
        self.min_margin = dict(zip(self.names, call.min_margin[:len(self.names)]))
        if not self.needs_trace:
            self.probed_steps += call.probed

    def _step_by_step(self, n0, rows, found, steps):
        """record() of the block's estimated steps one after the other (a failure warns at the first)."""
        dt = self.scene.scenario.dt
        rows[:] = math.nan
        for s in steps:
            rows[s, 0] = self.record(n0 + s, (n0 + s) * dt, self._kernel_margins(n0 + s, found[s]))

    def _kernel_margins(self, n, found):
        """{subsystem: margin} of step n from its row of the kernel's certificates (the probe's: counted)."""
        k = len(self.names)
        kept = found[2 * k + 1:].tolist()
        if not self.needs_trace and any(kept):
            self.probed_steps += 1
        return {name: v for name, v, h in zip(self.names, found[k + 1:2 * k + 1].tolist(), kept) if h}

    def before_step(self, n, t):
        """With fewer than two inner iterations there are no iterate pairs: probe the frozen maps
        (at a sampled step; NaN at the others)."""
        self.probed = None
        if self.master.K < 2 and self.pace.sampled(n):
            self.probed_steps += 1
            g = self.scene.gammas
            u0 = matvec(self.master.P, self.master.b)            # summed in a fixed order, as certs.c
            self.probed = {p.name: p.fne_margin(g[p.name])
                           for p in gt.probe_scene(self.scene, self.master.b, n, t, self.master.P, u0=u0)}

    def after_step(self, n, t, log, reading, row):
        made = self.kernel.row_of(n) if self.kernel is not None and self.probed is None else None
        if made is not None and not self.needs_trace:        # a block's step finished step by step
            margins = self._kernel_margins(n, made)
        elif self.probed is not None:
            margins = self.probed
        else:
            margins = trace_margins(self.scene, self.master.trace or []) if self.needs_trace else None
        row[0] = self.record(n, t, margins)
        self.probed = None

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
                g = self.scene.gammas[name]
                self.first = {"step": n, "t": t, "subsystem": name, "margin": worst, "gamma": g}
                self.warn(f"Condition 1 (FNE) fails at step {n} (t = {t:.6g}) in subsystem {name}: margin "
                          f"{worst:.3g} < 0 at gamma = {g:.4g}; Theorem 1 and DR convergence are not "
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
