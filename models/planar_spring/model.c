/* Teaches: a nonlinear vector port. The average-vector-field (AVF) discrete gradient of a
 * non-quadratic potential gives H' - H = h e . f - damping h |f|^2 exactly, and its Jacobian is
 * symmetric, so the port is reciprocal. State (x, y); a damped 2x2 Newton solves the step. */
#include <math.h>
#include <stdio.h>

#include "model.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)m; (void)msg; (void)n;
    return 0;
}

double model_energy(const ModelData *m) {
    const double *r = m->r;
    double x = r[VR_x], y = r[VR_y], rr = x * x + y * y;
    return 0.5 * r[VR_kx] * x * x + r[VR_kxy] * x * y + 0.5 * r[VR_ky] * y * y + 0.25 * r[VR_kn] * rr * rr;
}

typedef struct {
    const double *r;
    double h, p0[2], c[2], s[2];
} StepCtx;

/* AVF discrete gradient of V between p0 and p1: K (p0 + p1)/2 for the quadratic part, and
 * Simpson's rule (exact for the cubic integrand) for grad(kn r^4/4) = kn |p|^2 p. */
static void discrete_gradient(const StepCtx *x, const double p1[2], double g[2], double jac[2][2]) {
    const double *r = x->r;
    double pm[2] = {0.5 * (x->p0[0] + p1[0]), 0.5 * (x->p0[1] + p1[1])};
    double r0 = x->p0[0] * x->p0[0] + x->p0[1] * x->p0[1];
    double rm = pm[0] * pm[0] + pm[1] * pm[1];
    double r1 = p1[0] * p1[0] + p1[1] * p1[1];
    double kn = r[VR_kn];
    g[0] = r[VR_kx] * pm[0] + r[VR_kxy] * pm[1];
    g[1] = r[VR_kxy] * pm[0] + r[VR_ky] * pm[1];
    for (int i = 0; i < 2; i++) g[i] += kn * (r0 * x->p0[i] + 4.0 * rm * pm[i] + r1 * p1[i]) / 6.0;
    /* d g / d p1 = K/2 + kn (Hess(pm)/3 + Hess(p1)/6), Hess(q) = |q|^2 I + 2 q q^T: symmetric. */
    double K[2][2] = {{r[VR_kx], r[VR_kxy]}, {r[VR_kxy], r[VR_ky]}};
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 2; j++)
            jac[i][j] = 0.5 * K[i][j] + kn * ((i == j ? rm / 3.0 + r1 / 6.0 : 0.0) + 2.0 * pm[i] * pm[j] / 3.0 +
                                              p1[i] * p1[j] / 3.0);
}

/* Stage effort e(f) = grad_d V(p0, p0 + h f) + damping f and the closure residual f - c + s e. */
static void residual(const StepCtx *x, const double f[2], double e[2], double res[2], double dres[2][2]) {
    double p1[2] = {x->p0[0] + x->h * f[0], x->p0[1] + x->h * f[1]};
    double g[2], jac[2][2];
    discrete_gradient(x, p1, g, jac);
    for (int i = 0; i < 2; i++) {
        e[i] = g[i] + x->r[VR_damping] * f[i];
        res[i] = f[i] - x->c[i] + x->s[i] * e[i];
        for (int j = 0; j < 2; j++)
            dres[i][j] = (i == j) + x->s[i] * (x->h * jac[i][j] + (i == j) * x->r[VR_damping]);
    }
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    double *r = m->r;
    if (!(r[VR_kn] >= 0.0 && r[VR_damping] >= 0.0 && r[VR_kx] >= 0.0 && r[VR_ky] >= 0.0 &&
          r[VR_kx] * r[VR_ky] >= r[VR_kxy] * r[VR_kxy])) {
        snprintf(msg, n, "PlanarSpring needs kx, ky, kn, damping >= 0 and kxy^2 <= kx ky (a convex potential)");
        return 1;
    }
    StepCtx x = {r, h, {r[VR_x], r[VR_y]}, {p->c[0], p->c[1]}, {p->s[0], p->s[1]}};
    double fk[2] = {0.0, 0.0}, ek[2], res[2], J[2][2];
    double scale = fabs(p->c[0]) + fabs(p->c[1]) + 1e-300;
    int max_iter = m->i[VRI_newton_max_iter], converged = 0;
    residual(&x, fk, ek, res, J);
    for (int it = 0; it < max_iter && !converged; it++) {
        /* Newton direction from the 2x2 Jacobian (nonsingular: I + S M, S >= 0 diagonal, M SPD). */
        double det = J[0][0] * J[1][1] - J[0][1] * J[1][0];
        double d[2] = {-(J[1][1] * res[0] - J[0][1] * res[1]) / det, -(J[0][0] * res[1] - J[1][0] * res[0]) / det};
        double norm0 = res[0] * res[0] + res[1] * res[1];
        double lambda = 1.0, trial[2], e1[2], r1[2], J1[2][2];
        for (;;) { /* backtrack on |res|^2; the Newton direction is a descent direction */
            trial[0] = fk[0] + lambda * d[0];
            trial[1] = fk[1] + lambda * d[1];
            residual(&x, trial, e1, r1, J1);
            if (r1[0] * r1[0] + r1[1] * r1[1] <= (1.0 - 1e-4 * lambda) * norm0 || lambda < 1e-6) break;
            lambda *= 0.5;
        }
        double step = lambda * fmax(fabs(d[0]), fabs(d[1]));
        if (!isfinite(step)) break;
        converged = step <= r[VR_newton_rtol] * (scale + fmax(fabs(trial[0]), fabs(trial[1])));
        fk[0] = trial[0]; fk[1] = trial[1];
        ek[0] = e1[0]; ek[1] = e1[1];
        res[0] = r1[0]; res[1] = r1[1];
        J[0][0] = J1[0][0]; J[0][1] = J1[0][1]; J[1][0] = J1[1][0]; J[1][1] = J1[1][1];
    }
    if (!converged) {
        snprintf(msg, n, "Newton step of PlanarSpring did not converge in %d iterations (x = %.6g, y = %.6g)",
                 max_iter, r[VR_x], r[VR_y]);
        return 1;
    }
    r[VR_x] += h * fk[0];
    r[VR_y] += h * fk[1];
    e[0] = ek[0]; e[1] = ek[1];
    f[0] = fk[0]; f[1] = fk[1];
    return 0;
}
