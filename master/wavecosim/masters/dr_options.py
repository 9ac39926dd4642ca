"""The named options of the DR master (`master.relaxation`, `master.anderson`, `master.anderson_memory`,
`master.anderson_extrapolate`, `master.start`),
written once in plain Python in the operation order that kernel/c/dr_options.h mirrors, so the
reference and the C kernel stay bit-identical.

- relaxation lambda in (0, 2): line 12 becomes u + lambda (w - b_hat); lambda = 1 is the paper's
  update, lambda / 2 is the averaging constant of the relaxed DR operator, so it stays averaged
  (Fejer monotone) and Theorem 1 keeps holding.
- anderson m: type-II Anderson acceleration of the (relaxed) DR map over the last m differences,
  safeguarded: an accelerated iterate is kept only when its fixed-point residual is at most
  ANDERSON_SAFEGUARD times that of the last accepted iterate, otherwise the plain step from the
  last accepted iterate follows (b^* is the response of the smaller residual of the two). Its iterates are not Fejer monotone, so Theorem 1's per-step
  certificate does not apply; the energy ledger guard keeps the run energy-safe.
- anderson memory: the Anderson differences outlive the macro-step, so each step's first query is
  already accelerated with the secant information of the steps before; a rejection forgets them.
- anderson extrapolate: b^* is the Anderson combination of the responses, b_hat - sum theta_i dB_i,
  with the weights of the accelerated iterate (exact on an affine map once the differences span it,
  one query before that iterate is queried), as the classical masters commit their last update; it
  is no response of the frozen maps, so like Anderson itself it rests on the ledger guard.
- options: `auto` sets the others from the scene instead of from constants: gamma per subsystem
  from a probe of the port impedances at the start (`gamma: auto`, within each FNE bound), the
  relaxation lambda with the fastest predicted contraction at those gammas (`relaxation: auto`), and
  an Anderson window as wide as the interface (one difference per channel, at most ANDERSON_MAX),
  kept across macro-steps and extrapolating b^* (auto_settings); what was chosen is in the summary.
- start (u^{n,0}, eq. 19): `paper` P b^n; `previous` the incident wave committed at the previous
  macro-step, a^{n-1} (the previous step's estimate of its fixed point, held over the step as a
  zero-order hold); `extrapolated` P (2 b^n - b^{n-1}); `auto` is `previous` unless the energy guard
  is off (then Algorithm 1 runs as printed). The start changes only u^{n,0}: the iterates stay Fejer
  monotone from any start, so Theorem 1 keeps holding step by step. The first step, and the step
  after a change of gamma, start from P b^n.
"""
from dataclasses import replace

from ..kernel.drkernel import STARTS as DR_STARTS
from ..kernel.linalg import dot, matvec

ANDERSON_SAFEGUARD = 0.9     # an accelerated iterate must cut the fixed-point residual at least this much
ANDERSON_REG = 1e-12         # Tikhonov term of the least-squares problem, relative to its largest diagonal
ANDERSON_MAX = 16            # the largest window (the C kernel's fixed bound)


def relaxed_update(u, w, b_hat, lam):
    """Algorithm 1, line 12: u + w - b_hat (lam = 1, as in the paper) or u + lam (w - b_hat)."""
    if lam == 1.0:
        return [ui + wi - bh for ui, wi, bh in zip(u, w, b_hat)]
    return [ui + lam * (wi - bh) for ui, wi, bh in zip(u, w, b_hat)]


STARTS = DR_STARTS                # master.start (index: the C kernel's code), and "auto"
OPTION_MODES = ("manual", "auto")                  # master.options


def auto_settings(settings, channels):
    """The master settings `options: auto` runs with: relaxation auto, an Anderson window of one
    difference per interface channel (an affine frozen map is then solved once the differences span
    the channels), memory and extrapolation on; gamma auto is the runner's (auto_gamma)."""
    if settings.options != "auto":
        return settings
    return replace(settings, relaxation="auto", anderson=min(channels, ANDERSON_MAX), anderson_memory=True,
                   anderson_extrapolate=True)


def auto_gamma(gamma, settings):
    """The scenario's gamma as run: `auto` under `options: auto` unless the scenario names a mode."""
    return "auto" if settings.options == "auto" and not isinstance(gamma, str) else gamma


def resolve_start(start, energy_guard):
    """master.start as run: `auto` is `previous` under the energy ledger, whose redo keeps a start away
    from the fixed point from supplying energy, and `paper` under any other guard."""
    if start != "auto":
        return start
    return "previous" if energy_guard == "ledger" else "paper"


