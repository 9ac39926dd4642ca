/* The one FMI 2.0 Co-Simulation implementation shared by every model in models/.
 * It owns instances, logging, get/set by value reference, the wave/physical port closure,
 * state save/restore/serialization (byte copies of ModelData) and status checks. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model.h"

#if defined(__GNUC__)
#define PRINTF_LIKE(fmt_index, args_index) __attribute__((format(printf, fmt_index, args_index)))
#else
#define PRINTF_LIKE(fmt_index, args_index)
#endif

typedef enum { ST_INSTANTIATED, ST_INIT, ST_STEP, ST_TERMINATED, ST_ERROR } Phase;

typedef struct {
    ModelData d;
    Phase phase;
    char *name;
    fmi2CallbackFunctions cb;
    fmi2Boolean logging;
} Instance;

/* Phases in which each entry point may be called, as bit masks over Phase (MASK_<function>);
 * entry points with the same rule share one mask. */
#define PHASES_ANY ((1 << ST_INSTANTIATED) | (1 << ST_INIT) | (1 << ST_STEP) | (1 << ST_TERMINATED) | (1 << ST_ERROR))
#define PHASES_INSTANTIATED (1 << ST_INSTANTIATED)
#define PHASES_BEFORE_STEP ((1 << ST_INSTANTIATED) | (1 << ST_INIT))
#define PHASES_UNTIL_STEP ((1 << ST_INSTANTIATED) | (1 << ST_INIT) | (1 << ST_STEP))
#define MASK_fmi2SetDebugLogging PHASES_ANY
#define MASK_fmi2SetupExperiment PHASES_INSTANTIATED
#define MASK_fmi2EnterInitializationMode PHASES_INSTANTIATED
#define MASK_fmi2ExitInitializationMode (1 << ST_INIT)
#define MASK_fmi2Terminate ((1 << ST_STEP) | (1 << ST_ERROR))
#define MASK_fmi2Reset PHASES_ANY
#define MASK_fmi2GetReal PHASES_ANY
#define MASK_fmi2GetInteger PHASES_ANY
#define MASK_fmi2GetBoolean PHASES_ANY
#define MASK_fmi2GetString PHASES_ANY
#define MASK_fmi2SetReal PHASES_UNTIL_STEP
#define MASK_fmi2SetInteger PHASES_UNTIL_STEP
#define MASK_fmi2SetBoolean PHASES_UNTIL_STEP
#define MASK_fmi2SetString PHASES_UNTIL_STEP
#define MASK_fmi2GetFMUstate PHASES_ANY
#define MASK_fmi2SetFMUstate PHASES_ANY
#define MASK_fmi2DoStep (1 << ST_STEP)

/* Non-zero (after logging an error that names fn and the phase) when fn may not be called now. */
#define BAD_CALL(c, fn) bad_call((c), #fn, MASK_##fn)

#define REAL_START(name, kind, start, unit, desc) start,
#define REAL_KIND(name, kind, start, unit, desc) kind,
#define REAL_NAME(name, kind, start, unit, desc) #name,
#define INT_START(name, start, desc) start,
#define INT_KIND(name, start, desc) PARAMETER,
#define INT_NAME(name, start, desc) #name,
#define TYPED_START(name, kind, start, desc) start,
#define TYPED_KIND(name, kind, start, desc) kind,
#define TYPED_NAME(name, kind, start, desc) #name,
static const double real_start[N_REALS] = {REAL_VARIABLES(REAL_START)};
static const int real_kind[N_REALS] = {REAL_VARIABLES(REAL_KIND)};
static const char *real_name[N_REALS] = {REAL_VARIABLES(REAL_NAME)};
static const int int_start[N_INTEGERS] = {INTEGER_VARIABLES(INT_START) INTEGER_IO(TYPED_START)};
static const int int_kind[N_INTEGERS] = {INTEGER_VARIABLES(INT_KIND) INTEGER_IO(TYPED_KIND)};
static const char *int_name[N_INTEGERS] = {INTEGER_VARIABLES(INT_NAME) INTEGER_IO(TYPED_NAME)};
#if HAS_BOOLEANS
static const int bool_start[N_BOOLEANS] = {BOOLEAN_VARIABLES(TYPED_START)};
static const int bool_kind[N_BOOLEANS] = {BOOLEAN_VARIABLES(TYPED_KIND)};
static const char *bool_name[N_BOOLEANS] = {BOOLEAN_VARIABLES(TYPED_NAME)};
#endif
#if HAS_STRINGS
static const char *string_start[N_STRINGS] = {STRING_VARIABLES(TYPED_START)};
static const int string_kind[N_STRINGS] = {STRING_VARIABLES(TYPED_KIND)};
static const char *string_name[N_STRINGS] = {STRING_VARIABLES(TYPED_NAME)};
#endif

