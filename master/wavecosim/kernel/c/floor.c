/* The floor of a run: the FMU calls it made, recorded in order, then made again from C alone on
 * freshly instantiated FMUs (floor.h). The replay is a loop over the recorded calls, so its time
 * is what those FMU calls cost with no master, observer or recorder around them. */
#define _POSIX_C_SOURCE 200809L
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "abi.h"
#include "floor.h"
#include "fmicall.h"

enum { OP_GET_STATE, OP_SET_STATE, OP_FREE_STATE, OP_SET_REAL, OP_DO_STEP, OP_GET_REAL };

typedef struct {
    unsigned char op, flag;
    unsigned short fmu;
    unsigned n;                    /* value references (and values) that follow in the data */
    size_t at;                     /* where they start in the data (vr as doubles, then values) */
    double t, h;                   /* doStep's */
    int slot;                      /* the state handle (get, set, free) */
} Call;

typedef struct {
    fmi2Component comp;
    FLFunctions fn;                /* the FMU's own */
} Fmu;

struct FLRecorder {
    Fmu fmu[FL_MAX_FMUS];
    int n_fmus;
    Call *calls;
    size_t n_calls, room;
    double *data;
    size_t n_data, data_room;
    fmi2FMUstate slot_state[FL_MAX_SLOTS];    /* the handle each slot held when recorded */
    int slot_fmu[FL_MAX_SLOTS];               /* the FMU whose state it is */
    int n_slots;
    int overflow;
};

static FLRecorder *current;        /* the recorder whose FMUs the shims call (one at a time) */
static int recording;              /* whether they record the calls (fl_start .. fl_stop) */

FLRecorder *fl_create(void) { return calloc(1, sizeof(FLRecorder)); }

void fl_destroy(FLRecorder *r) {
    if (!r) return;
    if (current == r) current = NULL, recording = 0;
    free(r->calls);
    free(r->data);
    free(r);
}

int fl_register(FLRecorder *r, fmi2Component comp, const FLFunctions *fn) {
    for (int i = 0; i < r->n_fmus; i++)
        if (r->fmu[i].comp == comp) return i;
    if (r->n_fmus == FL_MAX_FMUS) return -1;
    r->fmu[r->n_fmus].comp = comp;
    r->fmu[r->n_fmus].fn = *fn;
    return r->n_fmus++;
}

void fl_start(FLRecorder *r) {
    current = r;
    recording = 1;
}

void fl_stop(void) { recording = 0; }

size_t fl_calls(const FLRecorder *r) { return r->overflow ? 0 : r->n_calls; }

/* The registered FMU of comp (its index in *index), or NULL. */
static Fmu *find(fmi2Component comp, int *index) {
    *index = -1;
    for (int i = 0; current && i < current->n_fmus; i++)
        if (current->fmu[i].comp == comp) {
            *index = i;
            return &current->fmu[i];
        }
    return NULL;
}

/* A new call of FMU i with n value references (and, with values, n values) appended; NULL when
 * out of memory (the recording is then marked spoilt). */
static Call *add(int i, int op, size_t n, const fmi2ValueReference *vr, const double *values) {
    FLRecorder *r = current;
    if (!recording) return NULL;
    size_t need = vr ? n * (values ? 2 : 1) : 0;
    if (r->n_calls == r->room) {
        size_t room = r->room ? 2 * r->room : 4096;
        Call *calls = realloc(r->calls, room * sizeof *calls);
        if (!calls) return r->overflow = 1, NULL;
        r->calls = calls, r->room = room;
    }
    if (r->n_data + need > r->data_room) {
        size_t room = r->data_room ? 2 * r->data_room : 16384;
        while (room < r->n_data + need) room *= 2;
        double *data = realloc(r->data, room * sizeof *data);
        if (!data) return r->overflow = 1, NULL;
        r->data = data, r->data_room = room;
    }
    Call *c = &r->calls[r->n_calls++];
    memset(c, 0, sizeof *c);
    c->op = (unsigned char)op, c->fmu = (unsigned short)i, c->n = (unsigned)n, c->at = r->n_data;
    for (size_t j = 0; vr && j < n; j++) r->data[r->n_data++] = (double)vr[j];
    for (size_t j = 0; vr && values && j < n; j++) r->data[r->n_data++] = values[j];
    return c;
}

static int slot_of(int fmu, fmi2FMUstate state, int create) {
    FLRecorder *r = current;
    for (int k = 0; k < r->n_slots; k++)
        if (r->slot_state[k] == state && r->slot_fmu[k] == fmu) return k;
    if (!create || r->n_slots == FL_MAX_SLOTS) return r->overflow = 1, 0;
    r->slot_state[r->n_slots] = state;
    r->slot_fmu[r->n_slots] = fmu;
    return r->n_slots++;
}

