"""Lossless interconnections: a Dirac structure E e + F f = 0 compiled to the wave map a = P b.

With per-channel impedances Gamma, substituting eq. (4) gives
P = (F Gamma^-1/2 + E Gamma^1/2)^-1 (F Gamma^-1/2 - E Gamma^1/2), orthogonal when E F^T + F E^T = 0
and [E F] has full row rank (paper eqs. 9-10, Remark 1). J_L = (2I - P)^-1 (eq. 16) is cached.
"""
from dataclasses import dataclass

import numpy as np

from .errors import CouplingError

TOL = 1e-10


def equal_effort_opposite_flow(m=1):
    """Two ports of m channels: e_A = e_B, f_A + f_B = 0 (paper eqs. 7-8)."""
    i, z = np.eye(m), np.zeros((m, m))
    return np.block([[i, -i], [z, z]]), np.block([[z, z], [i, i]])


def zero_junction(k):
    """Bond-graph 0-junction over k scalar ports: common effort, flows sum to zero."""
    E, F = np.zeros((k, k)), np.zeros((k, k))
    for r in range(k - 1):
        E[r, r], E[r, r + 1] = 1.0, -1.0
    F[k - 1, :] = 1.0
    return E, F


def one_junction(k):
    """Bond-graph 1-junction over k scalar ports: common flow, efforts sum to zero."""
    F, E = zero_junction(k)
    return E, F


def transformer(n):
    """Ideal transformer e1 = n e2, n f1 = -f2 (power into port 1 leaves through port 2)."""
    return np.array([[1.0, -n], [0.0, 0.0]]), np.array([[0.0, 0.0], [n, 1.0]])


def gyrator(r):
    """Ideal gyrator e1 = r f2, e2 = -r f1 (lossless: e1 f1 + e2 f2 = 0)."""
    return np.array([[1.0, 0.0], [0.0, 1.0]]), np.array([[0.0, -r], [r, 0.0]])


def free_end():
    """A 1-port termination with zero effort (nothing attached)."""
    return np.array([[1.0]]), np.array([[0.0]])


def clamped_end():
    """A 1-port termination with zero flow (held fixed)."""
    return np.array([[0.0]]), np.array([[1.0]])


def _two_ports(c, groups, where):
    if len(groups) != 2 or len(groups[0]) != len(groups[1]):
        raise CouplingError(f"{where}: equal_effort_opposite_flow joins two ports of equal dimension, "
                            f"got sizes {[len(g) for g in groups]}")
    return [("", *equal_effort_opposite_flow(len(groups[0])))]


def _junction(make):
    def blocks(c, groups, where):
        if sum(map(len, groups)) < 2:
            raise CouplingError(f"{where}: a junction needs at least two channels")
        return [("", *make(sum(map(len, groups))))]
    return blocks


def _two_port_element(make):
    def blocks(c, groups, where):
        n = sum(map(len, groups))
        if n != 2:
            raise CouplingError(f"{where}: a {c.type} joins exactly two scalar channels, got {n}")
        return [("", *make(c.ratio))]
    return blocks


def _termination(make):
    def blocks(c, groups, where):
        return [(f".{j}", *make()) for j in range(sum(map(len, groups)))]
    return blocks


def _dirac(c, groups, where):
    n = sum(map(len, groups))
    E, F = np.asarray(c.E, float), np.asarray(c.F, float)
    if E.shape != (n, n) or F.shape != (n, n):
        raise CouplingError(f"{where}: E and F must be {n}x{n} for the {n} listed channels, got "
                            f"{E.shape} and {F.shape}")
    check_dirac(E, F, where)
    return [("", E, F)]


# coupling type -> blocks(coupling, channel groups, where): [(suffix, E, F)]; a termination gives one
# block per channel (suffix ".j"), every other type one block over all its channels.
COUPLINGS = {
    "equal_effort_opposite_flow": _two_ports,
    "zero_junction": _junction(zero_junction),
    "one_junction": _junction(one_junction),
    "transformer": _two_port_element(transformer),
    "gyrator": _two_port_element(gyrator),
    "free_end": _termination(free_end),
    "clamped_end": _termination(clamped_end),
    "dirac": _dirac,
}
TAKES_RATIO = ("transformer", "gyrator")


