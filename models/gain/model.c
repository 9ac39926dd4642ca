/* Teaches: an output that depends directly on an input (HAS_FEEDTHROUGH), so that the value a
 * master reads depends on what it set before, in initialization mode as in step mode. */
#include "model.h"

void model_outputs(ModelData *m) {
    m->r[VR_y] = m->r[VR_k] * m->r[VR_u] + m->r[VR_c];
}

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)msg; (void)n;
    model_outputs(m);
    return 0;
}

int model_step_io(ModelData *m, double h, char *msg, size_t n) {
    (void)msg; (void)n;
    m->r[VR_x] += h * m->r[VR_y];
    m->i[VRI_steps] += 1;
    model_outputs(m);
    return 0;
}
