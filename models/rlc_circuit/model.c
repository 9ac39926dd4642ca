/* Teaches: the same port algebra in a second physical domain. Voltage and current replace force
 * and velocity; coupled to DCMotorLoad through a gyrator (motor constant) in the master.
 * State (q_C, i_L), H = L i^2/2 + q^2/(2C); implicit midpoint in closed form. */
#include "model.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)m; (void)msg; (void)n;
    return 0;
}

double model_energy(const ModelData *m) {
    const double *r = m->r;
    return 0.5 * r[VR_L] * r[VR_i_L] * r[VR_i_L] + 0.5 * r[VR_q_C] * r[VR_q_C] / r[VR_C];
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    (void)msg; (void)n;
    double *r = m->r;
    double L = r[VR_L], C = r[VR_C];
    /* L (i' - i)/h = u - R ibar - (q + h ibar/2)/C, i' = 2 ibar - i, u = c - s f = c - s ibar */
    double ibar = (2.0 * L * r[VR_i_L] / h - r[VR_q_C] / C + p->c[0]) / (2.0 * L / h + r[VR_R] + 0.5 * h / C + p->s[0]);
    r[VR_q_C] += h * ibar;
    r[VR_i_L] = 2.0 * ibar - r[VR_i_L];
    f[0] = ibar;
    e[0] = p->c[0] - p->s[0] * ibar;
    return 0;
}
