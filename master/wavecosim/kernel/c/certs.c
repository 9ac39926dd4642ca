/* The sampled certificates in the DR kernel's block loop (certs.h): the arithmetic of
 * wavecosim/core/certificates.py (fne_margins, augmented_residual's Fejer term) and of
 * wavecosim/run/observers/fne_watch.py (trace_margins), operation by operation (sums from 0.0, left to
 * right; compiled with -ffp-contract=off). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "certs.h"
#include "kernel_internal.h"
#include "abi.h"

struct DCCerts {
    DRKernel *k, *q;               /* the master's kernel; the certificates' own (FMU calls, counts) */
    NTKernel *nt;                  /* u*'s Newton on q */
    DCSettings set;
    DRStep qio;                    /* q's step: t, dt and its failures */
    size_t n;
    int n_sub, n0, rc, failed_sub;
    const double *normals;         /* armed: the sampled steps' normals, in order */
    const double *gammas;          /* armed: each subsystem's gamma (the probe) */
    fmi2ValueReference *stage_vr;  /* the probe: effort and flow of each subsystem */
    double *rows;                  /* armed: one row per step of the call */
    long used;                     /* normals used since dc_arm */
    double nt_out[2];
    double *b_star, *u_star, *centre, *xs, *ys, *X, *S;    /* n each; X and S: 2 pairs x max m */
};

DCCerts *dc_create(DRKernel *k, NTKernel *nt, DRKernel *q, const DCSettings *set, const fmi2ValueReference *stage_vr) {
    DCCerts *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    if (set->probe) {
        size_t count = 2 * (size_t)dr_subsystems(k);
        c->stage_vr = malloc(count * sizeof *c->stage_vr);
        if (!c->stage_vr) {
            free(c);
            return NULL;
        }
        memcpy(c->stage_vr, stage_vr, count * sizeof *stage_vr);
    }
    c->k = k, c->q = q, c->nt = nt, c->set = *set;
    c->n = dr_channels(k);
    c->n_sub = dr_subsystems(k);
    size_t pairs = set->pairs > 0 ? (size_t)set->pairs : 0;
    c->b_star = calloc(5 * c->n + 4 * pairs * c->n + 1, sizeof(double));
    if (!c->b_star) {
        free(c->stage_vr);
        free(c);
        return NULL;
    }
    c->u_star = c->b_star + c->n;
    c->centre = c->b_star + 2 * c->n;
    c->xs = c->b_star + 3 * c->n;
    c->ys = c->b_star + 4 * c->n;
    c->X = c->b_star + 5 * c->n;
    c->S = c->X + 2 * pairs * c->n;
    return c;
}

int dc_width(const DCCerts *c) { return 3 * c->n_sub + 1; }

/* |x| of m values, squares summed left to right (linalg.norm2). */
static double norm2(const double *x, size_t m) {
    double acc = 0.0;
    for (size_t j = 0; j < m; j++) acc += x[j] * x[j];
    return sqrt(acc);
}

/* 0.0 + x_0 y_0 + x_1 y_1 + ... (readings.row_dots of one row). */
static double row_dot(const double *x, const double *y, size_t m) {
    double acc = 0.0;
    for (size_t j = 0; j < m; j++) acc = acc + x[j] * y[j];
    return acc;
}

static int fail_fmu(DCCerts *c, int i) {
    dr_fail(c->q, &c->qio, i);
    c->failed_sub = i;
    c->rc = -1;
    return -1;
}

/* certificates.fne_margins of subsystem i around centre (its channels), queried on q. */
static int fne_margin(DCCerts *c, int i, double t, double dt, double *worst_out) {
    size_t off, m, rows = 2 * (size_t)c->set.pairs;
    dr_span(c->q, i, &off, &m);
    double sigma = c->set.scale * (norm2(c->centre + off, m) + sqrt(dt));
    const double *N = c->normals + c->used;
    for (size_t r = 0; r < rows; r++) {
        for (size_t j = 0; j < m; j++) c->xs[off + j] = c->X[r * m + j] = c->centre[off + j] + sigma * N[r * m + j];
        if (dr_evaluate(c->q, i, c->xs, c->ys, t, dt, 0)) return fail_fmu(c, i);
        memcpy(c->S + r * m, c->ys + off, m * sizeof(double));
    }
    c->used += (long)(rows * m);
    double worst = INFINITY, dS[64], dx[64];
    for (size_t p = 0; p < rows; p += 2) {
        for (size_t j = 0; j < m; j++) {
            dS[j] = c->S[p * m + j] - c->S[(p + 1) * m + j];
            dx[j] = c->X[p * m + j] - c->X[(p + 1) * m + j];
        }
        double margin = (row_dot(dS, dx, m) - row_dot(dS, dS, m)) / row_dot(dx, dx, m);
        if (margin < worst) worst = margin;              /* Python's min(worst, margin) */
    }
    *worst_out = worst;
    return 0;
}

