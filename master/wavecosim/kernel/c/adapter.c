/* The wave adapter in C (see adapter.h). Each function names the method of
 * wavecosim/core/ports.py::WaveAdapter it mirrors; sums run from 0.0, left to right, as there. */
#include <math.h>
#include <string.h>

#include "adapter.h"
#include "fmicall.h"
#include "linalg.h"
#include "abi.h"

/* The scratch vectors of one query, carved out of w->work. */
typedef struct {
    double *target, *u_new, *y_new, *r, *s, *du, *dy, *best_u, *best_y, *miss, *aug;
} Scratch;

MIRRORED(WaveAdapterC)
MIRRORED(FmiFailure)

size_t adapter_work_size(int m) {
    return 10 * (size_t)m + 2 * (size_t)m * (size_t)m;
}

WC_INLINE Scratch scratch(WaveAdapterC *w) {
    size_t m = (size_t)w->m;
    double *p = w->work;
    Scratch s = {p, p + m, p + 2 * m, p + 3 * m, p + 4 * m, p + 5 * m, p + 6 * m, p + 7 * m, p + 8 * m,
                 p + 9 * m, p + 10 * m};
    return s;
}

/* ---- wavecosim/kernel/linalg.py (the rest is linalg.h) ---- */

/* linalg.inverse on the augmented n x 2n matrix A = [M | I]: its right half becomes M^-1;
 * returns 0 when a pivot is zero (the reference's NaN matrix). */
static int gauss_jordan(double *A, size_t n) {
    size_t w = 2 * n;
    for (size_t col = 0; col < n; col++) {
        size_t p = col;
        for (size_t r = col + 1; r < n; r++)
            if (fabs(A[r * w + col]) > fabs(A[p * w + col])) p = r;
        if (A[p * w + col] == 0.0) return 0;
        for (size_t j = 0; j < w; j++) {
            double t = A[col * w + j];
            A[col * w + j] = A[p * w + j];
            A[p * w + j] = t;
        }
        double pivot = A[col * w + col];
        for (size_t j = 0; j < w; j++) A[col * w + j] = A[col * w + j] / pivot;
        for (size_t r = 0; r < n; r++) {
            if (r == col) continue;
            double factor = A[r * w + col];
            for (size_t j = 0; j < w; j++) A[r * w + j] = A[r * w + j] - factor * A[col * w + j];
        }
    }
    return 1;
}

/* ---- WaveAdapter ---- */

/* A failed FMU call (fmicall.h recorded it in w->failed) is the query's failure. */
static int fmu_failed(WaveAdapterC *w) {
    w->failure = AD_FMU;
    return 1;
}

/* _eval -> Subsystem.raw_query: restore x_i^n if moved, set u, one doStep, read y. */
WC_INLINE int eval(WaveAdapterC *w, size_t m, const double *u, double *y, double t, double h) {
    w->do_steps++;
    if (*w->dirty && fmi_set_state(w->fn.setFMUstate, w->fn.calls, w->comp, *w->state, &w->failed))
        return fmu_failed(w);
    *w->dirty = 1;
    if (fmi_set_real(w->fn.setReal, w->fn.calls, w->comp, w->in_vr, m, u, &w->failed)) return fmu_failed(w);
    if (fmi_do_step(w->fn.doStep, w->fn.calls, w->comp, t, h, w->no_prior, &w->failed)) return fmu_failed(w);
    return fmi_get_real(w->fn.getReal, w->fn.calls, w->comp, w->out_vr, m, y, &w->failed) ? fmu_failed(w) : 0;
}

/* _residual: wu u + wy y - target. */
WC_INLINE void residual(const WaveAdapterC *w, size_t m, const double *u, const double *y, const double *target,
                        double *r) {
    for (size_t j = 0; j < m; j++) r[j] = w->wu[j] * u[j] + w->wy[j] * y[j] - target[j];
}

static fmi2Status fail(WaveAdapterC *w, int failure, double rel, const double *r) {
    w->failure = failure;
    w->failed_rel = rel;
    memcpy(w->failed_r, r, (size_t)w->m * sizeof *r);
    return fmi2Error;
}

