/* Teaches: inputs of every type, held over the step, and outputs computed from them. */
#include <stdio.h>
#include <string.h>

#include "model.h"

static void write_outputs(ModelData *m) {
    m->r[VR_scaled] = m->r[VR_gain] * m->r[VR_u];
    m->i[VRI_shifted] = m->i[VRI_n] + m->i[VRI_offset];
    m->i[VRI_length] = (int)strlen(m->s[VRS_text]);
    m->b[VRB_off] = !m->b[VRB_on];
    snprintf(m->s[VRS_echo], STRING_SIZE, "%s", m->s[VRS_text]);
}

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)msg; (void)n;
    write_outputs(m);
    return 0;
}

int model_step_io(ModelData *m, double h, char *msg, size_t n) {
    (void)msg; (void)n;
    m->r[VR_integral] += h * m->r[VR_u];
    write_outputs(m);
    return 0;
}
