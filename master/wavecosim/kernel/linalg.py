"""Small vector arithmetic in a fixed operation order, shared by the Python reference path and
mirrored line by line in the C kernel (kernel/c), so both give bit-identical numbers.

The coupling maps P and J_L are stored sparse (`Sparse`, compressed rows with the columns of each
row ascending): a row's sum over its stored entries, left to right from 0.0, has the same bits as
the dense sum over every column, because adding an exact zero to a running sum that started at
+0.0 changes nothing (the sum is never -0.0; only a NaN or inf in a skipped column would differ).
"""
import math

import numpy as np


class Sparse:
    """A square matrix in compressed rows: row i holds col[start[i]:start[i+1]] (ascending) and val;
    np.asarray(M) gives the dense matrix (built once, for the few callers that need it)."""

    def __init__(self, n, start, col, val):
        self.n = n
        self.start = np.ascontiguousarray(start, dtype=np.int32)
        self.col = np.ascontiguousarray(col, dtype=np.int32)
        self.val = np.ascontiguousarray(val, dtype=np.float64)
        cols, vals = self.col.tolist(), self.val.tolist()
        bounds = self.start.tolist()
        self.rows = [(cols[a:b], vals[a:b]) for a, b in zip(bounds, bounds[1:])]
        self._dense = None

    @classmethod
    def from_dense(cls, M):
        """The nonzero entries of a dense square matrix, row by row, columns ascending."""
        M = np.asarray(M, dtype=np.float64)
        rows, cols = np.nonzero(M)
        start = np.searchsorted(rows, np.arange(M.shape[0] + 1))
        return cls(M.shape[0], start, cols, M[rows, cols])

    @property
    def nnz(self):
        return len(self.val)

    @property
    def shape(self):
        return (self.n, self.n)

    def __array__(self, dtype=None, copy=None):
        if self._dense is None:
            self._dense = np.zeros((self.n, self.n))
            rows = np.repeat(np.arange(self.n), np.diff(self.start))
            self._dense[rows, self.col] = self.val
            self._dense.flags.writeable = False
        return self._dense if dtype is None else self._dense.astype(dtype)

    def tolist(self):
        """Dense rows as lists (for printing and old callers)."""
        return np.asarray(self).tolist()


def matvec(M, x):
    """y_i = sum_j M_ij x_j, summed left to right from 0.0 over row i's stored entries (a Sparse
    M) or over every column (dense rows)."""
    y = []
    if isinstance(M, Sparse):
        for cols, vals in M.rows:
            acc = 0.0
            for c, v in zip(cols, vals):
                acc += v * x[c]
            y.append(acc)
        return y
    for row in M:
        acc = 0.0
        for mij, xj in zip(row, x):
            acc += mij * xj
        y.append(acc)
    return y


def matvec_rows(M, x, r0, r1):
    """Rows r0 .. r1 - 1 of matvec(M, x) for a Sparse M, in the same order."""
    y = []
    for cols, vals in M.rows[r0:r1]:
        acc = 0.0
        for c, v in zip(cols, vals):
            acc += v * x[c]
        y.append(acc)
    return y


def distance(x, y):
    """|x - y|, squares summed left to right."""
    acc = 0.0
    for xi, yi in zip(x, y):
        d = xi - yi
        acc += d * d
    return math.sqrt(acc)


def inverse(M):
    """M^-1 by Gauss-Jordan elimination with partial pivoting (the first row of largest |pivot|),
    each row divided by its pivot, then eliminated from the others left to right; a zero pivot
    gives NaN everywhere. For a 1 x 1 matrix it is 1.0 / M[0][0], as LAPACK's."""
    n = len(M)
    A = [[float(x) for x in row] + [1.0 if i == j else 0.0 for j in range(n)] for i, row in enumerate(M)]
    for col in range(n):
        p = col
        for r in range(col + 1, n):
            if abs(A[r][col]) > abs(A[p][col]):
                p = r
        if A[p][col] == 0.0:
            return [[math.nan] * n for _ in range(n)]
        A[col], A[p] = A[p], A[col]
        pivot = A[col][col]
        A[col] = [x / pivot for x in A[col]]
        for r in range(n):
            if r != col:
                factor = A[r][col]
                A[r] = [x - factor * y for x, y in zip(A[r], A[col])]
    return [row[n:] for row in A]