/* ---- the recording shims: the FMU's own call, then its record ---- */

static fmi2Status rec_getFMUstate(fmi2Component comp, fmi2FMUstate *state) {
    int i;
    Fmu *f = find(comp, &i);
    if (!f) return fmi2Error;
    fmi2Status status = f->fn.getFMUstate(comp, state);
    Call *c = add(i, OP_GET_STATE, 0, NULL, NULL);
    if (c) c->slot = slot_of(i, *state, 1);
    return status;
}

static fmi2Status rec_setFMUstate(fmi2Component comp, fmi2FMUstate state) {
    int i;
    Fmu *f = find(comp, &i);
    if (!f) return fmi2Error;
    Call *c = add(i, OP_SET_STATE, 0, NULL, NULL);
    if (c) c->slot = slot_of(i, state, 0);
    return f->fn.setFMUstate(comp, state);
}

static fmi2Status rec_freeFMUstate(fmi2Component comp, fmi2FMUstate *state) {
    int i;
    Fmu *f = find(comp, &i);
    if (!f) return fmi2Error;
    Call *c = add(i, OP_FREE_STATE, 0, NULL, NULL);
    if (c) c->slot = slot_of(i, *state, 0);
    return f->fn.freeFMUstate(comp, state);
}

static fmi2Status rec_setReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    int i;
    Fmu *f = find(comp, &i);
    if (!f) return fmi2Error;
    add(i, OP_SET_REAL, n, vr, v);
    return f->fn.setReal(comp, vr, n, v);
}

static fmi2Status rec_doStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean flag) {
    int i;
    Fmu *f = find(comp, &i);
    if (!f) return fmi2Error;
    Call *c = add(i, OP_DO_STEP, 0, NULL, NULL);
    if (c) c->t = t, c->h = h, c->flag = (unsigned char)flag;
    return f->fn.doStep(comp, t, h, flag);
}

static fmi2Status rec_getReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    int i;
    Fmu *f = find(comp, &i);
    if (!f) return fmi2Error;
    add(i, OP_GET_REAL, n, vr, NULL);
    return f->fn.getReal(comp, vr, n, v);
}

void fl_shims(FLFunctions *fn) {
    fn->getFMUstate = rec_getFMUstate;
    fn->setFMUstate = rec_setFMUstate;
    fn->freeFMUstate = rec_freeFMUstate;
    fn->setReal = rec_setReal;
    fn->doStep = rec_doStep;
    fn->getReal = rec_getReal;
}

/* ---- the replay ---- */

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double fl_replay(const FLRecorder *r, const fmi2Component *comps, const FLFunctions *fns, int *failed) {
    fmi2FMUstate slots[FL_MAX_SLOTS] = {0};
    fmi2ValueReference vr[FL_MAX_VALUES];
    double values[FL_MAX_VALUES];
    *failed = -1;
    if (r->overflow) return -1.0;
    double started = now_s();
    for (size_t k = 0; k < r->n_calls; k++) {
        const Call *c = &r->calls[k];
        const FLFunctions *fn = &fns[c->fmu];
        fmi2Component comp = comps[c->fmu];
        const double *data = r->data + c->at;
        size_t n = c->n < FL_MAX_VALUES ? c->n : FL_MAX_VALUES;
        fmi2Status status = fmi2OK;
        for (size_t j = 0; j < n && (c->op == OP_SET_REAL || c->op == OP_GET_REAL); j++)
            vr[j] = (fmi2ValueReference)data[j];
        switch (c->op) {
        case OP_GET_STATE: status = fn->getFMUstate(comp, &slots[c->slot]); break;
        case OP_SET_STATE: status = fn->setFMUstate(comp, slots[c->slot]); break;
        case OP_FREE_STATE: status = fn->freeFMUstate(comp, &slots[c->slot]); break;
        case OP_SET_REAL: status = fn->setReal(comp, vr, n, data + c->n); break;
        case OP_DO_STEP: status = fn->doStep(comp, c->t, c->h, c->flag); break;
        case OP_GET_REAL: status = fn->getReal(comp, vr, n, values); break;
        }
        if (fmi_fails(status)) {
            *failed = (int)k;
            break;
        }
    }
    double elapsed = now_s() - started;
    for (int k = 0; k < r->n_slots; k++)
        if (slots[k]) fns[r->slot_fmu[k]].freeFMUstate(comps[r->slot_fmu[k]], &slots[k]);
    return elapsed;
}

MIRRORED(DRFunctions)