/* _invert: J_inv = (diag(wu) + diag(wy) D)^-1, or AD_SINGULAR when it is not finite. */
static fmi2Status invert(WaveAdapterC *w, size_t m, Scratch *s) {
    size_t n2 = 2 * m;
    int finite;
    if (m == 1) {                     /* gauss_jordan on [M | 1] is its one division by the pivot */
        double pivot = w->wu[0] + w->wy[0] * w->D[0];
        s->aug[1] = 1.0 / pivot;
        finite = pivot != 0.0 && isfinite(s->aug[1]);
    } else {
        for (size_t i = 0; i < m; i++)
            for (size_t j = 0; j < m; j++) {
                s->aug[i * n2 + j] = (i == j ? w->wu[i] : 0.0) + w->wy[i] * w->D[i * m + j];
                s->aug[i * n2 + m + j] = i == j ? 1.0 : 0.0;
            }
        finite = gauss_jordan(s->aug, m);
        for (size_t i = 0; finite && i < m; i++)
            for (size_t j = 0; j < m; j++) finite = finite && isfinite(s->aug[i * n2 + m + j]);
    }
    if (!finite) {
        for (size_t j = 0; j < m; j++) s->target[j] = 0.0;
        residual(w, m, w->u, w->y, s->target, s->r);
        return fail(w, AD_SINGULAR, NAN, s->r);
    }
    for (size_t i = 0; i < m; i++) copy_doubles(w->J_inv + i * m, s->aug + i * n2 + m, m);
    return fmi2OK;
}

fmi2Status adapter_reinvert(WaveAdapterC *w) {
    Scratch s = scratch(w);
    w->failure = AD_OK;
    return w->have_slope ? invert(w, (size_t)w->m, &s) : fmi2OK;
}

/* _estimate_slope: dy/du at the warm start by forward differences (m + 1 doSteps). */
static fmi2Status estimate_slope(WaveAdapterC *w, size_t m, Scratch *s, double t, double h) {
    if (eval(w, m, w->u, w->y, t, h)) return (fmi2Status)w->failed.status;
    for (size_t j = 0; j < m * m; j++) w->D[j] = 0.0;
    w->have_slope = 1;
    w->h2 = w->u_scale = 0.0;
    for (size_t j = 0; j < m; j++) {
        double scale = fabs(w->u[j]) + (fabs(s->target[j]) + fabs(w->wy[j] * w->y[j])) / fabs(w->wu[j]);
        scale = scale > 0 ? scale : 1.0;
        w->u_scale += scale;
        double step = w->slope_rel * scale;
        w->h2 += step * step;
        copy_doubles(s->du, w->u, m);
        s->du[j] += step;
        if (eval(w, m, s->du, s->y_new, t, h)) return (fmi2Status)w->failed.status;
        for (size_t i = 0; i < m; i++) w->D[i * m + j] = (s->y_new[i] - w->y[i]) / step;
    }
    return invert(w, m, s);
}

/* _secant: Broyden update of D from the step (du, dy), unless shorter than the slope's own. */
static fmi2Status secant(WaveAdapterC *w, size_t m, Scratch *s) {
    double du2 = dot(s->du, s->du, m);
    if (!(du2 >= w->h2)) return fmi2OK;
    matvec(w->D, s->du, s->miss, m);
    for (size_t i = 0; i < m; i++) s->miss[i] = s->dy[i] - s->miss[i];
    for (size_t i = 0; i < m; i++)
        for (size_t j = 0; j < m; j++) w->D[i * m + j] += s->miss[i] * s->du[j] / du2;
    return invert(w, m, s);
}

/* _relative: the residual relative to the terms it balances, or the next correction relative to
 * the input's scale: the smaller. Uses s->s as scratch. */
WC_INLINE double relative(const WaveAdapterC *w, size_t m, Scratch *s, const double *r, const double *u,
                          const double *y) {
    double size = 0.0;
    for (size_t j = 0; j < m; j++) size += fabs(s->target[j]) + fabs(w->wu[j] * u[j]) + fabs(w->wy[j] * y[j]);
    double norm = norm1(r, m);
    matvec(w->J_inv, r, s->s, m);
    double step = norm1(s->s, m) / w->u_scale;
    double ratio = size > 0 ? norm / size : (norm == 0 ? 0.0 : INFINITY);
    return step < ratio ? step : ratio;
}

/* stage and outgoing: oriented (e, f) of the FMU's u and y, and b = k (e - gamma f). */
WC_INLINE fmi2Status stage(WaveAdapterC *w, size_t m) {
    for (size_t j = 0; j < m; j++) {
        w->e[j] = w->effort_in[j] ? w->u[j] : w->y[j];
        w->f[j] = w->sign[j] * (w->effort_in[j] ? w->y[j] : w->u[j]);
        w->b[j] = w->k * (w->e[j] - w->gamma * w->f[j]);
    }
    return fmi2OK;
}

/* _accept: Newton stalled; the best point is kept when within accept (the FMU put there). */
static fmi2Status accept(WaveAdapterC *w, size_t m, Scratch *s, double best_rel, int best_is_last, double t,
                         double h) {
    if (best_rel > w->accept) return fail(w, AD_STALLED, best_rel, s->r);
    w->accepted++;
    w->worst_accepted = best_rel > w->worst_accepted ? best_rel : w->worst_accepted;
    if (!best_is_last) {
        if (eval(w, m, s->best_u, s->best_y, t, h)) return (fmi2Status)w->failed.status;
        copy_doubles(w->u, s->best_u, m);
        copy_doubles(w->y, s->best_y, m);
    }
    return stage(w, m);
}

