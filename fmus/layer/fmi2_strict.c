/* A strict FMI 2.0 Co-Simulation layer, for models that must behave like the least forgiving
 * real exports (a model selects it with FMI_LAYER_SOURCE in config.h; it has no wave port).
 *
 * Where fmi2_cosim.c forgives, this layer stops the process with abort() and one line on stderr
 * naming the function, the instance and what was wrong, as a real FMU would crash on:
 *   - a component that is not a live instance of this binary (freed, or another FMU's);
 *   - a NULL state handle, a state already freed, or a state of another instance;
 *   - fmi2DoStep at a time other than the end of the previous step (after fmi2SetFMUstate: the
 *     restored time), a step size <= 0, or any call the FMI 2.0 state machine does not allow in the
 *     current phase (e.g. fmi2Terminate after a call returned fmi2Error);
 *   - fmi2SetFMUstate to a time before the communication point of a doStep that was given
 *     noSetFMUStatePriorToCurrentPoint = true (the master promised not to go back there).
 * Saved states are separate heap blocks; fmi2GetFMUstate on a handle that holds a state frees it
 * and returns a new one (as OpenModelica's runtime does), so a copy of an old handle goes stale.
 * Freed states are poisoned and kept in quarantine, so using one is recognised, not a crash.
 *
 * Two behaviours of real FMUs can be switched on by integer parameters, when config.h names them:
 *   QUIRK_FREEZE (an integer VRI_): fmi2DoStep with noSetFMUStatePriorToCurrentPoint = false
 *     after the first step (time advances, status OK) 1: leaves the state where it is; 2: puts the
 *     states and outputs back where they were at the end of initialization (its start point);
 *   QUIRK_SHARED (an integer VRI_): 1: instances keep their variables in one block shared by every
 *     instance in this copy of the binary (an FMU that is not reentrant; each keeps its own clock);
 *     2: one block for the whole process, every copy of the binary (process-wide data, as a runtime
 *     library the copies share would hold);
 *   QUIRK_RESTORE (a real VR_): fmi2SetFMUstate leaves every STATE variable off by this relative
 *     error (an FMU that restores its state only approximately).
 * COUNT_CALLS (an integer VRI_ of INTEGER_IO, optional): that integer and the next four read the
 * fmi2DoStep, fmi2GetFMUstate and fmi2SetFMUstate calls the instance took, and its value gets and
 * sets (fmi2Get/Set Real, Integer, Boolean, String; one each per call, the call reading them
 * included), which no restore undoes (a count for a master's bookkeeping to be checked against).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model.h"

#if HAS_WAVE_PORT
#error "fmi2_strict.c: a strict model has a physical port only (HAS_WAVE_PORT 0)"
#endif

#define INSTANCE_MAGIC 0x53545249u       /* "STRI" */
#define STATE_LIVE 0x4c495645u           /* "LIVE" */
#define STATE_FREED 0x44454144u          /* "DEAD" */
#define POISON 0xdb                      /* freed state data: every double a NaN */
#define QUARANTINE 1024                  /* freed states kept (never reused) before their memory goes */
#define MAX_LIVE 64                      /* live states per instance */

typedef enum { P_INSTANTIATED, P_INIT, P_STEP, P_TERMINATED, P_ERROR } Phase;

typedef struct SavedState SavedState;

typedef struct Instance {
    unsigned magic;
    char *name;
    fmi2CallbackFunctions cb;
    Phase phase;
    long steps;                          /* doSteps since initialization (part of the state) */
    double time;                         /* where the instance is (part of the state; its own, always) */
    double restore_floor;                /* no state before this time may be set again (the flag's promise) */
    ModelData own, *d;                   /* d: &own, or the process-wide block (QUIRK_SHARED) */
    double start[N_REALS];               /* the variables at the end of initialization (QUIRK_FREEZE 2) */
    long calls[5];                       /* doSteps, state gets and sets, value gets and sets taken
                                          * (COUNT_CALLS), never restored */
    SavedState *live[MAX_LIVE];
    int n_live;
    struct Instance *next;
} Instance;

