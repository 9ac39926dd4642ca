/* Multi-rate subsystems on the kernel route (multirate.h): the substeps of
 * wavecosim/core/frozen_port_map.py Subsystem._substeps operation by operation (sums from 0.0 in
 * substep order, -ffp-contract=off), so the numbers are the Python reference's to the last bit. */
#include <stdlib.h>
#include <string.h>

#include "fmicall.h"
#include "multirate.h"

struct MultiRate {
    DRFunctions fn;                /* the FMU's own */
    fmi2Component comp;
    int n, m, staged;              /* substeps; channels; whether the stage values are averaged */
    double scale;
    long do_steps;                 /* the FMU's doSteps so far */
    fmi2ValueReference *vr;        /* 3 m: efforts, flows, outgoing waves */
    double *values, *total;        /* 3 m each: one read, the sums */
    double *stage;                 /* the caller's 3 m + 1: the macro-step's values, then 1.0 once made */
};

MultiRate *mr_create(const DRFunctions *fn, fmi2Component comp, int n, double scale, int m,
                     const fmi2ValueReference *stage_vr, double *stage) {
    if (n < 1 || m < 1 || (stage_vr && !stage)) return NULL;
    MultiRate *p = calloc(1, sizeof *p);
    double *buf = calloc(6 * (size_t)m, sizeof(double));
    fmi2ValueReference *vr = calloc(3 * (size_t)m, sizeof *vr);
    if (!p || !buf || !vr) {
        free(p);
        free(buf);
        free(vr);
        return NULL;
    }
    p->fn = *fn;
    p->comp = comp;
    p->n = n;
    p->m = m;
    p->scale = scale;
    p->staged = stage_vr != NULL;
    if (stage_vr) memcpy(vr, stage_vr, 3 * (size_t)m * sizeof *vr);
    p->vr = vr;
    p->values = buf;
    p->total = buf + 3 * m;
    p->stage = stage;
    return p;
}

void mr_destroy(MultiRate *p) {
    if (!p) return;
    free(p->vr);
    free(p->values);
    free(p);
}

const long *mr_do_steps(const MultiRate *p) { return &p->do_steps; }

/* The shim of c: the call in progress (fmicall.h) names the FMU behind it, not the shim. */
static MultiRate *mr_of(fmi2Component c) {
    MultiRate *p = c;
    fmi_call_now->instance = p->comp;
    return p;
}

static fmi2Status mr_getFMUstate(fmi2Component c, fmi2FMUstate *state) {
    MultiRate *p = mr_of(c);
    return p->fn.getFMUstate(p->comp, state);
}

static fmi2Status mr_setFMUstate(fmi2Component c, fmi2FMUstate state) {
    MultiRate *p = mr_of(c);
    return p->fn.setFMUstate(p->comp, state);
}

static fmi2Status mr_freeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    MultiRate *p = mr_of(c);
    return p->fn.freeFMUstate(p->comp, state);
}

/* Subsystem._substeps: the FMU gets a times scale on its inputs. */
static fmi2Status mr_setReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    MultiRate *p = mr_of(c);
    if (nvr > (size_t)p->m) return fmi2Error;
    for (size_t j = 0; j < nvr; j++) p->values[j] = value[j] * p->scale;
    return p->fn.setReal(p->comp, vr, nvr, p->values);
}

/* n doSteps of h / n from t, the inputs held; with stage values, their sums over the substeps. */
static fmi2Status mr_doStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    MultiRate *p = mr_of(c);
    size_t w = 3 * (size_t)p->m;
    double hs = h / p->n;
    fmi2Status worst = fmi2OK;
    for (size_t j = 0; j < w; j++) p->total[j] = 0.0;
    for (int k = 0; k < p->n; k++) {
        fmi2Status status = p->fn.doStep(p->comp, t + (double)k * hs, hs, no_prior);
        if (fmi_fails(status)) return status;
        p->do_steps++;
        worst = status > worst ? status : worst;
        if (!p->staged) continue;
        status = p->fn.getReal(p->comp, p->vr, w, p->values);
        if (fmi_fails(status)) return status;
        for (size_t j = 0; j < w; j++) p->total[j] = p->total[j] + p->values[j];
    }
    if (p->staged) {
        size_t m = (size_t)p->m;
        for (size_t j = 0; j < 2 * m; j++) p->stage[j] = p->total[j] / p->n;
        for (size_t j = 2 * m; j < w; j++) p->stage[j] = p->total[j] * p->scale;
        p->stage[w] = 1.0;
    }
    return worst;
}

/* The FMU's values, a stage value reference's as the last macro-step's (readings.py, _macro_stage). */
static fmi2Status mr_getReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    MultiRate *p = mr_of(c);
    fmi2Status status = p->fn.getReal(p->comp, vr, nvr, value);
    if (fmi_fails(status) || !p->staged || p->stage[3 * (size_t)p->m] != 1.0) return status;
    for (size_t j = 0; j < nvr; j++)
        for (size_t i = 0; i < 3 * (size_t)p->m; i++)
            if (vr[j] == p->vr[i]) {
                value[j] = p->stage[i];
                break;
            }
    return status;
}

void mr_functions(DRFunctions *fn) {
    fn->getFMUstate = mr_getFMUstate;
    fn->setFMUstate = mr_setFMUstate;
    fn->freeFMUstate = mr_freeFMUstate;
    fn->setReal = mr_setReal;
    fn->doStep = mr_doStep;
    fn->getReal = mr_getReal;
}
