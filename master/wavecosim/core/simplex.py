"""Nelder-Mead simplex minimization, for the gamma search (gamma._search).

A few dozen lines of our own instead of scipy.optimize, whose import (linalg, sparse, special,
HiGHS, ...) costs more than a short run. It is the textbook method with the conventions of scipy's
minimize(method="Nelder-Mead") without bounds or adaptive parameters: the same trial points, made
by the same floating-point operations, the same termination tests and counting of evaluations, and
the simplex ordered by np.argsort, which is not stable: ties are common (the gamma search's
objective is flat outside its box) and their order decides the path. So the two give the same bits,
and the gammas chosen do not depend on which one ran.
"""
import numpy as np

REFLECT, EXPAND, CONTRACT, SHRINK = 1.0, 2.0, 0.5, 0.5


class _Spent(Exception):
    """The evaluation budget ran out in the middle of an iteration."""


def nelder_mead(f, simplex, xatol, fatol, maxfev):
    """(x, f(x), evaluations): minimize f from the (n + 1, n) `simplex` until the vertices lie within
    `xatol` of the best one (each coordinate) and their values within `fatol` of its value, or
    `maxfev` evaluations are spent (an iteration cut short keeps what it had changed)."""
    sim = np.array(simplex, dtype=float)
    fsim = np.full(len(sim), np.inf)
    spent = [0]

    def value(x):
        if spent[0] >= maxfev:
            raise _Spent
        spent[0] += 1
        return float(f(x.copy()))
    try:
        for k, x in enumerate(sim):
            fsim[k] = value(x)
    except _Spent:
        pass
    sim, fsim = _ordered(*_ordered(sim, fsim))      # sorted twice, as scipy does: argsort is not stable
    while spent[0] < maxfev:
        if np.max(np.abs(sim[1:] - sim[0])) <= xatol and np.max(np.abs(fsim[0] - fsim[1:])) <= fatol:
            break
        try:
            _iterate(value, sim, fsim)
        except _Spent:
            pass
        sim, fsim = _ordered(sim, fsim)
    return sim[0].copy(), float(np.min(fsim)), spent[0]


def _ordered(sim, fsim):
    """The simplex and its values, best vertex first."""
    order = np.argsort(fsim)
    return np.take(sim, order, 0), np.take(fsim, order, 0)


def _iterate(value, sim, fsim):
    """One Nelder-Mead iteration on the sorted simplex, in place: the worst vertex moves along the
    line through the centroid of the others (point(t) = (1 + t) centroid - t worst: reflection t = 1,
    expansion 2, outside contraction 0.5, inside contraction -0.5), or every vertex shrinks halfway
    towards the best one."""
    centroid = np.add.reduce(sim[:-1], 0) / (len(sim) - 1)

    def point(t):
        return (1.0 + t) * centroid - t * sim[-1]
    xr = point(REFLECT)
    fr = value(xr)
    if fr < fsim[0]:
        xe = point(REFLECT * EXPAND)
        fe = value(xe)
        sim[-1], fsim[-1] = (xe, fe) if fe < fr else (xr, fr)
    elif fr < fsim[-2]:
        sim[-1], fsim[-1] = xr, fr
    else:
        outside = fr < fsim[-1]
        xc = point(CONTRACT * REFLECT if outside else -CONTRACT)
        fc = value(xc)
        if (fc <= fr) if outside else (fc < fsim[-1]):
            sim[-1], fsim[-1] = xc, fc
        else:
            for j in range(1, len(sim)):
                sim[j] = sim[0] + SHRINK * (sim[j] - sim[0])
                fsim[j] = value(sim[j])
