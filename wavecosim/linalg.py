"""Small dense vector arithmetic in a fixed operation order, shared by the Python reference path
and mirrored line by line in the C fast path (fmus/kernel), so both give bit-identical numbers."""
import math


def matvec(M, x):
    """y_i = sum_j M_ij x_j, summed left to right from 0.0."""
    y = []
    for row in M:
        acc = 0.0
        for mij, xj in zip(row, x):
            acc += mij * xj
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


def dot(x, y):
    """sum_j x_j y_j, left to right from 0.0."""
    acc = 0.0
    for xj, yj in zip(x, y):
        acc += xj * yj
    return acc


def norm1(x):
    """sum_j |x_j|, left to right from 0.0."""
    acc = 0.0
    for xj in x:
        acc += abs(xj)
    return acc