/* The watch's probe of subsystem i (one channel) around centre: core/gamma.py probe_port's dE, dF by
 * a forward difference of the stage effort and flow, then PortProbe.fne_margin at its gamma:
 * J = (dE - g dF) / (dE + g dF) and 0.5 (J + J) - J J. */
static int probe_margin(DCCerts *c, int i, double t, double dt, double *margin) {
    size_t off, m;
    dr_span(c->q, i, &off, &m);
    const fmi2ValueReference *vr = c->stage_vr + 2 * i;
    double ef0[2], ef1[2];
    c->xs[off] = c->centre[off];
    if (dr_evaluate(c->q, i, c->xs, c->ys, t, dt, 0) || dr_read(c->q, i, vr, 2, ef0)) return fail_fmu(c, i);
    double h = c->set.probe_rel * (fabs(c->centre[off]) + fabs(c->ys[off]));
    if (h == 0.0) h = c->set.probe_rel * sqrt(dt);                  /* Python's `or` */
    c->xs[off] = c->centre[off] + h;
    if (dr_evaluate(c->q, i, c->xs, c->ys, t, dt, 0) || dr_read(c->q, i, vr, 2, ef1)) return fail_fmu(c, i);
    double dE = (ef1[0] - ef0[0]) / h, dF = (ef1[1] - ef0[1]) / h, g = c->gammas[i];
    double J = (dE - g * dF) / (dE + g * dF);
    *margin = 0.5 * (J + J) - J * J;
    return 0;
}

/* Before step n at x^n: u* and the FNE margins when n is sampled; the subsystems left at x^n. */
static int before(void *ctx, DRStep *io, int n) {
    DCCerts *c = ctx;
    double *row = c->rows + (size_t)(n - c->n0) * (size_t)dc_width(c);
    for (int j = 0; j < dc_width(c); j++) row[j] = j <= 2 * c->n_sub ? NAN : 0.0;    /* no pair kept yet */
    if (n % c->set.every || (!c->set.augmented && c->set.pairs <= 0 && !c->set.probe)) return 0;
    c->qio.t = io->t, c->qio.dt = io->dt;
    const double *b_n = dr_outputs(c->k);
    if (c->set.probe) {
        dr_begin(c->q, &c->qio);
        nt_apply_map(c->nt, b_n, c->centre);
        for (int i = 0; i < c->n_sub; i++) {
            if (probe_margin(c, i, io->t, io->dt, row + c->n_sub + 1 + i) || dr_thaw(c->q, i)) return fail_fmu(c, i);
            row[2 * c->n_sub + 1 + i] = 1.0;
        }
    }
    if (c->set.augmented) {
        int rc = nt_solve(c->nt, &c->qio, b_n, c->b_star, c->nt_out);
        if (rc) {
            c->rc = rc;
            c->failed_sub = c->qio.failed_subsystem;
            return -1;
        }
        nt_apply_map(c->nt, c->b_star, c->u_star);
    } else {
        dr_begin(c->q, &c->qio);
    }
    if (c->set.pairs <= 0) return 0;
    nt_apply_map(c->nt, b_n, c->centre);
    for (int i = 0; i < c->n_sub; i++)
        if (fne_margin(c, i, io->t, io->dt, row + i)) return -1;
    for (int i = 0; i < c->n_sub; i++)
        if (dr_thaw(c->q, i)) return fail_fmu(c, i);
    return 0;
}

/* Python's x ** 2: libm's pow, called (the compiler would make x * x of pow(x, 2.0), which can
 * differ from it in the last bit). */
static double (*volatile libm_pow)(double, double) = pow;
static double square(double x) { return libm_pow(x, 2.0); }