def start_point(start, P, b_n, b_prev, a_prev):
    """u^{n,0}: P b^n (`paper`, and every start without its history: first step, after a re-tune),
    P (2 b^n - b^{n-1}) (`extrapolated`) or a^{n-1} (`previous`)."""
    if start == "extrapolated" and b_prev is not None:
        return matvec(P, [2.0 * b - bp for b, bp in zip(b_n, b_prev)])
    if start == "previous" and a_prev is not None:
        return list(a_prev)
    return matvec(P, b_n)


def solve(A, r):
    """A x = r by Gaussian elimination with partial pivoting (in place on copies); None if singular."""
    p = len(r)
    A, x = [row[:] for row in A], r[:]
    for c in range(p):
        piv = max(range(c, p), key=lambda i: abs(A[i][c]))
        if A[piv][c] == 0.0:
            return None
        A[c], A[piv], x[c], x[piv] = A[piv], A[c], x[piv], x[c]
        for i in range(c + 1, p):
            f = A[i][c] / A[c][c]
            for j in range(c, p):
                A[i][j] -= f * A[c][j]
            x[i] -= f * x[c]
    for c in range(p - 1, -1, -1):
        acc = x[c]
        for j in range(c + 1, p):
            acc -= A[c][j] * x[j]
        x[c] = acc / A[c][c]
    return x


def least_squares(dG, g):
    """theta = argmin |g - sum_i theta_i dG_i| from the regularized normal equations; None if degenerate."""
    p = len(dG)
    A = [[dot(dG[i], dG[j]) for j in range(p)] for i in range(p)]
    top = max(A[i][i] for i in range(p))
    if not top > 0.0:
        return None
    for i in range(p):
        A[i][i] += ANDERSON_REG * top
    theta = solve(A, [dot(dG[i], g) for i in range(p)])
    if theta is None or any(t != t or abs(t) == float("inf") for t in theta):
        return None
    return theta


class Anderson:
    """Safeguarded Anderson acceleration of one macro-step's DR iteration (see the module docstring)."""

    def __init__(self, m, memory=False, extrapolate=False):
        self.m, self.memory, self.extrapolate = m, memory, extrapolate
        self.dF, self.dG, self.dB = [], [], []
        self.reset()

    def reset(self):
        """A new macro-step: forget the last accepted iterate and, without memory, the differences."""
        if not self.memory:
            self.dF, self.dG, self.dB = [], [], []
        self.f_acc = self.g_acc = self.b_acc = None
        self.candidate = False

    def next(self, u, f, b_hat):
        """From the query point u, its DR step f = T(u) and response b_hat: (next iterate, b^*), b^*
        the response at the last accepted iterate (Algorithm 1, line 13), or at a rejected one whose
        residual is still the smaller (so a rejection at the last query costs no accuracy)."""
        g = [fi - ui for fi, ui in zip(f, u)]
        gg, acc = dot(g, g), dot(self.g_acc, self.g_acc) if self.g_acc is not None else 0.0
        if self.candidate and gg > ANDERSON_SAFEGUARD * ANDERSON_SAFEGUARD * acc:
            self.dF, self.dG, self.dB, self.candidate = [], [], [], False   # rejected: the plain step instead,
            return self.f_acc, (b_hat if gg < acc else self.b_acc)  # b^* the response of smaller residual
        if self.g_acc is not None:
            if len(self.dG) == self.m:
                del self.dF[0], self.dG[0], self.dB[:1]
            self.dG.append([a - b for a, b in zip(g, self.g_acc)])
            self.dF.append([a - b for a, b in zip(f, self.f_acc)])
            if self.extrapolate:
                self.dB.append([a - b for a, b in zip(b_hat, self.b_acc)])
        self.f_acc, self.g_acc, self.b_acc = f, g, b_hat
        theta = least_squares(self.dG, g) if self.dG else None
        self.candidate = theta is not None
        if theta is None:
            return f, b_hat
        b_star = [bj - _combine(theta, self.dB, j) for j, bj in enumerate(b_hat)] if self.extrapolate else b_hat
        return [fj - _combine(theta, self.dF, j) for j, fj in enumerate(f)], b_star


def _combine(theta, cols, j):
    """sum_i theta_i cols_i[j], summed in history order from 0.0."""
    acc = 0.0
    for t, col in zip(theta, cols):
        acc += t * col[j]
    return acc
