/* Teaches: one FMU per mass still needs no spring FMUs, if each link owns the spring on its right.
 * Its two channels have opposite causality (effort in on the left, flow in on the right), which is
 * what lets equal_effort_opposite_flow join neighbours directly. State (q, v, d),
 * H = m v^2/2 + k0 q^2/2 + k d^2/2; implicit midpoint (the discrete gradient of a quadratic H)
 * in closed form, as in DuffingSide without the quartic term. */
#include "model.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)m; (void)msg; (void)n;
    return 0;
}

double model_energy(const ModelData *m) {
    const double *r = m->r;
    return 0.5 * r[VR_m] * r[VR_v] * r[VR_v] + 0.5 * r[VR_k0] * r[VR_q] * r[VR_q] +
           0.5 * r[VR_k] * r[VR_d] * r[VR_d];
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    (void)msg; (void)n;
    double *r = m->r;
    double mass = r[VR_m], k0 = r[VR_k0];
    /* Held inputs: F_left = c0 - s0 f_left = c0 + s0 vbar, u = c1 - s1 T. The spring tension at
     * the stage is T = k (d + h (u - vbar)/2) + c (u - vbar) = k d + kap (u - vbar); with the
     * closure of u, T = (k d + kap (c1 - vbar)) / D, D = 1 + kap s1. The momentum balance
     * 2 m (vbar - v)/h = -k0 (q + h vbar/2) - c0 vbar - F_left + T is then linear in vbar. */
    double kap = 0.5 * r[VR_k] * h + r[VR_c], D = 1.0 + kap * p->s[1];
    double vbar = (2.0 * mass * r[VR_v] / h - k0 * r[VR_q] - p->c[0] + (r[VR_k] * r[VR_d] + kap * p->c[1]) / D) /
                  (2.0 * mass / h + 0.5 * k0 * h + r[VR_c0] + p->s[0] + kap / D);
    double T = (r[VR_k] * r[VR_d] + kap * (p->c[1] - vbar)) / D;
    double u = p->c[1] - p->s[1] * T;
    r[VR_q] += h * vbar;
    r[VR_v] = 2.0 * vbar - r[VR_v];
    r[VR_d] += h * (u - vbar);
    f[0] = -vbar;
    e[0] = p->c[0] - p->s[0] * f[0];
    e[1] = T;
    f[1] = u;
    return 0;
}
