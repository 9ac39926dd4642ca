"""The monolithic macro-step: solve the interface condition b = S^n(P b) (eqs. 14-15) by Newton.

This is the monolithic reference of the DR master (the true monolithic discrete-time step, not a
long DR run), the Newton master's step and the energy guard's redo. The Jacobian of the
block-diagonal S^n is taken by forward differences through rollback, perturbing channel j of
every subsystem at once.

Acceptance: |b - S(Pb)| <= ACCEPT (1 + |b|), or, for FMUs whose step map is smooth only to their
own solver's tolerance (the wave adapter then solves S only to about that), within ACCEPT_REL of
the port-wave scale |a| + |b|. Past the absolute level, Newton also stops after STALL iterations in
a row that do not halve the residual (it has reached the FMUs' noise floor). Our own FMUs converge
to TOL well before either applies, so their reference results do not depend on them.

The Jacobian is block-diagonal (one block per subsystem) and P is sparse, so the Newton matrix
I - J_S P is sparse too: it is built row by row from P's stored entries and solved by the sparse LU
of linalg.solve_sparse, whose work follows the nonzeros (a chain of N subsystems: linear in N, as
the master). The arithmetic runs in a fixed operation order (wavecosim/kernel/linalg.py: sums left
to right, the LU's pivots and updates), mirrored by kernel/c/newton.c, so the Newton master's kernel
route (wavecosim/kernel/newton.py, which also holds the acceptance constants both share) gives the
same bits.
"""
import numpy as np

from ..kernel.linalg import distance, matvec, norm2, solve_sparse
from ..kernel.newton import (ACCEPT, ACCEPT_REL, MAX_ITER, NON_FINITE, SINGULAR, STALL, TOL, failed, nan_channel,
                             nan_source, not_converged)


def _jacobian(scene, a, s, h):
    """dS/da of the block-diagonal frozen map by forward differences, one query per channel index:
    its diagonal blocks (m x m, one per subsystem)."""
    n, blocks = len(a), [np.zeros((m, m)) for m in scene.sizes]
    for j in range(max(scene.sizes)):
        da = np.zeros(n)
        da[[off + j for off, m in zip(scene.offsets, scene.sizes) if j < m]] = h
        ds = (np.array(scene.S(list(a + da))) - s) / h
        for J, off, m in zip(blocks, scene.offsets, scene.sizes):
            if j < m:
                J[:, j] = ds[off:off + m]
    return blocks


def newton_matrix(blocks, P, offsets, sizes):
    """I - J_S P as sparse rows ({column: value}) for the block-diagonal J_S: entry (i, j) sums
    J_S[i, k] P[k, j] from 0.0 over k ascending in i's block (P's stored entries), then is subtracted
    from the identity's (the diagonal always stored)."""
    rows = []
    for J, off, m in zip(blocks, offsets, sizes):
        for r in range(m):
            acc = {}
            for k in range(m):
                for j, v in zip(*P.rows[off + k]):
                    acc[j] = acc.get(j, 0.0) + float(J[r, k]) * v
            i = off + r
            row = {j: (1.0 if j == i else 0.0) - x for j, x in acc.items()}
            row.setdefault(i, 1.0 - 0.0)
            rows.append(row)
    return rows


def solve_interface(scene, P, b0, tol=TOL, max_iter=MAX_ITER, where=""):
    """Newton on F(b) = b - S^n(P b) at the frozen x^n (P a linalg.Sparse); returns (b*, iterations,
    |F(b*)|, S-evaluations)."""
    b = [float(x) for x in b0]
    evals, best, stalled = 0, None, 0
    for it in range(max_iter + 1):
        a = matvec(P, b)
        s = scene.S(a)
        evals += 1
        res = distance(b, s)
        if not np.isfinite(res):
            raise failed(where, NON_FINITE, nan_source(scene.subsystems, nan_channel(a, s)))
        stalled = stalled + 1 if best is not None and res > 0.5 * best[1] else 0
        if best is None or res < best[1]:
            best = (b, res, _wave_scale(a, b))
        if res <= tol * (1.0 + norm2(b)) or it == max_iter or _stalled(best, stalled):
            break
        a = np.array(a)
        J_S = _jacobian(scene, a, np.array(s), 1e-7 * (1.0 + float(np.abs(a).max())))
        evals += max(scene.sizes)
        step = solve_sparse(newton_matrix(J_S, P, scene.offsets, scene.sizes), [-(bi - si) for bi, si in zip(b, s)])
        if step is None:
            raise failed(where, SINGULAR)
        b = [bi + di for bi, di in zip(b, step)]
    b, res, scale = best
    if res > ACCEPT * (1.0 + norm2(b)) and res > ACCEPT_REL * scale:
        raise not_converged(where, res, scale)
    return np.array(b), it, res, evals


def _wave_scale(a, b):
    """|a| + |b|: the size of the waves the residual is measured against."""
    return norm2(a) + norm2(b)


def _stalled(best, stalled):
    """Newton sits at the FMUs' noise floor: STALL steps without halving, past the absolute level
    but within the relative one (so it is accepted)."""
    b, res, scale = best
    return stalled >= STALL and ACCEPT * (1.0 + norm2(b)) < res <= ACCEPT_REL * scale