struct SavedState {
    unsigned magic;
    const Instance *owner;
    Phase phase;
    long steps;
    double time;
    ModelData *data;
};

static pthread_mutex_t registry = PTHREAD_MUTEX_INITIALIZER;
static Instance *instances;                       /* every live instance */
static SavedState *quarantine[QUARANTINE];        /* the last freed states, oldest first */
static int n_quarantined, quarantine_at;
static ModelData shared_block;                    /* QUIRK_SHARED 1: one block for every instance */
#define PROCESS_BLOCK "WAVECOSIM_STRICT_PROCESS_BLOCK" /* QUIRK_SHARED 2: the address of the first copy's */

/* The block of QUIRK_SHARED 2: the first loaded copy's, found through the environment. */
static ModelData *process_block(void) {
    const char *at = getenv(PROCESS_BLOCK);
    void *p = NULL;
    if (at && sscanf(at, "%p", &p) == 1 && p) return p;
    char text[32];
    snprintf(text, sizeof text, "%p", (void *)&shared_block);
    setenv(PROCESS_BLOCK, text, 1);
    return &shared_block;
}

/* This copy leaves the process: other copies must not use its block any more. */
__attribute__((destructor)) static void forget_process_block(void) {
    const char *at = getenv(PROCESS_BLOCK);
    void *p = NULL;
    if (at && sscanf(at, "%p", &p) == 1 && p == (void *)&shared_block) unsetenv(PROCESS_BLOCK);
}

static const char *phase_names[] = {"instantiated", "initialization mode", "step mode", "terminated", "error"};

#define REAL_START(name, kind, start, unit, desc) start,
#define REAL_KIND(name, kind, start, unit, desc) kind,
#define REAL_NAME(name, kind, start, unit, desc) #name,
#define INT_START(name, start, desc) start,
static const double real_start[N_REALS] = {REAL_VARIABLES(REAL_START)};
static const int real_kind[N_REALS] = {REAL_VARIABLES(REAL_KIND)};
static const char *real_name[N_REALS] = {REAL_VARIABLES(REAL_NAME)};
static const int int_start[N_INTEGERS] = {INTEGER_VARIABLES(INT_START)};

/* Stops the process with one line on stderr: the misuse a real FMU would crash on. */
static void die(const char *fn, const char *who, const char *fmt, ...) __attribute__((noreturn, format(printf, 3, 4)));
static void die(const char *fn, const char *who, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s (strict FMU): %s on instance %s: ", MODEL_IDENTIFIER_STR, fn, who);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    fflush(stderr);
    va_end(ap);
    abort();
}

