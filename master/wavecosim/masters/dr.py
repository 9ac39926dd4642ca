"""The wave-domain Douglas-Rachford master: Algorithm 1 of the paper, one macro-step at a time."""
import time

from ..kernel.linalg import distance, matvec
from .base import StepLog, WaveMaster
from .dr_options import Anderson, relaxed_update, warm_start


def algorithm1(S, P, J_L, b_n, K, eps=None, deadline=None, u_start=None, lam=1.0, anderson=None) -> StepLog:
    """Algorithm 1, lines 5-19, for one macro-step; returns the incident waves a_hat to advance with.

    S maps stacked incident waves to stacked outgoing waves (the frozen port maps, eq. 13). The
    options (dr_options.py): u_start replaces P b^n, lam relaxes line 12, anderson accelerates."""
    u = matvec(P, b_n) if u_start is None else u_start                # line 6, eq. (19): u^0 = P b^n
    u0, b_star = u, list(b_n)                                         # line 7, eq. (19): b^* = b^n
    k, residual, reason = 0, float("nan"), "budget"
    while k < K:                                                      # line 9
        b_hat = S(u)                                                  # line 10, eq. (17) response: b = S^n(u)
        w = matvec(J_L, [2.0 * bh - ui for bh, ui in zip(b_hat, u)])  # line 11, eq. (17) projection: w = J_L(2b - u)
        u_next = relaxed_update(u, w, b_hat, lam)                     # line 12, eq. (17) update: u + w - b
        b_star = b_hat                                                # line 13, eq. (20): b^* = last b
        if anderson is not None:                                      # safeguarded acceleration
            u_next, b_star = anderson.next(u, u_next, b_hat)
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


class DRMaster(WaveMaster):
    """Readable reference path: frozen maps queried from Python, Algorithm 1 above, one commit."""
    budgets = (0, 1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 35, 40, 50)
    style = ("tab:blue", "o")
    iterates = True
    guardable = True
    default_guard = "ledger"

    def __init__(self, scene, settings):
        super().__init__(scene, settings)
        self.K, self.eps = settings.K, settings.eps
        self.evaluations = self.K + 1                                  # at most; paces the certificates
        self._trace = None                                             # [] while recording (u, S(u)) pairs
        self.relaxation = self._relaxation(settings.relaxation)       # lambda of line 12
        self.anderson = self._anderson()
        self.warm_start = settings.warm_start
        self._b_before = None                                          # b^{n-1} for the warm start

    def _relaxation(self, setting):
        """lambda as a number; `auto` probes the scene at x^0 (wavecosim.core.gamma.choose_relaxation)."""
        self.relaxation_choice = None
        if setting != "auto":
            return float(setting)
        self.relaxation_choice = self.scene.choose_relaxation(self.b, self.P)
        return self.relaxation_choice["relaxation"]

    def _anderson(self):
        """A fresh Anderson accelerator (None when off): the window, its memory, the extrapolated b^*."""
        s = self.settings
        return Anderson(s.anderson, s.anderson_memory, s.anderson_extrapolate) if s.anderson else None

    def retune(self, b):
        super().retune(b)
        self._b_before = None                                          # b^{n-1} was at the old gammas
        self.anderson = self._anderson()                               # so were the Anderson differences

    def run_info(self):
        """The DR options in force (relaxation as used; with auto, the predicted rates)."""
        info = {"relaxation": self.relaxation, "anderson": self.settings.anderson,
                "anderson_memory": self.settings.anderson_memory,
                "anderson_extrapolate": self.settings.anderson_extrapolate, "warm_start": self.warm_start}
        if self.relaxation_choice is not None:
            info["relaxation_rates"] = {k: v for k, v in self.relaxation_choice.items() if k != "relaxation"}
        return info

    def start_iterate(self):
        """u^{n,0}: None (the paper's P b^n) or, with warm_start, P (2 b^n - b^{n-1}); remembers b^n."""
        if not self.warm_start:
            return None
        u, self._b_before = warm_start(self.P, self.b, self._b_before), self.b
        return u

    def enable_trace(self, on=True):
        self._trace = [] if on else None
        return True

    @property
    def trace(self):
        return self._trace

    def _S(self, u):
        """S^n (eq. 13), recording the query when tracing (for the Condition 1 watch and gamma tuner)."""
        b = self.scene.S(u)
        if self._trace is not None:
            self._trace.append((u, b))
        return b

    def step(self, n, t) -> StepLog:
        self.step_started = time.perf_counter()
        self.scene.freeze(n, t)                                        # line 3: S^n from x^n
        if self._trace is not None:
            self._trace = []
        deadline = self.step_started + self.inner_deadline_s if self.deadline_s else None
        if self.anderson is not None:
            self.anderson.reset()
        log = algorithm1(self._S, self.P, self.J_L, self.b, self.K, self.eps, deadline, self.start_iterate(),
                         self.relaxation, self.anderson)
        self.commit(log.a_hat)                                         # lines 20-22, eq. (21)
        return log
