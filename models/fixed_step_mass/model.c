/* Foreign-style mass: m v' = F - c v, x' = v, with F held over the communication step and
 * integrated by `substeps` classical Runge-Kutta (RK4) steps. */
#include <stdio.h>

#include "model.h"

int model_initialize(ModelData *md, char *msg, size_t n) {
    const double *r = md->r;
    if (!(r[VR_m] > 0.0)) { snprintf(msg, n, "m must be > 0, got %g", r[VR_m]); return 1; }
    if (!(r[VR_c] >= 0.0)) { snprintf(msg, n, "c must be >= 0, got %g", r[VR_c]); return 1; }
    if (md->i[VRI_substeps] < 1) { snprintf(msg, n, "substeps must be >= 1, got %d", md->i[VRI_substeps]); return 1; }
    return 0;
}

/* Acceleration of the mass at velocity v under the held force. */
static double acceleration(const double *r, double v) {
    return (r[VR_F] - r[VR_c] * v) / r[VR_m];
}

/* One RK4 step of size hs on (x, v). */
static void rk4_step(double *r, double hs) {
    double v0 = r[VR_v];
    double a1 = acceleration(r, v0);
    double v2 = v0 + 0.5 * hs * a1, a2 = acceleration(r, v2);
    double v3 = v0 + 0.5 * hs * a2, a3 = acceleration(r, v3);
    double v4 = v0 + hs * a3, a4 = acceleration(r, v4);
    r[VR_x] += hs / 6.0 * (v0 + 2.0 * v2 + 2.0 * v3 + v4);
    r[VR_v] += hs / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
}

int model_step_io(ModelData *md, double h, char *msg, size_t n) {
    (void)msg; (void)n;
    int steps = md->i[VRI_substeps];
    for (int k = 0; k < steps; k++) rk4_step(md->r, h / steps);
    return 0;
}