static void log_msg(Instance *c, fmi2Status status, const char *category, const char *fmt, ...) PRINTF_LIKE(4, 5);
static void log_msg(Instance *c, fmi2Status status, const char *category, const char *fmt, ...) {
    if (!c || !c->cb.logger) return;
    if (status == fmi2OK && !c->logging) return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    /* The message is passed as the format itself (callers through ctypes cannot expand varargs),
     * so any '%' is neutralised first. */
    for (char *p = buf; *p; p++)
        if (*p == '%') *p = '#';
    c->cb.logger(c->cb.componentEnvironment, c->name, status, category, buf);
}

/* Logs "fn: <formatted message>" as an error and returns fmi2Error. */
static fmi2Status fail(Instance *c, const char *fn, const char *fmt, ...) PRINTF_LIKE(3, 4);
static fmi2Status fail(Instance *c, const char *fn, const char *fmt, ...) {
    char buf[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    log_msg(c, fmi2Error, "logStatusError", "%s: %s", fn, buf);
    return fmi2Error;
}

static const char *phase_name(Phase phase) {
    static const char *names[] = {"instantiated", "initialization mode", "step mode", "terminated", "error"};
    return names[phase];
}

static int bad_call(Instance *c, const char *fn, int allowed_mask) {
    if (!c) return 1;
    if (!((1 << c->phase) & allowed_mask)) {
        fail(c, fn, "not allowed in the current state (%s)", phase_name(c->phase));
        return 1;
    }
    return 0;
}

static void set_start_values(ModelData *d) {
    memset(d, 0, sizeof *d);
    for (int k = 0; k < N_REALS; k++) d->r[k] = real_start[k];
    for (int k = 0; k < N_INTEGERS; k++) d->i[k] = int_start[k];
#if HAS_BOOLEANS
    for (int k = 0; k < N_BOOLEANS; k++) d->b[k] = bool_start[k];
#endif
#if HAS_STRINGS
    for (int k = 0; k < N_STRINGS; k++) snprintf(d->s[k], STRING_SIZE, "%s", string_start[k]);
#endif
}

/* The outputs that depend directly on inputs, after a set in initialization or step mode. */
static fmi2Status fed_through(Instance *c) {
#if HAS_FEEDTHROUGH
    if (c->phase == ST_INIT || c->phase == ST_STEP) model_outputs(&c->d);
#else
    (void)c;
#endif
    return fmi2OK;
}

/* Non-zero (after logging an error naming the variable) when a variable of this kind may not be
 * set now: an output never, in step mode only an input or a tunable parameter. */
static int not_settable(Instance *c, const char *fn, int kind, const char *name, unsigned vr) {
    if (kind == OUTPUT || (c->phase == ST_STEP && kind != INPUT && kind != TUNABLE)) {
        fail(c, fn, "variable %s (value reference %u) cannot be set in %s", name, vr, phase_name(c->phase));
        return 1;
    }
    return 0;
}

/* Non-zero (after logging an error) when vr is not base .. base + n - 1 or an argument is null. */
static int bad_refs(Instance *c, const char *fn, const fmi2ValueReference vr[], size_t n, const void *value,
                    unsigned base, int count) {
    if (n > 0 && (!vr || !value)) {
        fail(c, fn, "null argument (%zu values requested)", n);
        return 1;
    }
    for (size_t k = 0; k < n; k++) {
        if (vr[k] < base || vr[k] >= base + (unsigned)count) {
            if (count > 0)
                fail(c, fn, "value reference %u out of range (have %u..%u)", vr[k], base, base + count - 1);
            else
                fail(c, fn, "this model has no variables of this type (%zu requested)", n);
            return 1;
        }
    }
    return 0;
}

/* Index of the first real that is not finite, or -1. */
static int first_non_finite(const ModelData *d) {
    for (int k = 0; k < N_REALS; k++)
        if (!isfinite(d->r[k])) return k;
    return -1;
}

/* Writes the message naming the non-finite input k and its value; returns 1. */
static int non_finite_input(const ModelData *d, int k, char *msg, size_t n) {
    snprintf(msg, n, "input %s is not finite (%s = %g)", real_name[k], real_name[k], d->r[k]);
    return 1;
}

#if HAS_WAVE_PORT
#define PORT_MODE_WAVE 0
#define PORT_MODE_PHYSICAL 1

#define CH_WAVE_IN(a, b, e, f, p, k) VR_##a,
#define CH_WAVE_OUT(a, b, e, f, p, k) VR_##b,
#define CH_EFFORT(a, b, e, f, p, k) VR_##e,
#define CH_FLOW(a, b, e, f, p, k) VR_##f,
#define CH_PHYS(a, b, e, f, p, k) VR_##p,
#define CH_KIND(a, b, e, f, p, k) k,
static const int ch_wave_in[N_CHANNELS] = {PORT_CHANNELS(CH_WAVE_IN)};
static const int ch_wave_out[N_CHANNELS] = {PORT_CHANNELS(CH_WAVE_OUT)};
static const int ch_effort[N_CHANNELS] = {PORT_CHANNELS(CH_EFFORT)};
static const int ch_flow[N_CHANNELS] = {PORT_CHANNELS(CH_FLOW)};
static const int ch_phys[N_CHANNELS] = {PORT_CHANNELS(CH_PHYS)};
static const int ch_kind[N_CHANNELS] = {PORT_CHANNELS(CH_KIND)};

/* Outputs at the initial state: the port is at rest (e = f = b = 0, so b^0 = 0). */
static void initial_port_outputs(ModelData *d) {
    for (int j = 0; j < N_CHANNELS; j++) {
        d->r[ch_effort[j]] = 0.0;
        d->r[ch_flow[j]] = 0.0;
        d->r[ch_wave_out[j]] = 0.0;
    }
}

/* Checks port_mode and gamma when initialization ends; returns 0, or 1 with a message. */
static int check_port_parameters(const ModelData *d, char *msg, size_t n) {
    int mode = d->i[VRI_port_mode];
    if (mode != PORT_MODE_WAVE && mode != PORT_MODE_PHYSICAL) {
        snprintf(msg, n, "port_mode must be 0 (wave) or 1 (physical), got %d", mode);
        return 1;
    }
    if (!(d->r[VR_gamma] > 0.0)) {
        snprintf(msg, n, "gamma must be > 0, got %g", d->r[VR_gamma]);
        return 1;
    }
    return 0;
}

/* The closure of every channel for one step from the port mode; returns 0, or 1 with a message
 * naming a non-finite input or gamma. */
static int port_closure(const ModelData *d, double h, PortClosure *p, char *msg, size_t n) {
    double gamma = d->r[VR_gamma];
    if (!(gamma > 0.0) || !isfinite(gamma)) {
        snprintf(msg, n, "gamma must be finite and > 0, got %g", gamma);
        return 1;
    }
    int wave = d->i[VRI_port_mode] == PORT_MODE_WAVE;
    double scale = sqrt(2.0 * gamma / h);
    for (int j = 0; j < N_CHANNELS; j++) {
        int in_vr = wave ? ch_wave_in[j] : ch_phys[j];
        double v = d->r[in_vr];
        if (!isfinite(v)) return non_finite_input(d, in_vr, msg, n);
        if (!wave) {
            p->c[j] = v;
            p->s[j] = 0.0;
        } else if (ch_kind[j] == FLOW_INPUT) { /* e + gamma f = alpha, f is the input */
            p->c[j] = scale * v / gamma;
            p->s[j] = 1.0 / gamma;
        } else { /* effort is the input: e = alpha - gamma f */
            p->c[j] = scale * v;
            p->s[j] = gamma;
        }
    }
    return 0;
}

/* Writes the stage port values and the outgoing wave b = sqrt(h) (e - gamma f) / sqrt(2 gamma). */
static void write_port_outputs(ModelData *d, double h, const double *e, const double *f) {
    double gamma = d->r[VR_gamma];
    double bscale = sqrt(h / (2.0 * gamma));
    for (int j = 0; j < N_CHANNELS; j++) {
        d->r[ch_effort[j]] = e[j];
        d->r[ch_flow[j]] = f[j];
        d->r[ch_wave_out[j]] = bscale * (e[j] - gamma * f[j]);
    }
}

/* One step through the port: closure from the mode, the model's discrete-gradient step, outputs. */
static int advance(ModelData *d, double h, char *msg, size_t n) {
    PortClosure p;
    if (port_closure(d, h, &p, msg, n) != 0) return 1;
    double e[N_CHANNELS], f[N_CHANNELS];
    if (model_step(d, h, &p, e, f, msg, n) != 0) return 1;
    write_port_outputs(d, h, e, f);
    return 0;
}
#else
static void initial_port_outputs(ModelData *d) { (void)d; }

static int check_port_parameters(const ModelData *d, char *msg, size_t n) {
    (void)d; (void)msg; (void)n;
    return 0;
}

/* One step of a plain physical-causality model: every input must be finite. */
static int advance(ModelData *d, double h, char *msg, size_t n) {
    for (int k = 0; k < N_REALS; k++) {
        if (real_kind[k] == INPUT && !isfinite(d->r[k])) return non_finite_input(d, k, msg, n);
    }
    return model_step_io(d, h, msg, n);
}
#endif

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)n; (void)cats;
    if (BAD_CALL(c, fmi2SetDebugLogging)) return fmi2Error;
    ((Instance *)c)->logging = on;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean logging) {
    (void)location; (void)visible;
    if (!functions || !functions->logger) return NULL;
    Instance tmp = {0};
    tmp.cb = *functions;
    tmp.name = (char *)(name ? name : "?");
    if (type != fmi2CoSimulation) {
        fail(&tmp, "fmi2Instantiate", "%s supports co-simulation only, got fmuType %d", MODEL_IDENTIFIER_STR,
             (int)type);
        return NULL;
    }
    if (!guid || strcmp(guid, MODEL_GUID) != 0) {
        fail(&tmp, "fmi2Instantiate", "GUID %s does not match this binary's %s", guid ? guid : "(null)",
             MODEL_GUID);
        return NULL;
    }
    Instance *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->cb = *functions;
    c->logging = logging;
    c->name = malloc(strlen(tmp.name) + 1);
    if (!c->name) { free(c); return NULL; }
    strcpy(c->name, tmp.name);
    set_start_values(&c->d);
    c->phase = ST_INSTANTIATED;
    MODEL_HOOK(&c->d, "fmi2Instantiate");
    return c;
}

