/* The named options of the DR master in C: relaxation, safeguarded Anderson acceleration (with its
 * memory across macro-steps and the extrapolated b^*) and the warm start, each the mirror of
 * wavecosim/masters/dr_options.py operation by operation (sums from 0.0, left to right, history
 * oldest first), so the kernel stays bit-identical to the reference.
 * Included once, by drkernel.c (the build makes one library per .c file). */
#ifndef WAVECOSIM_DR_OPTIONS_H
#define WAVECOSIM_DR_OPTIONS_H

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "linalg.h"

#define DR_ANDERSON_MAX 16          /* dr_options.ANDERSON_MAX */
#define DR_ANDERSON_SAFEGUARD 0.9   /* dr_options.ANDERSON_SAFEGUARD */
#define DR_ANDERSON_REG 1e-12       /* dr_options.ANDERSON_REG */

typedef struct {
    double lambda;                 /* relaxation of line 12 (1.0: the paper's update) */
    int start_mode, have_prev;     /* u^{n,0} (DR_START_*) once b^{n-1} and a^{n-1} are known */
    int m, count, start;           /* Anderson window (0: off), differences kept, oldest slot */
    int have_acc, candidate;       /* an accepted iterate exists / the last iterate was accelerated */
    int memory, extrapolate;       /* keep the differences across steps / b^* the combined responses */
    size_t n;
    double *b_prev, *z;            /* b^{n-1}; scratch */
    double *dF, *dG, *dB;          /* m columns of n: differences of steps f, residuals g, responses b */
    double *f_acc, *g_acc, *b_acc, *g, *b_ext;
    double A[DR_ANDERSON_MAX * DR_ANDERSON_MAX], r[DR_ANDERSON_MAX];
} DROptions;

static void options_free(DROptions *o) {
    if (!o) return;
    free(o->b_prev);
    free(o);
}

/* Options for n channels; NULL on no memory. One block holds every vector. */
static DROptions *options_create(double lambda, int m, int start_mode, size_t n) {
    DROptions *o = calloc(1, sizeof *o);
    if (!o) return NULL;
    o->lambda = lambda;
    o->m = m;
    o->start_mode = start_mode;
    o->n = n;
    o->b_prev = calloc((7 + 3 * (size_t)m) * n, sizeof(double));
    if (!o->b_prev) {
        free(o);
        return NULL;
    }
    o->z = o->b_prev + n;
    o->f_acc = o->b_prev + 2 * n;
    o->g_acc = o->b_prev + 3 * n;
    o->b_acc = o->b_prev + 4 * n;
    o->g = o->b_prev + 5 * n;
    o->b_ext = o->b_prev + 6 * n;
    o->dF = o->b_prev + 7 * n;
    o->dG = o->dF + (size_t)m * n;
    o->dB = o->dG + (size_t)m * n;
    return o;
}

/* dr_options.solve: A x = r (p x p, row-major, overwritten; x in r), partial pivoting; -1 if singular. */
static int options_solve(double *A, double *r, int p) {
    for (int c = 0; c < p; c++) {
        int piv = c;
        for (int i = c + 1; i < p; i++)
            if (fabs(A[i * p + c]) > fabs(A[piv * p + c])) piv = i;
        if (A[piv * p + c] == 0.0) return -1;
        for (int j = 0; j < p; j++) {
            double t = A[c * p + j];
            A[c * p + j] = A[piv * p + j];
            A[piv * p + j] = t;
        }
        double t = r[c];
        r[c] = r[piv];
        r[piv] = t;
        for (int i = c + 1; i < p; i++) {
            double f = A[i * p + c] / A[c * p + c];
            for (int j = c; j < p; j++) A[i * p + j] -= f * A[c * p + j];
            r[i] -= f * r[c];
        }
    }
    for (int c = p - 1; c >= 0; c--) {
        double acc = r[c];
        for (int j = c + 1; j < p; j++) acc -= A[c * p + j] * r[j];
        r[c] = acc / A[c * p + c];
    }
    return 0;
}

