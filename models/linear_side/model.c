/* Linear side (subsystem B): state (q2, v2), H = m2 v2^2/2 + k2 q2^2/2. The implicit midpoint
 * step with the port closure F = c - s f, f = -vbar, is linear in vbar and solved in closed form. */
#include "model.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)m; (void)msg; (void)n;
    return 0;
}

double model_energy(const ModelData *m) {
    const double *r = m->r;
    return 0.5 * r[VR_m2] * r[VR_v2] * r[VR_v2] + 0.5 * r[VR_k2] * r[VR_q2] * r[VR_q2];
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    (void)msg; (void)n;
    double *r = m->r;
    double m2 = r[VR_m2], k2 = r[VR_k2], c = p->c[0], s = p->s[0];
    /* m2 (v2' - v2)/h = -k2 (q2 + h vbar/2) - c2 vbar - F, v2' = 2 vbar - v2, F = c + s vbar */
    double vbar = (2.0 * m2 * r[VR_v2] / h - k2 * r[VR_q2] - c) / (2.0 * m2 / h + 0.5 * k2 * h + r[VR_c2] + s);
    r[VR_q2] += h * vbar;
    r[VR_v2] = 2.0 * vbar - r[VR_v2];
    e[0] = c + s * vbar;
    f[0] = -vbar;
    return 0;
}
