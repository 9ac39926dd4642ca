/* The newton master on the kernel route: wavecosim/masters/monolithic.py's solve_interface and the commit
 * of wavecosim/masters/newton.py, with the FMUs in wave port mode, evaluated by drkernel.c's
 * subsystem evaluation (kernel_internal.h). The arithmetic follows the Python reference operation
 * by operation (a = P b by linalg.matvec, norms and residual summed left to right, the forward
 * difference Jacobian's blocks, I - J_S P by monolithic.newton_matrix as sparse rows, the sparse LU
 * of linalg.solve_sparse), so the numbers are bit-identical; the work follows the nonzeros. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kernel_internal.h"
#include "newton.h"
#include "abi.h"

/* One row of the sparse Newton matrix (entries in no order) and the rows holding a column. */
typedef struct {
    int *col;
    double *val;
    int len, cap;
} Row;

typedef struct {
    int *row;
    int len, cap;
} Col;

struct NTKernel {
    DRKernel *k;
    Csr *P;
    NTSettings set;
    size_t n;
    int max_m;                     /* the largest subsystem's channel count */
    double *b, *best_b, *a, *s, *ap, *sp, *x;    /* scratch, n each */
    double *J;                     /* the Jacobian's diagonal blocks, subsystem i's m x m at block[i] */
    size_t *block;
    Row *rows;                     /* the Newton matrix I - J_S P (n rows), reused between solves */
    Col *cols;                     /* n: which rows hold an entry of each column */
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
    size_t blocks = 0, room = n ? n : 1;
    c->block = calloc((size_t)dr_subsystems(k) + 1, sizeof(size_t));
    for (int i = 0; c->block && i < dr_subsystems(k); i++) {
        size_t off, m;
        dr_span(k, i, &off, &m);
        c->block[i] = blocks;
        blocks += m * m;
    }
    c->P = dr_csr_copy(P_start, P_col, P_val, n);
    c->b = calloc(7 * room, sizeof(double));
    c->J = calloc(blocks + 1, sizeof(double));
    c->rows = calloc(room, sizeof(Row));
    c->cols = calloc(room, sizeof(Col));
    if (!c->block || !c->P || !c->b || !c->J || !c->rows || !c->cols) {
        nt_destroy(c);
        return NULL;
    }
    c->best_b = c->b + n;
    c->a = c->b + 2 * n;
    c->s = c->b + 3 * n;
    c->ap = c->b + 4 * n;
    c->sp = c->b + 5 * n;
    c->x = c->b + 6 * n;
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
            for (size_t r = 0; r < m; r++) c->J[c->block[i] + r * m + (size_t)j] = (c->sp[off + r] - c->s[off + r]) / d;
        }
    }
    return -1;
}

/* ---- the sparse Newton matrix and its LU (linalg.solve_sparse) ---- */

/* Where column j sits in row R, or -1. */
static int find(const Row *R, int j) {
    for (int q = 0; q < R->len; q++)
        if (R->col[q] == j) return q;
    return -1;
}

/* A new entry (j, v) of row R (or a new row r of column C); nonzero when memory is short. */
static int append(Row *R, int j, double v) {
    if (R->len == R->cap) {
        int cap = R->cap ? 2 * R->cap : 8;
        int *col = realloc(R->col, (size_t)cap * sizeof(int));
        if (col) R->col = col;
        double *val = realloc(R->val, (size_t)cap * sizeof(double));
        if (val) R->val = val;
        if (!col || !val) return 1;
        R->cap = cap;
    }
    R->col[R->len] = j;
    R->val[R->len++] = v;
    return 0;
}

static int add_row(Col *C, int r) {
    if (C->len == C->cap) {
        int cap = C->cap ? 2 * C->cap : 8;
        int *row = realloc(C->row, (size_t)cap * sizeof(int));
        if (!row) return 1;
        C->row = row, C->cap = cap;
    }
    C->row[C->len++] = r;
    return 0;
}

/* M = I - J_S P (monolithic.newton_matrix): row i sums J_S[i][k] P[k][j] from 0.0 over k ascending in
 * i's block and P's stored entries, then subtracts it from the identity's; the diagonal is always
 * stored. The column index follows. Nonzero when memory is short. */
static int newton_matrix(NTKernel *c) {
    size_t n = c->n;
    const Csr *P = c->P;
    for (size_t j = 0; j < n; j++) c->rows[j].len = c->cols[j].len = 0;
    for (int i = 0; i < dr_subsystems(c->k); i++) {
        size_t off, m;
        dr_span(c->k, i, &off, &m);
        const double *J = c->J + c->block[i];
        for (size_t r = 0; r < m; r++) {
            Row *R = &c->rows[off + r];
            for (size_t k = 0; k < m; k++)
                for (int p = P->start[off + k]; p < P->start[off + k + 1]; p++) {
                    int q = find(R, P->col[p]);
                    if (q < 0 && append(R, P->col[p], 0.0)) return 1;
                    q = q < 0 ? R->len - 1 : q;
                    R->val[q] = R->val[q] + J[r * m + k] * P->val[p];
                }
            for (int q = 0; q < R->len; q++) R->val[q] = ((size_t)R->col[q] == off + r ? 1.0 : 0.0) - R->val[q];
            if (find(R, (int)(off + r)) < 0 && append(R, (int)(off + r), 1.0 - 0.0)) return 1;
        }
    }
    for (size_t r = 0; r < n; r++)
        for (int q = 0; q < c->rows[r].len; q++)
            if (add_row(&c->cols[c->rows[r].col[q]], (int)r)) return 1;
    return 0;
}