/* Logs "fn: message" through the master's logger as an error; returns fmi2Error. */
static fmi2Status fail(Instance *c, const char *fn, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static fmi2Status fail(Instance *c, const char *fn, const char *fmt, ...) {
    char buf[400], line[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    snprintf(line, sizeof line, "%s: %s", fn, buf);
    for (char *p = line; *p; p++)
        if (*p == '%') *p = '#';          /* the logger takes the message as a format */
    c->cb.logger(c->cb.componentEnvironment, c->name, fmi2Error, "logStatusError", line);
    return fmi2Error;
}

/* The live instance behind comp, in a phase that allows fn (mask over Phase), or abort. */
static Instance *instance(fmi2Component comp, const char *fn, int allowed) {
    pthread_mutex_lock(&registry);
    Instance *c = instances;
    while (c && c != (Instance *)comp) c = c->next;
    pthread_mutex_unlock(&registry);
    if (!c) die(fn, "?", "%p is not a live instance of this FMU (freed, or another FMU's component)", comp);
    if (!((1 << c->phase) & allowed))
        die(fn, c->name, "not allowed in %s (the FMI 2.0 co-simulation state machine)", phase_names[c->phase]);
    return c;
}

#define ANY ((1 << P_INSTANTIATED) | (1 << P_INIT) | (1 << P_STEP) | (1 << P_TERMINATED) | (1 << P_ERROR))
#define READABLE ((1 << P_INIT) | (1 << P_STEP) | (1 << P_TERMINATED) | (1 << P_ERROR))
#define SETTABLE ((1 << P_INSTANTIATED) | (1 << P_INIT) | (1 << P_STEP))
#define BEFORE_STEP ((1 << P_INSTANTIATED) | (1 << P_INIT))

/* ---- state handles ---- */

static int live_index(const Instance *c, const SavedState *s) {
    for (int k = 0; k < c->n_live; k++)
        if (c->live[k] == s) return k;
    return -1;
}

/* Aborts unless s is a live state of c, naming what it is instead. */
static void check_state(const Instance *c, const SavedState *s, const char *fn) {
    if (!s) die(fn, c->name, "NULL state handle");
    if (live_index(c, s) >= 0) return;
    pthread_mutex_lock(&registry);
    const Instance *other = instances;
    while (other && live_index(other, s) < 0) other = other->next;
    int freed = 0;
    for (int k = 0; k < n_quarantined; k++) freed |= quarantine[k] == s;
    pthread_mutex_unlock(&registry);
    if (other) die(fn, c->name, "state handle %p belongs to instance %s (a foreign state)", (const void *)s, other->name);
    if (freed) die(fn, c->name, "state handle %p was freed (fmi2FreeFMUstate, or replaced by fmi2GetFMUstate)",
                   (const void *)s);
    die(fn, c->name, "%p is not a state handle of this FMU (never made by it, or freed long ago)", (const void *)s);
}

/* Removes s from its owner's live states, poisons it and puts it in quarantine. */
static void release(Instance *c, SavedState *s) {
    memset(s->data, POISON, sizeof *s->data);
    s->magic = STATE_FREED;
    s->owner = NULL;
    pthread_mutex_lock(&registry);
    int k = live_index(c, s);
    c->live[k] = c->live[--c->n_live];
    if (n_quarantined == QUARANTINE) {
        SavedState *old = quarantine[quarantine_at];
        free(old->data);
        free(old);
        quarantine[quarantine_at] = s;
        quarantine_at = (quarantine_at + 1) % QUARANTINE;
    } else {
        quarantine[n_quarantined++] = s;
    }
    pthread_mutex_unlock(&registry);
}

/* A new live state of c holding its current variables. */
static SavedState *capture(Instance *c, const char *fn) {
    if (c->n_live == MAX_LIVE) die(fn, c->name, "more than %d states held at once (are they ever freed?)", MAX_LIVE);
    SavedState *s = malloc(sizeof *s);
    ModelData *data = malloc(sizeof *data);
    if (!s || !data) die(fn, c->name, "out of memory");
    *data = *c->d;
    *s = (SavedState){STATE_LIVE, c, c->phase, c->steps, c->time, data};
    pthread_mutex_lock(&registry);
    c->live[c->n_live++] = s;
    pthread_mutex_unlock(&registry);
    return s;
}

/* ---- the model's variables ---- */

static void set_start_values(ModelData *d) {
    memset(d, 0, sizeof *d);
    for (int k = 0; k < N_REALS; k++) d->r[k] = real_start[k];
    for (int k = 0; k < N_INTEGERS; k++) d->i[k] = int_start[k];
}

static int quirk(const Instance *c, int which) {
    return which >= 0 && c->d->i[which] != 0;
}

#ifndef QUIRK_FREEZE
#define QUIRK_FREEZE (-1)
#endif
#ifndef QUIRK_SHARED
#define QUIRK_SHARED (-1)
#endif
#ifndef QUIRK_RESTORE
#define QUIRK_RESTORE (-1)
#endif
#ifndef COUNT_CALLS
#define COUNT_CALLS (-1)
#endif

/* Instance.calls: what each counts. */
enum { CALL_DO_STEP = 0, CALL_GET_STATE = 1, CALL_SET_STATE = 2, CALL_GET = 3, CALL_SET = 4 };

/* The instance, with one more call of `kind` counted. */
static Instance *counted(Instance *c, int kind) {
    c->calls[kind]++;
    return c;
}

/* Integer k of the instance: its own count of calls for the COUNT_CALLS variables, else the block's. */
static fmi2Integer integer(const Instance *c, int k) {
    if (COUNT_CALLS >= 0 && k >= COUNT_CALLS && k < COUNT_CALLS + 5) return (fmi2Integer)c->calls[k - COUNT_CALLS];
    return c->d->i[k];
}

/* ---- the FMI 2.0 functions ---- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean logging) {
    (void)location; (void)visible; (void)logging;
    const char *who = name ? name : "?";
    if (!functions || !functions->logger) die("fmi2Instantiate", who, "no logger callback");
    if (type != fmi2CoSimulation || !guid || strcmp(guid, MODEL_GUID) != 0) return NULL;
    Instance *c = calloc(1, sizeof *c);
    if (!c || !(c->name = malloc(strlen(who) + 1))) die("fmi2Instantiate", who, "out of memory");
    strcpy(c->name, who);
    c->magic = INSTANCE_MAGIC;
    c->cb = *functions;
    c->d = &c->own;
    set_start_values(c->d);
    c->phase = P_INSTANTIATED;
    c->restore_floor = -INFINITY;
    pthread_mutex_lock(&registry);
    c->next = instances;
    instances = c;
    pthread_mutex_unlock(&registry);
    return c;
}

void fmi2FreeInstance(fmi2Component comp) {
    Instance *c = instance(comp, "fmi2FreeInstance", ANY);
    while (c->n_live) release(c, c->live[0]);
    pthread_mutex_lock(&registry);
    Instance **p = &instances;
    while (*p != c) p = &(*p)->next;
    *p = c->next;
    pthread_mutex_unlock(&registry);
    c->magic = 0;
    free(c->name);
    free(c);
}

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)on; (void)n; (void)cats;
    instance(comp, "fmi2SetDebugLogging", ANY);
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean tol_defined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stop_defined, fmi2Real stop) {
    (void)tol_defined; (void)tol; (void)stop_defined; (void)stop;
    instance(comp, "fmi2SetupExperiment", 1 << P_INSTANTIATED)->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    instance(comp, "fmi2EnterInitializationMode", 1 << P_INSTANTIATED)->phase = P_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    Instance *c = instance(comp, "fmi2ExitInitializationMode", 1 << P_INIT);
    char msg[300] = "";
    if (model_initialize(c->d, msg, sizeof msg) != 0) {
        c->phase = P_ERROR;
        return fail(c, "fmi2ExitInitializationMode", "%s", msg);
    }
    write_energy(c->d);
    memcpy(c->start, c->d->r, sizeof c->start);
    if (quirk(c, QUIRK_SHARED)) {            /* from now on every such instance shares one block */
        ModelData *block = c->d->i[QUIRK_SHARED] == 2 ? process_block() : &shared_block;
        *block = *c->d;
        c->d = block;
    }
    c->phase = P_STEP;
    c->steps = 0;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    instance(comp, "fmi2Terminate", 1 << P_STEP)->phase = P_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    Instance *c = instance(comp, "fmi2Reset", ANY);
    c->d = &c->own;
    set_start_values(c->d);
    c->phase = P_INSTANTIATED;
    c->restore_floor = -INFINITY;
    return fmi2OK;
}

