/* The newton master on the kernel route: wavecosim/masters/monolithic.py's solve_interface and the commit
 * of wavecosim/masters/newton.py, with the FMUs in wave port mode, evaluated by drkernel.c's
 * subsystem evaluation (kernel_internal.h). The arithmetic follows the Python reference operation
 * by operation (a = P b by linalg.matvec, norms and residual summed left to right, the forward
 * difference Jacobian, I - J_S P by monolithic.newton_matrix, the LU solve of linalg.solve), so
 * the numbers are bit-identical. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kernel_internal.h"
#include "newton.h"
#include "abi.h"

struct NTKernel {
    DRKernel *k;
    Csr *P;
    NTSettings set;
    size_t n;
    int max_m;                     /* the largest subsystem's channel count */
    double *b, *best_b, *a, *s, *ap, *sp, *x;    /* scratch, n each */
    double *J, *M;                 /* n x n: the Jacobian of S, the Newton matrix I - J_S P */
};

NTKernel *nt_create(DRKernel *k, const int *P_start, const int *P_col, const double *P_val, const NTSettings *set) {
    NTKernel *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    size_t n = dr_channels(k);
    c->k = k;
    c->n = n;
    c->set = *set;
    for (int i = 0; i < dr_subsystems(k); i++) {
        size_t off, m;
        dr_span(k, i, &off, &m);
        if ((int)m > c->max_m) c->max_m = (int)m;
    }
    c->P = dr_csr_copy(P_start, P_col, P_val, n);
    c->b = calloc(7 * n, sizeof(double));
    c->J = calloc(2 * n * n + 1, sizeof(double));
    if (!c->P || !c->b || !c->J) {
        nt_destroy(c);
        return NULL;
    }
    c->best_b = c->b + n;
    c->a = c->b + 2 * n;
    c->s = c->b + 3 * n;
    c->ap = c->b + 4 * n;
    c->sp = c->b + 5 * n;
    c->x = c->b + 6 * n;
    c->M = c->J + n * n;
    return c;
}

int nt_set_map(NTKernel *c, const int *P_start, const int *P_col, const double *P_val) {
    Csr *P = dr_csr_copy(P_start, P_col, P_val, c->n);
    if (!P) return -1;
    free(c->P);
    c->P = P;
    return 0;
}

/* S^n(a) into out, every subsystem from x_i^n (scene.S); the first failing subsystem, or -1. */
static int frozen_map(NTKernel *c, const double *a, double *out, double t, double h) {
    for (int i = 0; i < dr_subsystems(c->k); i++)
        if (dr_evaluate(c->k, i, a, out, t, h, 0)) return i;
    return -1;
}

/* |x| (linalg.norm2). */
static double norm2(const double *x, size_t n) {
    double acc = 0.0;
    for (size_t i = 0; i < n; i++) acc += x[i] * x[i];
    return sqrt(acc);
}

/* dS/da by forward differences (monolithic._jacobian): channel j of every subsystem perturbed at
 * once, one S-evaluation per j; J is zero outside the subsystem blocks. */
static int jacobian(NTKernel *c, double t, double h) {
    size_t n = c->n;
    double amax = 0.0;
    for (size_t i = 0; i < n; i++)
        if (fabs(c->a[i]) > amax) amax = fabs(c->a[i]);
    double d = 1e-7 * (1.0 + amax);
    memset(c->J, 0, n * n * sizeof(double));
    for (int j = 0; j < c->max_m; j++) {
        for (int i = 0; i < dr_subsystems(c->k); i++) {
            size_t off, m;
            dr_span(c->k, i, &off, &m);
            for (size_t r = 0; r < m; r++) c->ap[off + r] = c->a[off + r] + ((size_t)j == r ? d : 0.0);
        }
        int f = frozen_map(c, c->ap, c->sp, t, h);
        if (f >= 0) return f;
        for (int i = 0; i < dr_subsystems(c->k); i++) {
            size_t off, m;
            dr_span(c->k, i, &off, &m);
            if ((size_t)j >= m) continue;
            for (size_t r = 0; r < m; r++) c->J[(off + r) * n + off + j] = (c->sp[off + r] - c->s[off + r]) / d;
        }
    }
    return -1;
}

/* M = I - J_S P (monolithic.newton_matrix): entry (i, j) sums J[i][k] P[k][j] over k ascending in
 * i's subsystem block and P's stored entries, then is subtracted from the identity's. */
static void newton_matrix(NTKernel *c) {
    size_t n = c->n;
    const Csr *P = c->P;
    double *M = c->M;
    memset(M, 0, n * n * sizeof(double));
    for (int i = 0; i < dr_subsystems(c->k); i++) {
        size_t off, m;
        dr_span(c->k, i, &off, &m);
        for (size_t k = off; k < off + m; k++)
            for (int p = P->start[k]; p < P->start[k + 1]; p++)
                for (size_t r = off; r < off + m; r++) M[r * n + P->col[p]] += c->J[r * n + k] * P->val[p];
    }
    for (size_t r = 0; r < n; r++)
        for (size_t j = 0; j < n; j++) M[r * n + j] = (r == j ? 1.0 : 0.0) - M[r * n + j];
}

