/* Teaches: domain-crossing coupling lives in the master. This rotational load has an ordinary
 * torque/speed port; the motor constant is an ideal gyrator (orthogonal in waves) between it and
 * RLCCircuit. State (theta, omega), H = J omega^2/2 + stiffness theta^2/2; closed-form midpoint. */
#include "model.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)m; (void)msg; (void)n;
    return 0;
}

double model_energy(const ModelData *m) {
    const double *r = m->r;
    return 0.5 * r[VR_J] * r[VR_omega] * r[VR_omega] + 0.5 * r[VR_stiffness] * r[VR_theta] * r[VR_theta];
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    (void)msg; (void)n;
    double *r = m->r;
    double J = r[VR_J], k = r[VR_stiffness];
    /* J (w' - w)/h = tau - friction wbar - k (theta + h wbar/2), w' = 2 wbar - w, tau = c - s wbar */
    double wbar = (2.0 * J * r[VR_omega] / h - k * r[VR_theta] + p->c[0]) /
                  (2.0 * J / h + r[VR_friction] + 0.5 * k * h + p->s[0]);
    r[VR_theta] += h * wbar;
    r[VR_omega] = 2.0 * wbar - r[VR_omega];
    f[0] = wbar;
    e[0] = p->c[0] - p->s[0] * wbar;
    return 0;
}