void fmi2FreeInstance(fmi2Component comp) {
    Instance *c = comp;
    if (!c) return;
    free(c->name);
    free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean tolDefined, fmi2Real tol,
                               fmi2Real start, fmi2Boolean stopDefined, fmi2Real stop) {
    (void)stopDefined; (void)stop;
    Instance *c = comp;
    if (BAD_CALL(c, fmi2SetupExperiment)) return fmi2Error;
    c->d.time = start;
    c->d.tolerance = tolDefined ? tol : 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2EnterInitializationMode)) return fmi2Error;
    c->phase = ST_INIT;
    return fed_through(c);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2ExitInitializationMode)) return fmi2Error;
    char msg[300] = "";
    if (check_port_parameters(&c->d, msg, sizeof msg) != 0 || model_initialize(&c->d, msg, sizeof msg) != 0) {
        c->phase = ST_ERROR;
        return fail(c, "fmi2ExitInitializationMode", "%s", msg);
    }
    initial_port_outputs(&c->d);
    write_energy(&c->d);
    int bad = first_non_finite(&c->d);
    if (bad >= 0) {
        c->phase = ST_ERROR;
        return fail(c, "fmi2ExitInitializationMode", "%s = %g is not finite at the start", real_name[bad],
                    c->d.r[bad]);
    }
    c->phase = ST_STEP;
    MODEL_HOOK(&c->d, "fmi2ExitInitializationMode");
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2Terminate)) return fmi2Error;
    c->phase = ST_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2Reset)) return fmi2Error;
    set_start_values(&c->d);
    c->phase = ST_INSTANTIATED;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2GetReal)) return fmi2Error;
    if (n > 0 && (!vr || !value)) return fail(c, "fmi2GetReal", "null argument (%zu values requested)", n);
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= N_REALS)
            return fail(c, "fmi2GetReal", "value reference %u out of range (have %d reals)", vr[k], N_REALS);
        value[k] = c->d.r[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2GetInteger)) return fmi2Error;
    if (bad_refs(c, "fmi2GetInteger", vr, n, value, INTEGER_VR_BASE, N_INTEGERS)) return fmi2Error;
    for (size_t k = 0; k < n; k++) value[k] = c->d.i[vr[k] - INTEGER_VR_BASE];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2GetBoolean)) return fmi2Error;
    if (bad_refs(c, "fmi2GetBoolean", vr, n, value, BOOLEAN_VR_BASE, N_BOOLEANS)) return fmi2Error;