/* Column i (0 = oldest) of a history. */
static double *options_col(const DROptions *o, double *base, int i) {
    return base + (size_t)((o->start + i) % o->m) * o->n;
}

/* dr_options.least_squares into o->r; -1 if degenerate. */
static int options_least_squares(DROptions *o) {
    int p = o->count;
    double top = 0.0;
    for (int i = 0; i < p; i++)
        for (int j = 0; j < p; j++)
            o->A[i * p + j] = dot(options_col(o, o->dG, i), options_col(o, o->dG, j), o->n);
    for (int i = 0; i < p; i++)
        if (i == 0 || o->A[i * p + i] > top) top = o->A[i * p + i];
    if (!(top > 0.0)) return -1;
    for (int i = 0; i < p; i++) o->A[i * p + i] += DR_ANDERSON_REG * top;
    for (int i = 0; i < p; i++) o->r[i] = dot(options_col(o, o->dG, i), o->g, o->n);
    if (options_solve(o->A, o->r, p)) return -1;
    for (int i = 0; i < p; i++)
        if (!isfinite(o->r[i])) return -1;
    return 0;
}

/* Append g - g_acc, f - f_acc and b_hat - b_acc to the history (dropping the oldest when full). */
static void options_push(DROptions *o, const double *f, const double *b_hat) {
    if (o->count == o->m) o->start = (o->start + 1) % o->m;
    else o->count++;
    double *dg = options_col(o, o->dG, o->count - 1), *df = options_col(o, o->dF, o->count - 1);
    double *db = options_col(o, o->dB, o->count - 1);
    for (size_t j = 0; j < o->n; j++) {
        dg[j] = o->g[j] - o->g_acc[j];
        df[j] = f[j] - o->f_acc[j];
        db[j] = b_hat[j] - o->b_acc[j];
    }
}

/* out[j] = x[j] - sum_i r_i cols_i[j] over the history (dr_options._combine), in place allowed. */
static void options_combine(const DROptions *o, double *base, const double *x, double *out) {
    for (size_t j = 0; j < o->n; j++) {
        double acc = 0.0;
        for (int i = 0; i < o->count; i++) acc += o->r[i] * options_col(o, base, i)[j];
        out[j] = x[j] - acc;
    }
}

/* dr_options.Anderson.next: u the query point, f = T(u) (overwritten by the next iterate), b_hat its
 * response; *b_star becomes the response at the last accepted iterate, or at a rejected one whose
 * residual is still the smaller. */
static void options_anderson(DROptions *o, const double *u, double *f, const double *b_hat, const double **b_star) {
    size_t n = o->n;
    for (size_t j = 0; j < n; j++) o->g[j] = f[j] - u[j];
    double gg = dot(o->g, o->g, n), acc = o->have_acc ? dot(o->g_acc, o->g_acc, n) : 0.0;
    if (o->candidate && gg > DR_ANDERSON_SAFEGUARD * DR_ANDERSON_SAFEGUARD * acc) {
        o->count = o->start = o->candidate = 0;                  /* rejected: the plain step instead, */
        memcpy(f, o->f_acc, n * sizeof *f);
        *b_star = gg < acc ? b_hat : o->b_acc;                   /* b^* the response of smaller residual */
        return;
    }
    if (o->have_acc) options_push(o, f, b_hat);
    memcpy(o->f_acc, f, n * sizeof *f);
    memcpy(o->g_acc, o->g, n * sizeof *f);
    memcpy(o->b_acc, b_hat, n * sizeof *f);
    o->have_acc = 1;
    *b_star = o->b_acc;
    o->candidate = o->count > 0 && options_least_squares(o) == 0;
    if (!o->candidate) return;
    if (o->extrapolate) {
        options_combine(o, o->dB, b_hat, o->b_ext);
        *b_star = o->b_ext;
    }
    options_combine(o, o->dF, f, f);
}

#endif