static double entry(const Row *R, int j) {
    int q = find(R, j);
    return q < 0 ? 0.0 : R->val[q];
}

/* Rows c and p exchanged (x too), the column index following. */
static void swap_rows(NTKernel *c, int r1, int r2) {
    for (int pass = 0; pass < 2; pass++) {
        const Row *R = &c->rows[pass ? r2 : r1], *other = &c->rows[pass ? r1 : r2];
        for (int q = 0; q < R->len; q++) {
            int j = R->col[q];
            if (find(other, j) >= 0) continue;               /* in both rows: its column keeps both */
            Col *C = &c->cols[j];
            for (int t = 0; t < C->len; t++)
                if (C->row[t] == (pass ? r2 : r1)) C->row[t] = pass ? r1 : r2;
        }
    }
    Row tmp = c->rows[r1];
    c->rows[r1] = c->rows[r2];
    c->rows[r2] = tmp;
    double x = c->x[r1];
    c->x[r1] = c->x[r2];
    c->x[r2] = x;
}

/* The pivot row of column col (linalg.solve_sparse): the first row at or below it of largest |A[r][col]|,
 * the first NaN before any number. */
static int pivot_row(const NTKernel *c, int col) {
    int p = col, nan_row = -1;
    double best = fabs(entry(&c->rows[col], col));
    if (isnan(best)) return col;
    const Col *C = &c->cols[col];
    for (int t = 0; t < C->len; t++) {
        int r = C->row[t];
        if (r <= col) continue;
        double v = fabs(entry(&c->rows[r], col));
        if (isnan(v)) {
            if (nan_row < 0 || r < nan_row) nan_row = r;
        } else if (v > best || (v == best && r < p && p != col)) {
            p = r;
            best = v;
        }
    }
    return nan_row >= 0 ? nan_row : p;
}

/* x <- M^-1 x by the sparse LU of linalg.solve_sparse (M overwritten): 0, NT_SINGULAR when a pivot is
 * zero, -2 when memory is short. */
static int lu_sparse(NTKernel *c) {
    int n = (int)c->n;
    double *x = c->x;
    for (int col = 0; col < n; col++) {
        int p = pivot_row(c, col);
        if (entry(&c->rows[p], col) == 0.0) return NT_SINGULAR;
        if (p != col) swap_rows(c, col, p);
        const Row *U = &c->rows[col];
        double inv = 1.0 / entry(U, col);
        const Col *C = &c->cols[col];
        for (int t = 0; t < C->len; t++) {
            int r = C->row[t];
            if (r <= col) continue;
            Row *R = &c->rows[r];
            double ell = entry(R, col) * inv;
            if (ell == 0.0) continue;                         /* a zero multiplier leaves its row as it is */
            U = &c->rows[col];
            for (int q = 0; q < U->len; q++) {
                int j = U->col[q];
                if (j <= col) continue;
                int at = find(R, j);
                if (at < 0) {                                  /* fill-in, from 0.0 */
                    if (append(R, j, 0.0) || add_row(&c->cols[j], r)) return -2;
                    at = R->len - 1;
                }
                R->val[at] -= ell * U->val[q];
            }
            x[r] -= ell * x[col];
        }
    }
    for (int col = n - 1; col >= 0; col--) {
        x[col] /= entry(&c->rows[col], col);
        const Col *C = &c->cols[col];
        for (int t = 0; t < C->len; t++)
            if (C->row[t] < col) x[C->row[t]] -= entry(&c->rows[C->row[t]], col) * x[col];
    }
    return 0;
}

/* newton.py's nan_channel: the first channel whose outgoing wave is not finite for a finite incident
 * one (the subsystem that made a NaN), else -1. */
static double nan_channel(const double *a, const double *s, size_t n) {
    for (size_t j = 0; j < n; j++)
        if (isfinite(a[j]) && !isfinite(s[j])) return (double)j;
    return -1.0;
}

/* The Newton loop of solve_interface from c->b; leaves b* in c->b and io->iterations, io->residual,
 * out[0] (S-evaluations) and out[1] (the wave scale of b*; after NT_NONFINITE, nan_channel). Returns
 * like nt_step. */
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
        if (!isfinite(res)) {
            out[1] = nan_channel(c->a, c->s, n);
            return NT_NONFINITE;
        }
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
        if (newton_matrix(c)) return NT_NO_MEMORY;
        for (size_t i = 0; i < n; i++) c->x[i] = -(c->b[i] - c->s[i]);
        int lu = lu_sparse(c);
        if (lu) return lu == NT_SINGULAR ? NT_SINGULAR : NT_NO_MEMORY;
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
    for (size_t j = 0; c->rows && c->cols && j < (c->n ? c->n : 1); j++) {
        free(c->rows[j].col);
        free(c->rows[j].val);
        free(c->cols[j].row);
    }
    free(c->rows);
    free(c->cols);
    free(c->block);
    free(c->P);
    free(c->b);
    free(c->J);
    free(c);
}

MIRRORED(NTSettings)