def solve_sparse(rows, b):
    """solve() on a sparse A given as rows ({column: value} each, absent entries zero), with the same
    operations on the entries it stores: the same pivots (the first row of largest |A[r, c]|, a NaN
    first), the same multipliers, each stored entry of a row updated once per step as there, fill-in
    starting from 0.0; rows with a zero multiplier and absent entries are skipped, where solve()
    subtracts exact zeros (which changes no value, at most the sign of a zero in x). The work follows
    the nonzeros (a chain's banded Newton matrix: linear in n). Returns x as a list, or None when a
    pivot is zero (kernel/c/newton.c's lu_sparse mirrors it)."""
    n = len(b)
    A, x = [dict(row) for row in rows], [float(v) for v in b]
    where = [set() for _ in range(n)]                 # column -> the rows holding an entry there
    for r, row in enumerate(A):
        for j in row:
            where[j].add(r)
    for c in range(n):
        p, best = c, abs(A[c].get(c, 0.0))
        for r in sorted(r for r in where[c] if r > c) if best == best else ():
            v = abs(A[r][c])
            if v != v or v > best:
                p, best = r, v
                if v != v:
                    break
        if A[p].get(c, 0.0) == 0.0:
            return None
        if p != c:
            _swap_rows(A, x, where, c, p)
        inv = 1.0 / A[c][c]
        pivot = [(j, v) for j, v in A[c].items() if j > c]
        for r in where[c]:
            ell = A[r][c] * inv if r > c else 0.0
            if ell != 0.0:                            # a zero multiplier leaves its row as it is
                row = A[r]
                for j, v in pivot:
                    if j not in row:
                        row[j] = 0.0
                        where[j].add(r)
                    row[j] -= ell * v
                x[r] -= ell * x[c]
    for c in range(n - 1, -1, -1):
        x[c] /= A[c][c]
        for r in where[c]:
            if r < c:
                x[r] -= A[r][c] * x[c]
    return x


def solve_columns(A, B):
    """X with A X = B, solve() on each column of B (one factorization's operations per column); None
    when A is singular. The coupling's compiled maps use it, so their bits are the same on every CPU."""
    B = np.asarray(B, dtype=np.float64)
    columns = [solve(A, B[:, j]) for j in range(B.shape[1])]
    if any(c is None for c in columns):
        return None
    return np.column_stack(columns) if columns else np.zeros(B.shape)


def least_squares(V, b, rcond=1e-12):
    """x minimizing |V x - b| by modified Gram-Schmidt over V's columns in order, sums left to right;
    a column whose part outside the earlier ones is at most rcond times the largest column norm is
    left out (its x is 0), as a rank-revealing solve drops it. The same bits on every CPU, where
    LAPACK's least squares takes its CPU's kernels."""
    V = np.asarray(V, dtype=np.float64)
    cols = [V[:, j].tolist() for j in range(V.shape[1])]
    scale = max((norm2(c) for c in cols), default=0.0)
    Q, R, kept = [], {}, []
    for j, v in enumerate(cols):
        for i, q in zip(kept, Q):
            R[i, j] = dot(q, v)
            v = [vk - R[i, j] * qk for vk, qk in zip(v, q)]
        length = norm2(v)
        if length > rcond * scale:
            R[j, j] = length
            Q.append([vk / length for vk in v])
            kept.append(j)
    x = [0.0] * len(cols)
    for idx in range(len(kept) - 1, -1, -1):
        j, acc = kept[idx], dot(Q[idx], b)
        for later in kept[idx + 1:]:
            acc -= R[j, later] * x[later]
        x[j] = acc / R[j, j]
    return np.array(x)


def _swap_rows(A, x, where, c, p):
    """Rows c and p of A (and x) exchanged, with the column index following."""
    for j in set(A[c]) | set(A[p]):
        has_c, has_p = c in where[j], p in where[j]
        if has_c != has_p:
            where[j].discard(c if has_c else p)
            where[j].add(p if has_c else c)
    A[c], A[p] = A[p], A[c]
    x[c], x[p] = x[p], x[c]


def dot(x, y):
    """sum_j x_j y_j, left to right from 0.0."""
    acc = 0.0
    for xj, yj in zip(x, y):
        acc += xj * yj
    return acc


def total(x):
    """sum_j x_j, left to right from 0.0 (the builtin sum() adds with compensation from Python 3.12 on;
    the kernel's C and the blocks' numpy passes add left to right)."""
    acc = 0.0
    for xj in x:
        acc += xj
    return acc


def norm1(x):
    """sum_j |x_j|, left to right from 0.0."""
    acc = 0.0
    for xj in x:
        acc += abs(xj)
    return acc


def norm2(x):
    """|x|, squares summed left to right."""
    acc = 0.0
    for xj in x:
        acc += xj * xj
    return math.sqrt(acc)


def solve(A, b):
    """x with A x = b by LU with partial pivoting (the first row of largest |pivot|), as LAPACK's
    dgesv: multipliers times the pivot's reciprocal, rows updated and b reduced column by column,
    then back substitution dividing by the pivots. A row whose multiplier is zero is not updated (for finite entries that
    is what subtracting zero gives: A never holds -0.0), so a banded A costs O(n^2 band).
    Elementwise numpy operations only (no sums), so kernel/c/newton.c's loops give the same
    bits on every CPU (numpy's BLAS and LAPACK pick their kernels by CPU). None when a pivot is zero
    (A singular)."""
    A, x = np.array(A, dtype=np.float64), np.array(b, dtype=np.float64)
    n = len(x)
    for c in range(n):
        p = c + int(np.argmax(np.abs(A[c:, c])))
        if A[p, c] == 0.0:
            return None
        if p != c:
            A[[c, p]], x[[c, p]] = A[[p, c]], x[[p, c]]
        ell = A[c + 1:, c] * (1.0 / A[c, c])
        rows = np.flatnonzero(ell)                    # a zero multiplier leaves its row as it is
        A[c + 1 + rows, c + 1:] -= ell[rows, None] * A[c, c + 1:]
        x[c + 1:] -= ell * x[c]
    for c in range(n - 1, -1, -1):
        x[c] /= A[c, c]
        x[:c] -= A[:c, c] * x[c]
    return x
