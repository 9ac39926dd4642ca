"""The wave-domain Douglas-Rachford master: Algorithm 1 of the paper, one macro-step at a time."""
import time

from ..linalg import distance, matvec
from .base import Master, StepLog


def algorithm1(S, P, J_L, b_n, K, eps=None, deadline=None) -> StepLog:
    """Algorithm 1, lines 5-19, for one macro-step; returns the incident waves a_hat to advance with.

    S maps stacked incident waves to stacked outgoing waves (the frozen port maps, eq. 13)."""
    u = matvec(P, b_n)                                                # line 6, eq. (19): u^0 = P b^n
    u0, b_star = u, list(b_n)                                         # line 7, eq. (19): b^* = b^n
    k, residual, reason = 0, float("nan"), "budget"
    while k < K:                                                      # line 9
        b_hat = S(u)                                                  # line 10, eq. (17) response: b = S^n(u)
        w = matvec(J_L, [2.0 * bh - ui for bh, ui in zip(b_hat, u)])  # line 11, eq. (17) projection: w = J_L(2b - u)
        u_next = [ui + wi - bh for ui, wi, bh in zip(u, w, b_hat)]    # line 12, eq. (17) update: u + w - b
        b_star = b_hat                                                # line 13, eq. (20): b^* = last b
        residual = distance(u_next, u)
        u, k = u_next, k + 1
        if eps is not None and residual <= eps:                       # lines 14-16: optional exit
            reason = "tolerance"
            break
        if deadline is not None and time.perf_counter() >= deadline:
            reason = "deadline"
            break
    a_hat = matvec(P, b_star)                                         # line 19, eq. (21): a = P b^*
    return StepLog(iterations=k, residual=residual, reason=reason if K else "explicit", a_hat=a_hat,
                   u0=u0, uK=u)


class DRMaster(Master):
    """Readable reference path: frozen maps queried from Python, Algorithm 1 above, one commit."""
    name = "dr"

    def __init__(self, scene, settings, gamma=None):
        super().__init__(scene, settings)
        self.coupling = scene.wave_map(gamma)
        self.P, self.J_L = self.coupling.P.tolist(), self.coupling.J_L.tolist()
        self.b = [0.0] * scene.n_channels                              # b^0 = 0
        self.K, self.eps = settings.K, settings.eps
        self.deadline_s = settings.deadline_us * 1e-6 if settings.deadline_us else None
        self.trace = None                                              # set to [] to record (u, S(u)) pairs

    def S(self, u):
        """Stacked frozen port map S^n = diag(S_A, S_B, ...) (eq. 13)."""
        b = []
        for sub, a_i in zip(self.subsystems, self.scene.split(u)):
            b.extend(sub.query(a_i))
        if self.trace is not None:                                    # for the Condition 1 watch (fne_watch)
            self.trace.append((u, b))
        return b

    def set_gamma(self, gamma, b):
        """Between macro-steps only: recompile P, J_L for a new gamma and take b^n re-scattered to it."""
        self.coupling = self.scene.wave_map(gamma)
        self.P, self.J_L = self.coupling.P.tolist(), self.coupling.J_L.tolist()
        self.b = list(b)

    def freeze(self, n, t):
        for sub in self.subsystems:                                   # line 3: S^n from x^n
            sub.freeze(n, t)

    def step(self, n, t) -> StepLog:
        self.freeze(n, t)
        if self.trace is not None:
            self.trace = []
        deadline = time.perf_counter() + self.deadline_s if self.deadline_s else None
        log = algorithm1(self.S, self.P, self.J_L, self.b, self.K, self.eps, deadline)
        b_next = []
        for sub, a_i in zip(self.subsystems, self.scene.split(log.a_hat)):
            b_next.extend(sub.advance(a_i))                          # lines 20-22, eq. (21): commit
        self.b = b_next
        return log