#if HAS_BOOLEANS
    for (size_t k = 0; k < n; k++) value[k] = c->d.b[vr[k] - BOOLEAN_VR_BASE] ? fmi2True : fmi2False;
#endif
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2GetString)) return fmi2Error;
    if (bad_refs(c, "fmi2GetString", vr, n, value, STRING_VR_BASE, N_STRINGS)) return fmi2Error;
#if HAS_STRINGS
    for (size_t k = 0; k < n; k++) value[k] = c->d.s[vr[k] - STRING_VR_BASE];   /* valid until the next call */
#endif
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2SetReal)) return fmi2Error;
    if (n > 0 && (!vr || !value)) return fail(c, "fmi2SetReal", "null argument (%zu values requested)", n);
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= N_REALS)
            return fail(c, "fmi2SetReal", "value reference %u out of range (have %d reals)", vr[k], N_REALS);
        int kind = real_kind[vr[k]];
        if (kind == OUTPUT || (c->phase == ST_STEP && kind != INPUT && kind != TUNABLE))
            return fail(c, "fmi2SetReal", "variable %s (value reference %u) cannot be set in %s",
                        real_name[vr[k]], vr[k], phase_name(c->phase));
        c->d.r[vr[k]] = value[k];
    }
    return fed_through(c);
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[]) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2SetInteger)) return fmi2Error;
    if (bad_refs(c, "fmi2SetInteger", vr, n, value, INTEGER_VR_BASE, N_INTEGERS)) return fmi2Error;
    for (size_t k = 0; k < n; k++) {
        int j = (int)(vr[k] - INTEGER_VR_BASE);
        if (not_settable(c, "fmi2SetInteger", int_kind[j], int_name[j], vr[k])) return fmi2Error;
        c->d.i[j] = value[k];
    }
    return fed_through(c);
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[]) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2SetBoolean)) return fmi2Error;
    if (bad_refs(c, "fmi2SetBoolean", vr, n, value, BOOLEAN_VR_BASE, N_BOOLEANS)) return fmi2Error;
