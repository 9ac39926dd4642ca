/* Teaches: an experiment that does not start at 0; m->time is the start time after set-up, the
 * start of the step in model_step_io, and m->tolerance the tolerance set up. */
#include "model.h"

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)msg; (void)n;
    m->r[VR_start] = m->r[VR_clock] = m->time;
    m->r[VR_elapsed] = 0.0;
    m->r[VR_tolerance] = m->tolerance;
    m->i[VRI_steps] = 0;
    return 0;
}

int model_step_io(ModelData *m, double h, char *msg, size_t n) {
    (void)msg; (void)n;
    m->r[VR_clock] = m->time + h;
    m->r[VR_elapsed] = m->r[VR_clock] - m->r[VR_start];
    m->i[VRI_steps] += 1;
    return 0;
}
