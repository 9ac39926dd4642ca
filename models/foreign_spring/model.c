/* Foreign-style spring-damper: x' = v with v held over the communication step, integrated by
 * `substeps` explicit steps (exact for a held input; the substeps stand for the exporting tool's
 * fixed-step solver), then the output force on the mass F = -(k x + d v). */
#include <stdio.h>

#include "model.h"

/* The force the element exerts on the mass in the current state. */
static void write_force(double *r) {
    r[VR_F] = -(r[VR_k] * r[VR_x] + r[VR_d] * r[VR_v]);
}

int model_initialize(ModelData *md, char *msg, size_t n) {
    double *r = md->r;
    if (!(r[VR_k] >= 0.0)) { snprintf(msg, n, "k must be >= 0, got %g", r[VR_k]); return 1; }
    if (!(r[VR_d] >= 0.0)) { snprintf(msg, n, "d must be >= 0, got %g", r[VR_d]); return 1; }
    if (md->i[VRI_substeps] < 1) { snprintf(msg, n, "substeps must be >= 1, got %d", md->i[VRI_substeps]); return 1; }
    write_force(r);
    return 0;
}

int model_step_io(ModelData *md, double h, char *msg, size_t n) {
    (void)msg; (void)n;
    double *r = md->r;
    int steps = md->i[VRI_substeps];
    for (int k = 0; k < steps; k++) r[VR_x] += h / steps * r[VR_v];
    write_force(r);
    return 0;
}
