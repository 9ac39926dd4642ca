/* Teaches: a large subsystem behind a one-channel port. n masses with hardening springs take one
 * discrete-gradient step per doStep, solved by full Newton with a tridiagonal Jacobian; the
 * master sees only (a, b) or (F, f), so its cost does not grow with n. */
#include <math.h>
#include <stdio.h>

#include "model.h"

#define NMAX HEAVY_CHAIN_MAX_N

static int valid_n(const ModelData *m) { return m->i[VRI_n] >= 1 && m->i[VRI_n] <= NMAX; }

static double spring_energy(const double *r, double d) {
    return 0.5 * r[VR_k] * d * d + 0.25 * r[VR_kn] * d * d * d * d;
}

/* Elongation of spring j: q_{j+1} - q_j, and the wall spring n-1: 0 - q_{n-1}. */
static double elongation(const double *q, int j, int n) { return (j < n - 1 ? q[j + 1] : 0.0) - q[j]; }

int model_initialize(ModelData *m, char *msg, size_t msg_size) {
    if (!valid_n(m)) {
        snprintf(msg, msg_size, "parameter n must be between 1 and %d, got %d", NMAX, m->i[VRI_n]);
        return 1;
    }
    int n = m->i[VRI_n];
    double centre = 0.5 * (n - 1), width = n >= 20 ? n / 20.0 : 1.0;
    for (int i = 0; i < NMAX; i++) {
        double z = (i - centre) / width;
        m->q[i] = i < n ? m->r[VR_amplitude] * exp(-z * z) : 0.0;
        m->v[i] = 0.0;
    }
    m->r[VR_q_first] = m->q[0];
    m->r[VR_q_last] = m->q[n - 1];
    return 0;
}

/* NaN for an invalid n (initialization refuses it first; a state restored from elsewhere might not). */
double model_energy(const ModelData *m) {
    if (!valid_n(m)) return NAN;
    const double *r = m->r;
    int n = m->i[VRI_n];
    double H = 0.0;
    for (int i = 0; i < n; i++) H += 0.5 * r[VR_m] * m->v[i] * m->v[i] + spring_energy(r, elongation(m->q, i, n));
    return H;
}

typedef struct {
    const ModelData *md;
    double h, c, s; /* port closure: F = c - s f = c + s vbar_0 */
    int n;
} StepCtx;

/* Momentum residuals R_i(u), u_i = q_i' - q_i, of m (v_i' - v_i)/h = DG_i - DG_{i-1} - c vbar_i
 * (- F on mass 0), with the discrete gradient DG_j = [V(d_j') - V(d_j)] / (d_j' - d_j) of spring j.
 * If diag/off are given, also the symmetric tridiagonal Jacobian dR/du. Returns |R|^2. */
static double residual(const StepCtx *x, const double *u, double *R, double *diag, double *off) {
    const double *r = x->md->r, *q = x->md->q, *v = x->md->v;
    double h = x->h, k = r[VR_k], kn = r[VR_kn], inertia = 2.0 * r[VR_m] / (h * h) + r[VR_c] / h;
    int n = x->n;
    double dg_prev = 0.0, D_prev = 0.0, norm = 0.0;
    for (int i = 0; i < n; i++) {
        double d0 = elongation(q, i, n);
        double d1 = d0 + (i < n - 1 ? u[i + 1] : 0.0) - u[i];
        double dg = 0.5 * k * (d0 + d1) + 0.25 * kn * (d0 * d0 * d0 + d0 * d0 * d1 + d0 * d1 * d1 + d1 * d1 * d1);
        double D = 0.5 * k + 0.25 * kn * (d0 * d0 + 2.0 * d0 * d1 + 3.0 * d1 * d1); /* d DG / d d1 >= 0 */
        R[i] = 2.0 * r[VR_m] * (u[i] / h - v[i]) / h + r[VR_c] * u[i] / h - (dg - dg_prev);
        if (diag) {
            diag[i] = inertia + D + D_prev;
            if (i < n - 1) off[i] = -D;
        }
        dg_prev = dg;
        D_prev = D;
    }
    R[0] += x->c + x->s * u[0] / h;
    if (diag) diag[0] += x->s / h;
    for (int i = 0; i < n; i++) norm += R[i] * R[i];
    return norm;
}