/* One Newton iteration from (w->u, w->y): u_new, y_new, their residual r and its relative size. */
WC_INLINE int newton_step(WaveAdapterC *w, size_t m, Scratch *s, double *rel, double t, double h) {
    residual(w, m, w->u, w->y, s->target, s->r);
    matvec(w->J_inv, s->r, s->s, m);
    for (size_t j = 0; j < m; j++) s->u_new[j] = w->u[j] - s->s[j];
    if (eval(w, m, s->u_new, s->y_new, t, h)) return 1;
    residual(w, m, s->u_new, s->y_new, s->target, s->r);
    *rel = relative(w, m, s, s->r, s->u_new, s->y_new);
    return 0;
}

/* _solve, over m channels (adapter_solve) */
WC_INLINE fmi2Status solve(WaveAdapterC *w, size_t m, double t, double h) {
    Scratch s = scratch(w);
    w->failure = AD_OK;
    w->evaluations++;
    for (size_t j = 0; j < m; j++) s.target[j] = w->c * w->a[j];
    fmi2Status status;
    if (!w->have_slope && (status = estimate_slope(w, m, &s, t, h)) != fmi2OK) return status;
    double best_rel = NAN;
    int have_best = 0, stalled = 0, best_at = -1, last = -1;
    for (int it = 0; it < w->max_iter; it++) {
        double rel;
        if (newton_step(w, m, &s, &rel, t, h)) return (fmi2Status)w->failed.status;
        if (rel > w->tol) {
            for (size_t j = 0; j < m; j++) {
                s.du[j] = s.u_new[j] - w->u[j];
                s.dy[j] = s.y_new[j] - w->y[j];
            }
            if ((status = secant(w, m, &s)) != fmi2OK) return status;
        }
        copy_doubles(w->u, s.u_new, m);
        copy_doubles(w->y, s.y_new, m);
        last = it;
        if (rel <= w->tol) return stage(w, m);
        stalled = have_best && rel > 0.5 * best_rel ? stalled + 1 : 0;
        if (!have_best || rel < best_rel) {
            best_rel = rel;
            best_at = it;
            have_best = 1;
            copy_doubles(s.best_u, s.u_new, m);
            copy_doubles(s.best_y, s.y_new, m);
        }
        if (stalled >= w->stall) break;
    }
    return accept(w, m, &s, best_rel, best_at == last, t, h);
}

/* The adapter's solve for any m, and for the one-channel port most FMUs have: the same code, its
 * loops of one value folded by the compiler. */
fmi2Status adapter_solve(WaveAdapterC *w, double t, double h) {
    return w->m == 1 ? solve(w, 1, t, h) : solve(w, (size_t)w->m, t, h);
}

/* ---- the fmi2 shim ---- */

fmi2Status adapter_getFMUstate(fmi2Component c, fmi2FMUstate *state) {
    WaveAdapterC *w = c;
    w->failure = AD_OK;
    if (fmi_get_state(w->fn.getFMUstate, w->fn.calls, w->comp, state, &w->failed) && fmu_failed(w))
        return (fmi2Status)w->failed.status;
    w->state = state;
    *w->dirty = 0;            /* Subsystem.freeze */
    w->have_slope = 0;       /* WaveAdapter.new_step */
    return fmi2OK;
}

fmi2Status adapter_setFMUstate(fmi2Component c, fmi2FMUstate state) {
    WaveAdapterC *w = c;
    (void)state;             /* always w->state's: the next doStep restores it before its first doStep */
    *w->dirty = 1;
    return fmi2OK;
}

fmi2Status adapter_freeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    WaveAdapterC *w = c;
    return w->fn.freeFMUstate(w->comp, state);
}

fmi2Status adapter_setReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    WaveAdapterC *w = c;
    for (size_t j = 0; j < nvr; j++) {
        if (vr[j] >= (fmi2ValueReference)w->m) return fmi2Error;
        w->a[vr[j]] = value[j];
    }
    return fmi2OK;
}

fmi2Status adapter_doStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    (void)no_prior;          /* the FMU's doSteps pass w->no_prior: x_i^n (at t) is restored after them */
    return adapter_solve((WaveAdapterC *)c, t, h);
}

fmi2Status adapter_getReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    WaveAdapterC *w = c;
    for (size_t j = 0; j < nvr; j++) {
        if (vr[j] >= (fmi2ValueReference)w->m) return fmi2Error;
        value[j] = w->b[vr[j]];
    }
    return fmi2OK;
}
