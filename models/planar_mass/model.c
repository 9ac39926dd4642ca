/* Teaches: a vector port is just several channels. A planar point mass exchanges a force vector
 * for a velocity vector; each channel has its own wave pair and the power is the dot product.
 * State (x, y, vx, vy), H = m |v|^2/2; implicit midpoint, one closed form per channel. */
#include "model.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)m; (void)msg; (void)n;
    return 0;
}

double model_energy(const ModelData *m) {
    const double *r = m->r;
    return 0.5 * r[VR_m] * (r[VR_vx] * r[VR_vx] + r[VR_vy] * r[VR_vy]);
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    (void)msg; (void)n;
    double *r = m->r;
    const int pos[2] = {VR_x, VR_y}, vel[2] = {VR_vx, VR_vy};
    for (int j = 0; j < 2; j++) {
        /* m (v' - v)/h = -drag vbar - F, v' = 2 vbar - v, F = c - s f = c + s vbar */
        double v = r[vel[j]];
        double vbar = (2.0 * r[VR_m] * v / h - p->c[j]) / (2.0 * r[VR_m] / h + r[VR_drag] + p->s[j]);
        r[pos[j]] += h * vbar;
        r[vel[j]] = 2.0 * vbar - v;
        f[j] = -vbar;
        e[j] = p->c[j] - p->s[j] * f[j];
    }
    return 0;
}
