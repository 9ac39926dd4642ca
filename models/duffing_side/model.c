/* Duffing side (subsystem A): state (q1, v1, d), H = m1 v1^2/2 + k1 q1^2/2 + knl q1^4/4 + k12 d^2/2.
 * Discrete gradient: midpoint for quadratic terms, exact difference quotient for the quartic.
 * The step reduces to one monotone scalar equation in the displacement increment delta. */
#include <math.h>
#include <stdio.h>

#include "model.h"
#include "newton.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)m; (void)msg; (void)n;
    return 0;
}

double model_energy(const ModelData *m) {
    const double *r = m->r;
    double q = r[VR_q1];
    return 0.5 * r[VR_m1] * r[VR_v1] * r[VR_v1] + 0.5 * r[VR_k1] * q * q + 0.25 * r[VR_knl] * q * q * q * q +
           0.5 * r[VR_k12] * r[VR_d] * r[VR_d];
}

typedef struct {
    const double *r;
    double h, c, s, kappa;
} StepCtx;

/* Coupling force at the stage for a given mean velocity: from u = c - s e and
 * e = k12 dbar + c12 (u - vbar) with dbar = d0 + h (u - vbar) / 2. */
static double stage_effort(const StepCtx *x, double vbar) {
    return (x->r[VR_k12] * x->r[VR_d] + x->kappa * (x->c - vbar)) / (1.0 + x->kappa * x->s);
}

/* Momentum balance m1 (v1' - v1)/h = -k1 qbar - DQ - c1 vbar + e, as a function of delta = q1' - q1. */
static double momentum_residual(double delta, void *ctx, double *dg) {
    const StepCtx *x = ctx;
    const double *r = x->r;
    double h = x->h, q0 = r[VR_q1], q1 = q0 + delta, vbar = delta / h;
    double dq = 0.25 * r[VR_knl] * (q0 * q0 * q0 + q0 * q0 * q1 + q0 * q1 * q1 + q1 * q1 * q1);
    double ddq = 0.25 * r[VR_knl] * (q0 * q0 + 2.0 * q0 * q1 + 3.0 * q1 * q1);
    *dg = 2.0 * r[VR_m1] / (h * h) + 0.5 * r[VR_k1] + ddq + r[VR_c1] / h + x->kappa / (h * (1.0 + x->kappa * x->s));
    return 2.0 * r[VR_m1] * (vbar - r[VR_v1]) / h + r[VR_k1] * (q0 + 0.5 * delta) + dq + r[VR_c1] * vbar -
           stage_effort(x, vbar);
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    double *r = m->r;
    StepCtx x = {r, h, p->c[0], p->s[0], 0.5 * r[VR_k12] * h + r[VR_c12]};
    double delta = h * r[VR_v1];
    double scale = fabs(r[VR_q1]) + h * fabs(r[VR_v1]) + 1e-300;
    int it = newton_increasing(momentum_residual, &x, &delta, scale, r[VR_newton_rtol], 1e-300,
                               m->i[VRI_newton_max_iter]);
    if (it < 0) {
        snprintf(msg, n, "Newton step of the Duffing side did not converge in %d iterations (q1 = %.6g, v1 = %.6g)",
                 m->i[VRI_newton_max_iter], r[VR_q1], r[VR_v1]);
        return 1;
    }
    double vbar = delta / h;
    double force = stage_effort(&x, vbar);
    double u = x.c - x.s * force;
    r[VR_q1] += delta;
    r[VR_v1] = 2.0 * vbar - r[VR_v1];
    r[VR_d] += h * (u - vbar);
    e[0] = force;
    f[0] = u;
    return 0;
}