/* The first row at or below c of largest |A[r][c]| (numpy's argmax: a NaN counts as largest). */
static size_t pivot_row(const double *A, size_t n, size_t c) {
    size_t p = c;
    double best = fabs(A[c * n + c]);
    for (size_t r = c + 1; r < n && !isnan(best); r++) {
        double v = fabs(A[r * n + c]);
        if (isnan(v) || v > best) {
            p = r;
            best = v;
        }
    }
    return p;
}

static void swap_rows(double *A, double *x, size_t n, size_t r, size_t p) {
    if (r == p) return;
    for (size_t j = 0; j < n; j++) {
        double tmp = A[r * n + j];
        A[r * n + j] = A[p * n + j];
        A[p * n + j] = tmp;
    }
    double tmp = x[r];
    x[r] = x[p];
    x[p] = tmp;
}

/* x <- A^-1 x by LU with partial pivoting, in linalg.solve's operation order (A overwritten);
 * nonzero when a pivot is zero. */
static int lu_solve(double *A, double *x, size_t n) {
    for (size_t c = 0; c < n; c++) {
        size_t p = pivot_row(A, n, c);
        if (A[p * n + c] == 0.0) return 1;
        swap_rows(A, x, n, c, p);
        double inv = 1.0 / A[c * n + c];
        for (size_t r = c + 1; r < n; r++) {
            double ell = A[r * n + c] * inv;
            if (ell != 0.0)                         /* a zero multiplier leaves its row as it is */
                for (size_t j = c + 1; j < n; j++) A[r * n + j] -= ell * A[c * n + j];
            x[r] -= ell * x[c];
        }
    }
    for (size_t c = n; c-- > 0;) {
        x[c] /= A[c * n + c];
        for (size_t r = 0; r < c; r++) x[r] -= A[r * n + c] * x[c];
    }
    return 0;
}

/* The Newton loop of solve_interface from c->b; leaves b* in c->b and io->iterations, io->residual,
 * out[0] (S-evaluations) and out[1] (the wave scale of b*). Returns like nt_step. */
static int newton(NTKernel *c, DRStep *io, double *out) {
    size_t n = c->n;
    const NTSettings *set = &c->set;
    double best = INFINITY, scale = 0.0, t = io->t, h = io->dt;
    int evals = 0, stalled = 0, have_best = 0, it;
    for (it = 0; it <= set->max_iter; it++) {
        dr_csr_rows(c->P, c->b, c->a, 0, n);
        int f = frozen_map(c, c->a, c->s, t, h);
        if (f >= 0) return dr_fail(c->k, io, f);
        evals++;
        double res = dr_distance(c->b, c->s, n);
        if (!isfinite(res)) return NT_NONFINITE;
        stalled = have_best && res > 0.5 * best ? stalled + 1 : 0;
        if (!have_best || res < best) {
            memcpy(c->best_b, c->b, n * sizeof(double));
            best = res;
            scale = norm2(c->a, n) + norm2(c->b, n);
            have_best = 1;
        }
        double level = set->accept * (1.0 + norm2(c->best_b, n));
        int at_floor = stalled >= set->stall && level < best && best <= set->accept_rel * scale;
        if (res <= set->tol * (1.0 + norm2(c->b, n)) || it == set->max_iter || at_floor) break;
        f = jacobian(c, t, h);
        if (f >= 0) return dr_fail(c->k, io, f);
        evals += c->max_m;
        newton_matrix(c);
        for (size_t i = 0; i < n; i++) c->x[i] = -(c->b[i] - c->s[i]);
        if (lu_solve(c->M, c->x, n)) return NT_SINGULAR;
        for (size_t i = 0; i < n; i++) c->b[i] = c->b[i] + c->x[i];
    }
    memcpy(c->b, c->best_b, n * sizeof(double));
    io->iterations = it;
    io->residual = best;
    out[0] = evals;
    out[1] = scale;
    return best > set->accept * (1.0 + norm2(c->b, n)) && best > set->accept_rel * scale ? NT_NOT_CONVERGED : 0;
}

int nt_step(NTKernel *c, DRStep *io, const double *b_n, double *b_next, double *a_hat, double *out) {
    dr_begin(c->k, io);
    io->reason = DR_EXPLICIT;
    memcpy(c->b, b_n, c->n * sizeof(double));
    int rc = newton(c, io, out);
    if (rc) return rc;
    dr_csr_rows(c->P, c->b, a_hat, 0, c->n);                        /* a_hat = P b* */
    for (int i = 0; i < dr_subsystems(c->k); i++)                   /* the commit (eq. 21) */
        if (dr_evaluate(c->k, i, a_hat, b_next, io->t, io->dt, 1)) return dr_fail(c->k, io, i);
    return 0;
}

void nt_apply_map(const NTKernel *c, const double *x, double *y) { dr_csr_rows(c->P, x, y, 0, c->n); }

int nt_solve(NTKernel *c, DRStep *io, const double *b_n, double *b_star, double *out) {
    dr_begin(c->k, io);
    io->reason = DR_EXPLICIT;
    memcpy(c->b, b_n, c->n * sizeof(double));
    int rc = newton(c, io, out);
    memcpy(b_star, c->b, c->n * sizeof(double));
    for (int i = 0; i < dr_subsystems(c->k); i++)
        if (dr_thaw(c->k, i)) return rc ? rc : dr_fail(c->k, io, i);
    return rc;
}

void nt_destroy(NTKernel *c) {
    if (!c) return;
    free(c->P);
    free(c->b);
    free(c->J);
    free(c);
}

MIRRORED(NTSettings)
