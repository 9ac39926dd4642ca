/* Teaches: a coupling element is a subsystem too. A spring-damper with two flow-input ends turns
 * mass-mass coupling into pairs of effort-in/flow-in ports; one tension serves both channels.
 * State delta, H = k delta^2/2; implicit midpoint in closed form. */
#include "model.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)m; (void)msg; (void)n;
    return 0;
}

double model_energy(const ModelData *m) {
    return 0.5 * m->r[VR_k] * m->r[VR_delta] * m->r[VR_delta];
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    (void)msg; (void)n;
    double *r = m->r;
    /* Elongation rate w = f_left + f_right with f_j = c_j - s_j T; the stage tension is
     * T = k (delta + h w/2) + c w, so T = (k delta + kappa (c0 + c1)) / (1 + kappa (s0 + s1)). */
    double kappa = 0.5 * r[VR_k] * h + r[VR_c];
    double tension = (r[VR_k] * r[VR_delta] + kappa * (p->c[0] + p->c[1])) / (1.0 + kappa * (p->s[0] + p->s[1]));
    f[0] = p->c[0] - p->s[0] * tension;
    f[1] = p->c[1] - p->s[1] * tension;
    r[VR_delta] += h * (f[0] + f[1]);
    e[0] = tension;
    e[1] = tension;
    return 0;
}
