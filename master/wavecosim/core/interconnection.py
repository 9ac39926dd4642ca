"""Lossless interconnections: a Dirac structure E e + F f = 0 compiled to the wave map a = P b.

With per-channel impedances Gamma, substituting eq. (4) gives
P = (F Gamma^-1/2 + E Gamma^1/2)^-1 (F Gamma^-1/2 - E Gamma^1/2), orthogonal when E F^T + F E^T = 0
and [E F] has full row rank (paper eqs. 9-10, Remark 1). J_L = (2I - P)^-1 (eq. 16) is cached.

Couplings that share no channel are independent: after a permutation E and F are block diagonal,
and so are P and J_L, one block per connected component of [E F]'s pattern. Each block is compiled
alone and P, J_L are kept sparse (linalg.Sparse), so compiling and applying them grows with the
number of couplings, not its square.
"""
from dataclasses import dataclass

import numpy as np

from ..errors import CouplingError
from ..kernel import linalg
from ..kernel.linalg import Sparse

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
    """The compiled interconnection: P (orthogonal) and J_L = (2I - P)^-1, sparse (P_sparse,
    J_L_sparse; the dense P and J_L are built when asked), and |P^T P - I|."""
    P_sparse: Sparse
    J_L_sparse: Sparse
    orthogonality_residual: float

    @property
    def P(self):
        return np.asarray(self.P_sparse)

    @property
    def J_L(self):
        return np.asarray(self.J_L_sparse)


def components(E, F):
    """(rows, columns) of each connected component of [E F]'s nonzero pattern, in order of their
    first row; one component over everything when a component is not square."""
    n = E.shape[0]
    parent = list(range(2 * n))                  # rows 0..n-1, columns n..2n-1

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for r, c in zip(*np.nonzero((E != 0) | (F != 0))):
        a, b = root(int(r)), root(n + int(c))
        if a != b:
            parent[max(a, b)] = min(a, b)
    groups = {}
    for i in range(2 * n):
        groups.setdefault(root(i), ([], []))[i >= n].append(i % n)
    found = [(rows, cols) for rows, cols in groups.values() if rows or cols]
    if any(len(rows) != len(cols) for rows, cols in found):
        return [(list(range(n)), list(range(n)))]
    return found


def check_dirac(E, F, where="coupling"):
    """Raise CouplingError unless E e + F f = 0 is a lossless Dirac structure of full rank
    (checked per connected component: the rank of a block-diagonal matrix is the sum of its blocks')."""
    E, F = np.asarray(E, float), np.asarray(F, float)
    if E.ndim != 2 or E.shape != F.shape or E.shape[0] != E.shape[1]:
        raise CouplingError(f"{where}: E and F must be square matrices of the same size, got "
                            f"{E.shape} and {F.shape}")
    n = E.shape[0]
    tol = TOL * max(1.0, np.abs(E).max(initial=0.0), np.abs(F).max(initial=0.0))
    scale = max(1.0, np.abs(E).max() * np.abs(F).max())
    rank, lossless = 0, 0.0
    for rows, cols in components(E, F):
        Eb, Fb = E[np.ix_(rows, cols)], F[np.ix_(rows, cols)]
        rank += np.linalg.matrix_rank(np.hstack([Eb, Fb]), tol=tol)
        lossless = max(lossless, float(np.abs(Eb @ Fb.T + Fb @ Eb.T).max() / scale))
    if rank < n:
        raise CouplingError(f"{where}: [E F] is not of full rank {n}; the coupling leaves port variables free")
    if lossless > TOL:
        raise CouplingError(f"{where}: not lossless, |E F^T + F E^T| = {lossless:.3g} (must be 0)")
    return lossless


def _snap(M):
    """Round entries within 1e-12 of an integer, so permutations and junction maps are exact."""
    R = np.round(M)
    return np.where(np.abs(M - R) < 1e-12, R, M)


_CHECKED = {}         # the components of recently checked couplings (gamma searches compile one many times)
CHECKED_KEPT = 8


def _checked_components(E, F, where):
    """check_dirac, then components(E, F), remembered for the same E and F (neither depends on gamma)."""
    key = (E.shape, E.tobytes(), F.tobytes())
    if key not in _CHECKED:
        check_dirac(E, F, where)
        if len(_CHECKED) >= CHECKED_KEPT:
            _CHECKED.pop(next(iter(_CHECKED)))
        _CHECKED[key] = components(E, F)
    return _CHECKED[key]


def compile_wave_map(E, F, gammas, where="coupling") -> WaveInterconnection:
    """P from E e + F f = 0 for channel impedances `gammas` (one per channel, all > 0)."""
    E, F = np.asarray(E, float), np.asarray(F, float)
    parts = _checked_components(E, F, where)
    g = np.asarray(gammas, float)
    if g.shape != (E.shape[0],) or not np.all(g > 0) or not np.all(np.isfinite(g)):
        raise CouplingError(f"{where}: gamma must be finite and > 0 on each of the {E.shape[0]} channels")
    left = F / np.sqrt(g) + E * np.sqrt(g)
    right = F / np.sqrt(g) - E * np.sqrt(g)
    P_parts, J_parts, ortho = [], [], 0.0
    for rows, cols in parts:
        P, J_L, residual = _compile_block(left[np.ix_(rows, cols)], right[np.ix_(rows, cols)], where)
        ortho = max(ortho, residual)
        P_parts.append((cols, P))
        J_parts.append((cols, J_L))
    n = E.shape[0]
    return WaveInterconnection(P_sparse=_gather(P_parts, n), J_L_sparse=_gather(J_parts, n),
                               orthogonality_residual=ortho)


def _compile_block(left, right, where):
    """P = left^-1 right (snapped), |P^T P - I| and J_L = (2I - P)^-1 of one component."""
    P = linalg.solve_columns(left, right)
    if P is None:
        raise CouplingError(f"{where}: F + gamma E is singular; the coupling has no wave form")
    P = _snap(P)
    n = P.shape[0]
    ortho = float(np.abs(P.T @ P - np.eye(n)).max())
    if ortho > 1e-9:
        raise CouplingError(f"{where}: compiled wave map is not orthogonal (|P^T P - I| = {ortho:.3g})")
    return P, linalg.solve_columns(2.0 * np.eye(n) - P, np.eye(n)), ortho


def _gather(parts, n):
    """One Sparse n x n matrix from blocks (channels, dense block on those channels)."""
    rows, cols, vals = [], [], []
    for channels, block in parts:
        r, c = np.nonzero(block)
        ch = np.asarray(channels)
        rows.append(ch[r])
        cols.append(ch[c])
        vals.append(block[r, c])
    rows, cols, vals = (np.concatenate(x) for x in (rows, cols, vals))
    order = np.lexsort((cols, rows))
    start = np.searchsorted(rows[order], np.arange(n + 1))
    return Sparse(n, start, cols[order], vals[order])


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