/* Aborts unless vr[0..n) are value references below `end` (+ base) and the arrays are given. */
static void check_refs(const Instance *c, const char *fn, const fmi2ValueReference vr[], size_t n, const void *values,
                       unsigned base, unsigned end) {
    if (n > 0 && (!vr || !values)) die(fn, c->name, "NULL array for %zu values", n);
    for (size_t k = 0; k < n; k++)
        if (vr[k] < base || vr[k] >= base + end) die(fn, c->name, "value reference %u does not exist", vr[k]);
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Instance *c = counted(instance(comp, "fmi2GetReal", READABLE), CALL_GET);
    check_refs(c, "fmi2GetReal", vr, n, value, 0, N_REALS);
    for (size_t k = 0; k < n; k++) value[k] = c->d->r[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
    Instance *c = counted(instance(comp, "fmi2GetInteger", READABLE), CALL_GET);
    check_refs(c, "fmi2GetInteger", vr, n, value, INTEGER_VR_BASE, N_INTEGERS);
    for (size_t k = 0; k < n; k++) value[k] = integer(c, (int)(vr[k] - INTEGER_VR_BASE));
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Instance *c = counted(instance(comp, "fmi2SetReal", SETTABLE), CALL_SET);
    check_refs(c, "fmi2SetReal", vr, n, value, 0, N_REALS);
    for (size_t k = 0; k < n; k++) {
        int kind = real_kind[vr[k]];
        if (kind == OUTPUT || (c->phase == P_STEP && kind != INPUT && kind != TUNABLE))
            die("fmi2SetReal", c->name, "%s cannot be set in %s", real_name[vr[k]], phase_names[c->phase]);
        c->d->r[vr[k]] = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[]) {
    Instance *c = counted(instance(comp, "fmi2SetInteger", BEFORE_STEP), CALL_SET);
    check_refs(c, "fmi2SetInteger", vr, n, value, INTEGER_VR_BASE, N_INTEGERS);
    for (size_t k = 0; k < n; k++) c->d->i[vr[k] - INTEGER_VR_BASE] = value[k];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]) {
    check_refs(counted(instance(comp, "fmi2GetBoolean", READABLE), CALL_GET), "fmi2GetBoolean", vr, n, value, 0, 0);
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    check_refs(counted(instance(comp, "fmi2GetString", READABLE), CALL_GET), "fmi2GetString", vr, n, value, 0, 0);
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[]) {
    check_refs(counted(instance(comp, "fmi2SetBoolean", SETTABLE), CALL_SET), "fmi2SetBoolean", vr, n, value, 0, 0);
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2String value[]) {
    check_refs(counted(instance(comp, "fmi2SetString", SETTABLE), CALL_SET), "fmi2SetString", vr, n, value, 0, 0);
    return fmi2OK;
}

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *state) {
    Instance *c = instance(comp, "fmi2GetFMUstate", ANY);
    if (!state) die("fmi2GetFMUstate", c->name, "NULL pointer to the state handle");
    c->calls[CALL_GET_STATE]++;
    if (*state) {                            /* by the book: a state of ours; it is replaced */
        check_state(c, *state, "fmi2GetFMUstate");
        release(c, *state);
    }
    *state = capture(c, "fmi2GetFMUstate");
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state) {
    Instance *c = instance(comp, "fmi2SetFMUstate", ANY);
    check_state(c, state, "fmi2SetFMUstate");
    c->calls[CALL_SET_STATE]++;
    const SavedState *s = state;
    if (s->time < c->restore_floor - 1e-9 * (1.0 + fabs(c->restore_floor)))
        die("fmi2SetFMUstate", c->name, "the state at t = %.17g is before %.17g, where a doStep was given "
            "noSetFMUStatePriorToCurrentPoint = true", s->time, c->restore_floor);
    *c->d = *s->data;
    for (int k = 0; QUIRK_RESTORE >= 0 && k < N_REALS; k++)
        if (real_kind[k] == STATE) c->d->r[k] *= 1.0 + c->d->r[QUIRK_RESTORE];
    c->phase = s->phase;
    c->steps = s->steps;
    c->time = s->time;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *state) {
    Instance *c = instance(comp, "fmi2FreeFMUstate", ANY);
    if (!state) die("fmi2FreeFMUstate", c->name, "NULL pointer to the state handle");
    if (!*state) return fmi2OK;              /* nothing to free */
    check_state(c, *state, "fmi2FreeFMUstate");
    release(c, *state);
    *state = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate state, size_t *size) {
    (void)state; (void)size;
    return fail(instance(comp, "fmi2SerializedFMUstateSize", ANY), "fmi2SerializedFMUstateSize",
                "not supported (canSerializeFMUstate is false)");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    (void)state; (void)bytes; (void)size;
    return fail(instance(comp, "fmi2SerializeFMUstate", ANY), "fmi2SerializeFMUstate",
                "not supported (canSerializeFMUstate is false)");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state) {
    (void)bytes; (void)size; (void)state;
    return fail(instance(comp, "fmi2DeSerializeFMUstate", ANY), "fmi2DeSerializeFMUstate",
                "not supported (canSerializeFMUstate is false)");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return fail(instance(comp, "fmi2GetDirectionalDerivative", ANY), "fmi2GetDirectionalDerivative",
                "not provided");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)order; (void)value;
    return fail(instance(comp, "fmi2SetRealInputDerivatives", SETTABLE), "fmi2SetRealInputDerivatives",
                "inputs are held over a step (%zu derivatives given)", n);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)n; (void)order; (void)value;
    return fail(instance(comp, "fmi2GetRealOutputDerivatives", READABLE), "fmi2GetRealOutputDerivatives",
                "not provided");
}

