"""The wave-domain Douglas-Rachford master: Algorithm 1 of the paper, one macro-step at a time."""
import time

from ..kernel.linalg import distance, matvec
from .base import StepLog, WaveMaster
from .dr_options import Anderson, auto_settings, relaxed_update, resolve_start, start_point


class Anchors:
    """Queries of a macro-step the energy ledger may commit instead of a_hat, each with its known
    response and supply 1/2 (|u|^2 - |S(u)|^2): the last one, and the latest whose supply was <= 0
    (it fits any allowance). kernel/c/drkernel.c keeps the same two."""

    def __init__(self):
        self.last = self.safe = None

    def add(self, u, b):
        self.last = (u, b, WaveMaster._supply(u, b)[0])
        if self.last[2] <= 0.0:
            self.safe = self.last

    def candidates(self):
        """The last query, then the latest safe one when it is another."""
        out = [self.last] if self.last is not None else []
        return out + [self.safe] if self.safe is not None and self.safe is not self.last else out


def algorithm1(S, P, J_L, b_n, K, eps=None, deadline=None, u_start=None, lam=1.0, anderson=None,
               anchors=None) -> StepLog:
    """Algorithm 1, lines 5-19, for one macro-step; returns the incident waves a_hat to advance with.

    S maps stacked incident waves to stacked outgoing waves (the frozen port maps, eq. 13). The
    options (dr_options.py): u_start replaces P b^n, lam relaxes line 12, anderson accelerates;
    anchors (Anchors) keeps queries for the energy ledger."""
    u = matvec(P, b_n) if u_start is None else u_start                # line 6, eq. (19): u^0 = P b^n
    u0, b_star = u, list(b_n)                                         # line 7, eq. (19): b^* = b^n
    k, residual, reason = 0, float("nan"), "budget"
    while k < K:                                                      # line 9
        b_hat = S(u)                                                  # line 10, eq. (17) response: b = S^n(u)
        if anchors is not None:
            anchors.add(u, b_hat)
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
        settings = auto_settings(settings, scene.n_channels)           # options: auto
        super().__init__(scene, settings)
        self.K, self.eps = settings.K, settings.eps
        self.evaluations = self.K + 1                                  # at most; paces the certificates
        self._trace = None                                             # [] while recording (u, S(u)) pairs
        self.relaxation = self._relaxation(settings.relaxation)       # lambda of line 12
        self.anderson = self._anderson()
        self.start = resolve_start(settings.start, settings.energy_guard or self.default_guard)
        self._b_before = self._a_before = None                         # b^{n-1}, a^{n-1} for the start
        self._a_step_start = None                                      # a^{n-1} again after an undo
        self._anchors = Anchors()

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
        self._b_before = self._a_before = None                         # b^{n-1}, a^{n-1} were at the old gammas
        self.anderson = self._anderson()                               # so were the Anderson differences

    def _commit(self, a_hat):
        super()._commit(a_hat)
        self._a_step_start, self._a_before = self._a_before, a_hat

    def _undo_step(self):
        super()._undo_step()
        self._a_before = self._a_step_start

    def run_info(self):
        """The DR options in force (relaxation as used; with auto, the predicted rates)."""
        info = {"options": self.settings.options, "relaxation": self.relaxation, "anderson": self.settings.anderson,
                "anderson_memory": self.settings.anderson_memory,
                "anderson_extrapolate": self.settings.anderson_extrapolate, "start": self.start}
        if self.relaxation_choice is not None:
            info["relaxation_rates"] = {k: v for k, v in self.relaxation_choice.items() if k != "relaxation"}
        return info

    def _start_iterate(self):
        """u^{n,0} of master.start (dr_options.start_point); remembers b^n."""
        if self.start == "paper":
            return None
        u, self._b_before = start_point(self.start, self.P, self.b, self._b_before, self._a_before), self.b
        return u

    def _anchor_queries(self):
        """The queries of the step just made that the energy ledger may commit (Anchors.candidates)."""
        return self._anchors.candidates()

    def _remaining_iterations(self, log):
        """Inner iterations the step's budget K has left after it stopped (tolerance, deadline)."""
        return self.K - log.iterations

    def _iterate_on(self, log, more, deadline):
        """After _undo_step: up to `more` further inner iterations of this macro-step from log's u^K,
        without the tolerance exit, then the commit; returns the step's log with the new a_hat and
        the iterations made."""
        more_log = algorithm1(self.scene.S, self.P, self.J_L, self.b, more, None, deadline, log.uK, self.relaxation,
                              self.anderson, self._anchors)
        self._commit(more_log.a_hat)
        return StepLog(iterations=log.iterations, residual=log.residual, reason=log.reason, a_hat=more_log.a_hat,
                       u0=log.u0, uK=more_log.uK), more_log.iterations

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

    def make_step(self, n, t) -> StepLog:
        self.step_started = time.perf_counter()
        self.scene.freeze(n, t)                                        # line 3: S^n from x^n
        if self._trace is not None:
            self._trace = []
        deadline = self.step_started + self.inner_deadline_s if self.deadline_s else None
        if self.anderson is not None:
            self.anderson.reset()
        self._anchors = Anchors()
        log = algorithm1(self._S, self.P, self.J_L, self.b, self.K, self.eps, deadline, self._start_iterate(),
                         self.relaxation, self.anderson, self._anchors)
        self._commit(log.a_hat)                                         # lines 20-22, eq. (21)
        return log
