"""Accelerated fixed-point iteration on the physical interface, the classical anchors of partitioned
coupling (as preCICE offers them): Aitken's dynamic under-relaxation and interface quasi-Newton
with inverse least squares (IQN-ILS, Degroote et al.).

Both iterate y -> H(y) = S^n(G y) (a Jacobi pass, one doStep per subsystem) with rollback, like
jacobi-iter, and only choose the next iterate differently; residual r = H(y) - y.
"""
import numpy as np

from ..kernel import linalg
from .fixed_point import JacobiIterMaster

INITIAL_RELAXATION = 0.5     # the first update of each macro-step: y + 0.5 r


class AitkenMaster(JacobiIterMaster):
    """y^{k+1} = y^k + w_k r^k with w_k = -w_{k-1} <r^{k-1}, r^k - r^{k-1}> / |r^k - r^{k-1}|^2."""
    style = ("tab:olive", "P")

    def restart(self):
        self.omega, self.r_prev = INITIAL_RELAXATION, None

    def update(self, y, y_tilde):
        r = y_tilde - y
        if self.r_prev is not None:
            dr = r - self.r_prev
            denom = linalg.dot(dr.tolist(), dr.tolist())
            if denom > 0.0:
                self.omega = -self.omega * linalg.dot(self.r_prev.tolist(), dr.tolist()) / denom
        self.r_prev = r
        return y + self.omega * r


class IQNILSMaster(JacobiIterMaster):
    """IQN-ILS: from the differences of residuals V and of images W seen in this macro-step,
    alpha = argmin |V alpha + r^k| and y^{k+1} = H(y^k) + W alpha (the first update relaxed)."""
    style = ("tab:pink", "X")

    def restart(self):
        self.V, self.W, self.last = [], [], None

    def update(self, y, y_tilde):
        r = y_tilde - y
        if self.last is not None:
            self.V.append(r - self.last[0])
            self.W.append(y_tilde - self.last[1])
        self.last = (r, y_tilde)
        if not self.V:
            return y + INITIAL_RELAXATION * r
        V, W = np.column_stack(self.V), np.column_stack(self.W)
        alpha = linalg.least_squares(V, (-r).tolist())
        return y_tilde + np.array(linalg.matvec(W, alpha.tolist()))