/* np.abs(x).max() of m values (a NaN wins). */
static double abs_max(const double *x, size_t m) {
    double best = fabs(x[0]);
    for (size_t j = 1; j < m && !isnan(best); j++) {
        double v = fabs(x[j]);
        if (isnan(v) || v > best) best = v;
    }
    return best;
}

/* One pair (k - 1, k) of the trace for subsystem i: its margin into worst (a NaN wins) when kept. */
static void watch_pair(DCCerts *c, const double *trace, int k, size_t off, size_t m, double *worst, int *any) {
    size_t n = c->n;
    double da[64], ds[64];
    const double *U = trace + 2 * n * (size_t)(k - 1) + off, *B = U + n, *U1 = U + 2 * n, *B1 = U1 + n;
    for (size_t j = 0; j < m; j++) da[j] = U1[j] - U[j], ds[j] = B1[j] - B[j];
    double size = abs_max(U, m) + abs_max(B, m), dd = row_dot(da, da, m), norm = sqrt(dd);
    if (!(norm > 0.0 && norm > c->set.floor * size)) return;
    double v = (row_dot(ds, da, m) - row_dot(ds, ds, m)) / dd;
    if (!*any || (!isnan(*worst) && (isnan(v) || v < *worst))) *worst = v;
    *any = 1;
}

/* fne_watch.trace_margins of subsystem i over the pairs at pair_indices(count): 1, 2, 3, 4, 6, 9, ...
 * and count - 1 (np.min: a NaN wins); NaN and kept = 0 when no pair is kept. */
static void watch_margin(DCCerts *c, const double *trace, int count, int i, double *margin, double *kept) {
    size_t off, m;
    dr_span(c->k, i, &off, &m);
    double worst = NAN;
    int any = 0, k = 1, last = 0;
    for (; k < count; k = k + 1 > (3 * k) / 2 ? k + 1 : (3 * k) / 2) {
        watch_pair(c, trace, k, off, m, &worst, &any);
        last = k;
    }
    if (count >= 2 && last != count - 1) watch_pair(c, trace, count - 1, off, m, &worst, &any);
    *margin = any ? worst : NAN;
    *kept = any;
}

/* After step n (and the ledger's redo): the Fejer term when sampled; the watch every step. */
static int after(void *ctx, DRStep *io, int n) {
    DCCerts *c = ctx;
    double *row = c->rows + (size_t)(n - c->n0) * (size_t)dc_width(c);
    double *u0, *uK, *trace;
    int capacity;
    dr_iterates(c->k, &u0, &uK, &trace, &capacity);
    if (c->set.augmented && n % c->set.every == 0) {
        double dK = dr_distance(uK, c->u_star, c->n), d0 = dr_distance(u0, c->u_star, c->n);
        row[c->n_sub] = 0.5 * square(dK) - 0.5 * square(d0);
    }
    if (c->set.watch && trace) {
        int count = io->iterations < capacity ? io->iterations : capacity;
        for (int i = 0; i < c->n_sub; i++)
            watch_margin(c, trace, count, i, row + c->n_sub + 1 + i, row + 2 * c->n_sub + 1 + i);
    }
    return 0;
}

void dc_arm(DCCerts *c, int n0, const double *normals, double *rows, const double *gammas) {
    if (!rows) {                                   /* disarm: the status of the call stays readable */
        dr_set_hooks(c->k, NULL, NULL, NULL);
        return;
    }
    c->n0 = n0, c->normals = normals, c->rows = rows, c->gammas = gammas, c->used = 0, c->rc = 0, c->failed_sub = -1;
    dr_set_hooks(c->k, before, after, c);
}

int dc_status(const DCCerts *c, int *failed, double *out, long *normals_used) {
    failed[0] = c->failed_sub, failed[1] = c->qio.failed_function, failed[2] = c->qio.failed_status;
    out[0] = c->qio.residual, out[1] = c->nt_out[1];
    *normals_used = c->used;
    return c->rc;
}

void dc_destroy(DCCerts *c) {
    if (!c) return;
    dr_set_hooks(c->k, NULL, NULL, NULL);
    free(c->b_star);
    free(c->stage_vr);
    free(c);
}

MIRRORED(DCSettings)
