/* The arithmetic of wavecosim/kernel/linalg.py in C, in the same operation order (sums from 0.0, left to
 * right), shared by the DR kernel and the wave adapter (compiled with -ffp-contract=off). */
#ifndef WAVECOSIM_LINALG_H
#define WAVECOSIM_LINALG_H

#include <math.h>
#include <stddef.h>

/* A function on the path of every step, always inlined (GCC, Clang): the constants of its callers,
 * such as a port of one channel, fold into it. */
#define WC_INLINE static inline __attribute__((always_inline))

/* to = from, n doubles: a loop, not a call of memcpy, as the vectors of a step are a few values long. */
static inline void copy_doubles(double *to, const double *from, size_t n) {
    for (size_t j = 0; j < n; j++) to[j] = from[j];
}

/* y_i = sum_j M_ij x_j (M n x n, row-major; linalg.matvec). */
static inline void matvec(const double *M, const double *x, double *y, size_t n) {
    for (size_t i = 0; i < n; i++) {
        double acc = 0.0;
        for (size_t j = 0; j < n; j++) acc += M[i * n + j] * x[j];
        y[i] = acc;
    }
}

/* |x - y|, squares summed (linalg.distance). */
static inline double distance(const double *x, const double *y, size_t n) {
    double acc = 0.0;
    for (size_t j = 0; j < n; j++) {
        double d = x[j] - y[j];
        acc += d * d;
    }
    return sqrt(acc);
}

/* sum_j x_j y_j (linalg.dot). */
static inline double dot(const double *x, const double *y, size_t n) {
    double acc = 0.0;
    for (size_t j = 0; j < n; j++) acc += x[j] * y[j];
    return acc;
}

/* sum_j |x_j| (linalg.norm1). */
static inline double norm1(const double *x, size_t n) {
    double acc = 0.0;
    for (size_t j = 0; j < n; j++) acc += fabs(x[j]);
    return acc;
}

#endif
