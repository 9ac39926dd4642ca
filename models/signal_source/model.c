/* Teaches: outputs of every type from one model, each written at the end of the step from the
 * step count and the time (m->time is the start of the step, h its length). */
#include <math.h>
#include <stdio.h>

#include "model.h"

static void write_outputs(ModelData *m, double t) {
    double *r = m->r;
    r[VR_y] = r[VR_amplitude] * sin(2.0 * 3.14159265358979323846 * r[VR_frequency] * t);
    m->b[VRB_flag] = (m->i[VRI_count] / m->i[VRI_period]) % 2 == 1;
    snprintf(m->s[VRS_label], STRING_SIZE, "%s", m->b[VRB_flag] ? "high, \"on\"" : "low");
}

int model_initialize(ModelData *m, char *msg, size_t n) {
    if (m->i[VRI_period] < 1) { snprintf(msg, n, "period must be >= 1, got %d", m->i[VRI_period]); return 1; }
    m->i[VRI_count] = 0;
    write_outputs(m, m->time);
    return 0;
}

int model_step_io(ModelData *m, double h, char *msg, size_t n) {
    (void)msg; (void)n;
    m->i[VRI_count] += 1;
    write_outputs(m, m->time + h);
    return 0;
}
