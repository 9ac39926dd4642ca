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