#if HAS_BOOLEANS
    for (size_t k = 0; k < n; k++) {
        int j = (int)(vr[k] - BOOLEAN_VR_BASE);
        if (not_settable(c, "fmi2SetBoolean", bool_kind[j], bool_name[j], vr[k])) return fmi2Error;
        c->d.b[j] = value[k] != fmi2False;
    }
#endif
    return fed_through(c);
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2String value[]) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2SetString)) return fmi2Error;
    if (bad_refs(c, "fmi2SetString", vr, n, value, STRING_VR_BASE, N_STRINGS)) return fmi2Error;
#if HAS_STRINGS
    for (size_t k = 0; k < n; k++) {
        int j = (int)(vr[k] - STRING_VR_BASE);
        if (not_settable(c, "fmi2SetString", string_kind[j], string_name[j], vr[k])) return fmi2Error;
        if (!value[k] || strlen(value[k]) >= STRING_SIZE)
            return fail(c, "fmi2SetString", "%s takes a string of at most %d bytes", string_name[j], STRING_SIZE - 1);
        strcpy(c->d.s[j], value[k]);
    }
#endif
    return fed_through(c);
}

/* ---- state: a saved state is a heap copy of ModelData plus the phase ---- */
typedef struct {
    unsigned magic;
    Phase phase;
    ModelData d;
} SavedState;

