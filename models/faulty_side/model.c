/* FaultySide: LinearSide's implicit midpoint step, and the fault of config.h at step fault_step. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"

enum { FAULT_NONE, FAULT_SEGFAULT, FAULT_EXIT, FAULT_HANG, FAULT_ABORT };

static int *volatile nowhere = NULL;      /* read at run time, so the compiler keeps the store */

int model_initialize(ModelData *m, char *msg, size_t n) {
    if (m->i[VRI_fault] < FAULT_NONE || m->i[VRI_fault] > FAULT_ABORT) {
        snprintf(msg, n, "fault must be 0..4, got %d", m->i[VRI_fault]);
        return 1;
    }
    if (m->i[VRI_log_bytes] < 0 || m->i[VRI_log_bytes] > 250) {
        snprintf(msg, n, "log_bytes must be 0..250, got %d", m->i[VRI_log_bytes]);
        return 1;
    }
    return 0;
}

double model_energy(const ModelData *m) {
    const double *r = m->r;
    return 0.5 * r[VR_m2] * r[VR_v2] * r[VR_v2] + 0.5 * r[VR_k2] * r[VR_q2] * r[VR_q2];
}

/* The fault of this instance, when the step from m->time is fault_step. */
static void strike(const ModelData *m, double h) {
    if (m->i[VRI_fault] == FAULT_NONE || floor(m->time / h + 0.5) != (double)m->i[VRI_fault_step]) return;
    volatile int spin = 1;
    switch (m->i[VRI_fault]) {
    case FAULT_SEGFAULT: *nowhere = 1; break;
    case FAULT_EXIT: exit(0);
    case FAULT_HANG: while (spin) {} break;
    default: abort();
    }
}

/* A warning note of log_bytes characters for the layer to log after the step. */
static void note(const ModelData *m, double h, char *msg, size_t n) {
    size_t want = (size_t)m->i[VRI_log_bytes];
    if (!want || n < 2) return;
    if (want > n - 1) want = n - 1;
    int head = snprintf(msg, n, "step %.0f of FaultySide: ", floor(m->time / h + 0.5));
    size_t at = head > 0 && (size_t)head < want ? (size_t)head : want;
    memset(msg + at, '.', want - at);
    msg[want] = '\0';
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    strike(m, h);
    double *r = m->r;
    double m2 = r[VR_m2], k2 = r[VR_k2], c = p->c[0], s = p->s[0];
    double vbar = (2.0 * m2 * r[VR_v2] / h - k2 * r[VR_q2] - c) / (2.0 * m2 / h + 0.5 * k2 * h + r[VR_c2] + s);
    r[VR_q2] += h * vbar;
    r[VR_v2] = 2.0 * vbar - r[VR_v2];
    e[0] = c + s * vbar;
    f[0] = -vbar;
    note(m, h, msg, n);
    return 0;
}
