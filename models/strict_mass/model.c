/* Strict mass: m v' = F - c v, x' = v, with F held over the communication step, integrated
 * exactly (an affine step map, so the wave adapter solves each query in one Newton step). */
#include <math.h>
#include <stdio.h>

#include "model.h"

int model_initialize(ModelData *md, char *msg, size_t n) {
    const double *r = md->r;
    if (!(r[VR_m] > 0.0)) { snprintf(msg, n, "m must be > 0, got %g", r[VR_m]); return 1; }
    if (!(r[VR_c] >= 0.0)) { snprintf(msg, n, "c must be >= 0, got %g", r[VR_c]); return 1; }
    if (!(r[VR_F_max] > 0.0)) { snprintf(msg, n, "F_max must be > 0, got %g", r[VR_F_max]); return 1; }
    return 0;
}

double model_energy(const ModelData *md) {
    return 0.5 * md->r[VR_m] * md->r[VR_v] * md->r[VR_v];
}

int model_step_io(ModelData *md, double h, char *msg, size_t n) {
    double *r = md->r;
    double m = r[VR_m], c = r[VR_c], F = r[VR_F], v = r[VR_v];
    if (fabs(F) > r[VR_F_max]) { snprintf(msg, n, "force F = %g beyond F_max = %g", F, r[VR_F_max]); return 1; }
    if (c == 0.0) {
        r[VR_x] += h * (v + 0.5 * h * F / m);
        r[VR_v] = v + h * F / m;
        return 0;
    }
    double tau = m / c, v_end = F / c, gone = -expm1(-h / tau);    /* 1 - exp(-h / tau) */
    r[VR_x] += v_end * h + (v - v_end) * tau * gone;
    r[VR_v] = v - (v - v_end) * gone;
    return 0;
}