/* Solves the symmetric positive definite tridiagonal system (diag, off) d = -R (Thomas). */
static void solve_tridiagonal(int n, const double *diag, const double *off, const double *R, double *d, double *w) {
    double piv = diag[0];
    d[0] = -R[0] / piv;
    for (int i = 1; i < n; i++) {
        w[i - 1] = off[i - 1] / piv;
        piv = diag[i] - off[i - 1] * w[i - 1];
        d[i] = (-R[i] - off[i - 1] * d[i - 1]) / piv;
    }
    for (int i = n - 2; i >= 0; i--) d[i] -= w[i] * d[i + 1];
}

int model_step(ModelData *md, double h, const PortClosure *p, double *e, double *f, char *msg, size_t msg_size) {
    if (!valid_n(md)) {
        snprintf(msg, msg_size, "HeavyChain needs 1 <= n <= %d, got n = %d", NMAX, md->i[VRI_n]);
        return 1;
    }
    double *r = md->r;
    int n = md->i[VRI_n];
    StepCtx x = {md, h, p->c[0], p->s[0], n};
    double u[NMAX], trial[NMAX], R[NMAX], diag[NMAX], off[NMAX], d[NMAX], w[NMAX];
    double scale = 1e-300;
    for (int i = 0; i < n; i++) {
        u[i] = h * md->v[i];
        scale = fmax(scale, fabs(md->q[i]) + h * fabs(md->v[i]));
    }
    int sweeps = md->i[VRI_newton_sweeps], max_iter = md->i[VRI_newton_max_iter];
    if (max_iter < sweeps) max_iter = sweeps;
    int converged = 0;
    double norm = residual(&x, u, R, diag, off);
    for (int it = 1; it <= max_iter; it++) {
        solve_tridiagonal(n, diag, off, R, d, w);
        double dmax = 0.0, umax = 0.0;
        for (int i = 0; i < n; i++) {
            dmax = fmax(dmax, fabs(d[i]));
            umax = fmax(umax, fabs(u[i]));
        }
        if (!isfinite(dmax)) break;
        double tol = r[VR_newton_rtol] * (scale + umax);
        /* Far from the solution, backtrack on |R|^2 (the Newton direction descends); once the
         * step is at the tolerance, take it whole. */
        double lambda = 1.0, trial_norm;
        for (;;) {
            for (int i = 0; i < n; i++) trial[i] = u[i] + lambda * d[i];
            trial_norm = residual(&x, trial, R, diag, off);
            if (dmax <= tol || trial_norm <= (1.0 - 1e-4 * lambda) * norm || lambda < 1e-6) break;
            lambda *= 0.5;
        }
        for (int i = 0; i < n; i++) u[i] = trial[i];
        norm = trial_norm;
        if (lambda * dmax <= tol) converged = 1;
        if (converged && it >= sweeps) break;
    }
    if (!converged || !isfinite(norm)) {
        snprintf(msg, msg_size, "Newton step of HeavyChain did not converge in %d iterations (|R| = %.3g)",
                 max_iter, sqrt(norm));
        return 1;
    }
    for (int i = 0; i < n; i++) {
        double vbar = u[i] / h;
        md->q[i] += u[i];
        md->v[i] = 2.0 * vbar - md->v[i];
    }
    f[0] = -u[0] / h;
    e[0] = p->c[0] - p->s[0] * f[0];
    r[VR_q_first] = md->q[0];
    r[VR_q_last] = md->q[n - 1];
    return 0;
}
