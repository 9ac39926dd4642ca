"""Energy certificates of a macro-step (paper Section IV): the formulas.

- Condition 2: r_i = dH_i - 1/2 (|a_i|^2 - |b_i|^2) <= 0 (eq. 27), or dH_i - dt e_i.f_i in physical mode
  (computed each step by wavecosim/run/observers/passivity.py with wavecosim/core/waves.py).
- Theorem 1: dH + 1/2|u^K - u*|^2 - 1/2|u^0 - u*|^2 - 1/2(|a|^2 - |b|^2) <= 0 (eq. 32), u* = P b* (eq. 18).
- Condition 1: FNE margin <S(x)-S(y), x-y> - |S(x)-S(y)|^2 (eq. 22), reported divided by |x-y|^2
  so it is scale-free (a linear map b = rho a gives rho - rho^2).
Sampled certificates are paced (`sampling`): they never cost more FMU evaluations than the master.
"""
import math
from dataclasses import dataclass

import numpy as np

from ..kernel.linalg import distance, norm2
from .readings import row_dots
from .waves import port_energy


@dataclass(frozen=True)
class Sampling:
    """The steps n % every == 0 at which the sampled certificates (FNE pairs, u* and the augmented
    residual, the watch's probe) are computed, and how `every` was chosen."""
    every: int
    chosen: str

    def sampled(self, n):
        return n % self.every == 0

    def next_sampled(self, n):
        """The first sampled step >= n."""
        return n + (-n) % self.every

    def rows_of(self, n0, count):
        """Indices (from 0) of the sampled steps among n0 .. n0 + count - 1."""
        return np.arange((-n0) % self.every, count, self.every)

    def info(self):
        return {"certificates_every": self.every, "certificates_every_chosen": self.chosen}


def sampling(config, evaluations):
    """The one place that paces the certificates: certificates.every, or with `auto` the smallest
    every at which a sampled step's C = 2 fne_pairs + 4 FMU evaluations per subsystem (the pairs and
    u*'s Newton) do not exceed the master's `evaluations` per subsystem of `every` steps (DR: K + 1);
    every step when the master's evaluations per step are not fixed."""
    if config.every != "auto":
        return Sampling(config.every, "certificates.every")
    if evaluations is None:
        return Sampling(1, "auto: every step (the master's FMU evaluations per step are not fixed)")
    cost = 2 * config.fne_pairs + 4
    return Sampling(max(1, math.ceil(cost / evaluations)),
                    f"auto: ceil((2 fne_pairs + 4) / evaluations per step) = ceil({cost} / {evaluations})")


def fejer_term(u0, uK, u_star):
    """1/2 |u^K - u*|^2 - 1/2 |u^0 - u*|^2, Theorem 1's iterate part (kernel/c/certs.c alike)."""
    return 0.5 * distance(uK, u_star) ** 2 - 0.5 * distance(u0, u_star) ** 2


def augmented_residual(dH_total, u0, uK, u_star, a_hat, b_next, fejer=None):
    """Theorem 1 residual (eq. 32) with u* a DR fixed point of this macro-step (or its Fejer term given)."""
    fejer = fejer_term(u0, uK, u_star) if fejer is None else fejer
    return dH_total + fejer - port_energy(a_hat, b_next)


def fne_margins(subsystem, centre, pairs, rng, scale, dt):
    """Smallest normalized FNE margin of S_i^n over `pairs` random pairs around `centre` (the pairs
    drawn x, y, x, y, ... and queried in that order, all in one call); sums in a fixed order, as
    kernel/c/certs.c makes them."""
    m = len(centre)
    sigma = scale * (norm2(centre) + math.sqrt(dt))
    X = np.asarray(centre) + sigma * rng.standard_normal((2 * pairs, m))
    S = subsystem.queries(X)
    dS, dx = S[0::2] - S[1::2], X[0::2] - X[1::2]
    worst = np.inf
    for margin in ((row_dots(dS, dx) - row_dots(dS, dS)) / row_dots(dx, dx)).tolist():
        worst = min(worst, margin)
    return worst
