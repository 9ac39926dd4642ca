/* Teaches: the smallest chain link. One mass with two force ports shows how port signs make
 * e f the power into the subsystem on both sides, so N links and SpringDampers chain losslessly.
 * State (q, v), H = m v^2/2 + k q^2/2; implicit midpoint in closed form. */
#include "model.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)m; (void)msg; (void)n;
    return 0;
}

double model_energy(const ModelData *m) {
    const double *r = m->r;
    return 0.5 * r[VR_m] * r[VR_v] * r[VR_v] + 0.5 * r[VR_k] * r[VR_q] * r[VR_q];
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    (void)msg; (void)n;
    double *r = m->r;
    double mass = r[VR_m], k = r[VR_k];
    /* m (v' - v)/h = -k (q + h vbar/2) - c vbar - F_left + F_right, v' = 2 vbar - v, with the held
     * inputs F_left = c0 - s0 f_left = c0 + s0 vbar and F_right = c1 - s1 f_right = c1 - s1 vbar. */
    double vbar = (2.0 * mass * r[VR_v] / h - k * r[VR_q] - p->c[0] + p->c[1]) /
                  (2.0 * mass / h + 0.5 * k * h + r[VR_c] + p->s[0] + p->s[1]);
    r[VR_q] += h * vbar;
    r[VR_v] = 2.0 * vbar - r[VR_v];
    f[0] = -vbar;
    f[1] = vbar;
    e[0] = p->c[0] - p->s[0] * f[0];
    e[1] = p->c[1] - p->s[1] * f[1];
    return 0;
}