/* One step from the end of the last one: inputs finite, the model's step, H; a failure leaves the
 * variables as they were and the instance in the error phase (only reset or free may follow). */
fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    Instance *c = instance(comp, "fmi2DoStep", 1 << P_STEP);
    ModelData *d = c->d;
    if (!(h > 0.0) || !isfinite(h)) die("fmi2DoStep", c->name, "communication step size %g", h);
    if (!(fabs(t - c->time) <= 1e-6 * h))
        die("fmi2DoStep", c->name, "currentCommunicationPoint %.17g is not where the instance is (%.17g)", t, c->time);
    if (no_prior && t > c->restore_floor) c->restore_floor = t;
    c->calls[CALL_DO_STEP]++;
    if (quirk(c, QUIRK_FREEZE) && !no_prior && c->steps > 0) {
        for (int k = 0; d->i[QUIRK_FREEZE] == 2 && k < N_REALS; k++)     /* back to the start point */
            if (real_kind[k] == STATE || real_kind[k] == OUTPUT) d->r[k] = c->start[k];
        c->time = t + h;                     /* the quirk: the state stays (or returns), status OK */
        c->steps++;
        return fmi2OK;
    }
    ModelData backup = *d;
    char msg[300] = "";
    for (int k = 0; k < N_REALS; k++)
        if (real_kind[k] == INPUT && !isfinite(d->r[k]))
            snprintf(msg, sizeof msg, "input %s = %g is not finite", real_name[k], d->r[k]);
    if (msg[0] || model_step_io(d, h, msg, sizeof msg) != 0) {
        *d = backup;
        c->phase = P_ERROR;
        return fail(c, "fmi2DoStep", "at t = %.17g: %s", t, msg);
    }
    write_energy(d);
    c->time = t + h;
    c->steps++;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component comp) {
    return fail(instance(comp, "fmi2CancelStep", 1 << P_STEP), "fmi2CancelStep", "steps are synchronous");
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value) {
    (void)value;
    return fail(instance(comp, "fmi2GetStatus", READABLE), "fmi2GetStatus", "unsupported status kind %d", (int)s);
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    Instance *c = instance(comp, "fmi2GetRealStatus", READABLE);
    if (s != fmi2LastSuccessfulTime || !value) return fail(c, "fmi2GetRealStatus", "unsupported status kind %d", (int)s);
    *value = c->time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value) {
    (void)value;
    return fail(instance(comp, "fmi2GetIntegerStatus", READABLE), "fmi2GetIntegerStatus",
                "unsupported status kind %d", (int)s);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)value;
    return fail(instance(comp, "fmi2GetBooleanStatus", READABLE), "fmi2GetBooleanStatus",
                "unsupported status kind %d", (int)s);
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value) {
    (void)value;
    return fail(instance(comp, "fmi2GetStringStatus", READABLE), "fmi2GetStringStatus",
                "unsupported status kind %d", (int)s);
}