@dataclass
class WaveInterconnection:
    """The compiled interconnection: P (orthogonal), J_L = (2I - P)^-1 and |P^T P - I|."""
    P: np.ndarray
    J_L: np.ndarray
    orthogonality_residual: float


def check_dirac(E, F, where="coupling"):
    """Raise CouplingError unless E e + F f = 0 is a lossless Dirac structure of full rank."""
    E, F = np.asarray(E, float), np.asarray(F, float)
    if E.ndim != 2 or E.shape != F.shape or E.shape[0] != E.shape[1]:
        raise CouplingError(f"{where}: E and F must be square matrices of the same size, got "
                            f"{E.shape} and {F.shape}")
    n = E.shape[0]
    if np.linalg.matrix_rank(np.hstack([E, F]), tol=TOL * max(1.0, np.abs(np.hstack([E, F])).max())) < n:
        raise CouplingError(f"{where}: [E F] is not of full rank {n}; the coupling leaves port variables free")
    scale = max(1.0, np.abs(E).max() * np.abs(F).max())
    lossless = float(np.abs(E @ F.T + F @ E.T).max() / scale)
    if lossless > TOL:
        raise CouplingError(f"{where}: not lossless, |E F^T + F E^T| = {lossless:.3g} (must be 0)")
    return lossless


def _snap(M):
    """Round entries within 1e-12 of an integer, so permutations and junction maps are exact."""
    R = np.round(M)
    return np.where(np.abs(M - R) < 1e-12, R, M)


def compile_wave_map(E, F, gammas, where="coupling") -> WaveInterconnection:
    """P from E e + F f = 0 for channel impedances `gammas` (one per channel, all > 0)."""
    E, F = np.asarray(E, float), np.asarray(F, float)
    check_dirac(E, F, where)
    g = np.asarray(gammas, float)
    if g.shape != (E.shape[0],) or not np.all(g > 0) or not np.all(np.isfinite(g)):
        raise CouplingError(f"{where}: gamma must be finite and > 0 on each of the {E.shape[0]} channels")
    left = F / np.sqrt(g) + E * np.sqrt(g)
    right = F / np.sqrt(g) - E * np.sqrt(g)
    try:
        P = _snap(np.linalg.solve(left, right))
    except np.linalg.LinAlgError:
        raise CouplingError(f"{where}: F + gamma E is singular; the coupling has no wave form") from None
    n = P.shape[0]
    ortho = float(np.abs(P.T @ P - np.eye(n)).max())
    if ortho > 1e-9:
        raise CouplingError(f"{where}: compiled wave map is not orthogonal (|P^T P - I| = {ortho:.3g})")
    J_L = np.linalg.inv(2.0 * np.eye(n) - P)
    return WaveInterconnection(P=P, J_L=J_L, orthogonality_residual=ortho)


def assemble(blocks, n_channels, where="coupling"):
    """Stack per-coupling (E, F, channel indices) into global E, F over all channels.

    Each channel must appear in exactly one block, so the stacked structure is square."""
    E = np.zeros((n_channels, n_channels))
    F = np.zeros((n_channels, n_channels))
    row = 0
    seen = {}
    for name, Eb, Fb, channels in blocks:
        Eb, Fb = np.asarray(Eb, float), np.asarray(Fb, float)
        if Eb.shape != (len(channels), len(channels)) or Fb.shape != Eb.shape:
            raise CouplingError(f"{where}.{name}: E and F must be {len(channels)}x{len(channels)} for its "
                                f"{len(channels)} channels, got {Eb.shape} and {Fb.shape}")
        for c in channels:
            if c in seen:
                raise CouplingError(f"{where}.{name}: channel {c} is already connected by {seen[c]}")
            seen[c] = name
        k = len(channels)
        E[row:row + k, channels] = Eb
        F[row:row + k, channels] = Fb
        row += k
    if row != n_channels:
        missing = sorted(set(range(n_channels)) - set(seen))
        raise CouplingError(f"{where}: port channels {missing} are not connected by any coupling")
    return E, F