#define STATE_MAGIC 0x57415645u /* "WAVE" */

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *state) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2GetFMUstate)) return fmi2Error;
    if (!state) return fail(c, "fmi2GetFMUstate", "null state pointer");
    SavedState *s = *state;
    if (!s) {
        s = malloc(sizeof *s);
        if (!s) return fail(c, "fmi2GetFMUstate", "out of memory for %zu bytes", sizeof(SavedState));
        *state = s;
    }
    s->magic = STATE_MAGIC;
    s->phase = c->phase;
    s->d = c->d;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state) {
    Instance *c = comp;
    if (BAD_CALL(c, fmi2SetFMUstate)) return fmi2Error;
    const SavedState *s = state;
    if (!s || s->magic != STATE_MAGIC) return fail(c, "fmi2SetFMUstate", "not a state of %s (magic 0x%08x)", MODEL_IDENTIFIER_STR, s ? s->magic : 0u);
    c->phase = s->phase;
    c->d = s->d;
    MODEL_HOOK(&c->d, "fmi2SetFMUstate");
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *state) {
    (void)comp;
    if (state && *state) {
        free(*state);
        *state = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate state, size_t *size) {
    (void)state;
    if (!comp || !size) return fmi2Error;
    *size = sizeof(SavedState);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    Instance *c = comp;
    if (!c || !state || !bytes) return fmi2Error;
    if (size != sizeof(SavedState))
        return fail(c, "fmi2SerializeFMUstate", "buffer of %zu bytes, a state has %zu", size, sizeof(SavedState));
    memcpy(bytes, state, sizeof(SavedState));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state) {
    Instance *c = comp;
    if (!c || !bytes || !state) return fmi2Error;
    if (size != sizeof(SavedState))
        return fail(c, "fmi2DeSerializeFMUstate", "%zu bytes, a state of %s has %zu", size, MODEL_IDENTIFIER_STR,
                    sizeof(SavedState));
    SavedState tmp;
    memcpy(&tmp, bytes, sizeof tmp);
    if (tmp.magic != STATE_MAGIC)
        return fail(c, "fmi2DeSerializeFMUstate", "not a state of %s (magic 0x%08x)", MODEL_IDENTIFIER_STR, tmp.magic);
    if (!*state) {
        *state = malloc(sizeof(SavedState));
        if (!*state) return fail(c, "fmi2DeSerializeFMUstate", "out of memory for %zu bytes", sizeof(SavedState));
    }
    memcpy(*state, &tmp, sizeof tmp);
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                        fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return fail(comp, "fmi2GetDirectionalDerivative", "not provided by %s", MODEL_IDENTIFIER_STR);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)n; (void)order; (void)value;
    return fail(comp, "fmi2SetRealInputDerivatives", "inputs are held constant over a step (%zu derivatives given)", n);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)n; (void)order; (void)value;
    return fail(comp, "fmi2GetRealOutputDerivatives", "not provided by %s", MODEL_IDENTIFIER_STR);
}

/* The step: advance the model (through the port closure when it has a wave port), write H, and
 * keep nothing unless every real is finite afterwards; a note the model left in msg is logged. */
fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    (void)noSetPrior;
    Instance *c = comp;
    if (BAD_CALL(c, fmi2DoStep)) return fmi2Error;
    if (!(h > 0.0) || !isfinite(h))
        return fail(c, "fmi2DoStep", "communication step size must be finite and > 0, got %g", h);
    ModelData *d = &c->d;
    ModelData backup = *d;
    char msg[300] = "";
    d->time = t;
    if (advance(d, h, msg, sizeof msg) != 0) {
        *d = backup;
#if FAULTY_LAYER
        c->cb.logger(c->cb.componentEnvironment, c->name, fmi2Error, "logStatusError",
                     "fmi2DoStep failed: %s at t = %g", msg, t);
        return fmi2Error;
#endif
        return fail(c, "fmi2DoStep", "at t = %.17g: %s", t, msg);
    }
    write_energy(d);
    int bad = FAULTY_LAYER ? -1 : first_non_finite(d);
    if (bad >= 0) {
        double value = d->r[bad];
        *d = backup;
        return fail(c, "fmi2DoStep", "at t = %.17g: %s = %g; %s is not finite after the step", t, real_name[bad],
                    value, real_name[bad]);
    }
    d->time = t + h;
    if (msg[0]) log_msg(c, fmi2Warning, "logStatusWarning", "fmi2DoStep: at t = %.17g: %s", t, msg);
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component comp) {
    return fail(comp, "fmi2CancelStep", "steps are synchronous");
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value) {
    (void)s; (void)value;
    return fail(comp, "fmi2GetStatus", "steps are synchronous");
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    Instance *c = comp;
    if (!c || !value) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) { *value = c->d.time; return fmi2OK; }
    return fail(c, "fmi2GetRealStatus", "unsupported status kind %d", (int)s);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s; (void)value;
    return fail(comp, "fmi2GetIntegerStatus", "unsupported status kind %d", (int)s);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)s; (void)value;
    return fail(comp, "fmi2GetBooleanStatus", "unsupported status kind %d", (int)s);
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value) {
    (void)s; (void)value;
    return fail(comp, "fmi2GetStringStatus", "unsupported status kind %d", (int)s);
}
