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

#define PORT_MODE_WAVE 0
#define PORT_MODE_PHYSICAL 1

typedef enum { ST_INSTANTIATED, ST_INIT, ST_STEP, ST_TERMINATED, ST_ERROR } Phase;

typedef struct {
    ModelData d;
    Phase phase;
    char *name;
    fmi2CallbackFunctions cb;
    fmi2Boolean logging;
} Instance;

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

#define REAL_START(name, kind, start, unit, desc) start,
#define REAL_KIND(name, kind, start, unit, desc) kind,
#define REAL_NAME(name, kind, start, unit, desc) #name,
#define INT_START(name, start, desc) start,
#define INT_NAME(name, start, desc) #name,
static const double real_start[N_REALS] = {REAL_VARIABLES(REAL_START)};
static const int real_kind[N_REALS] = {REAL_VARIABLES(REAL_KIND)};
static const char *real_name[N_REALS] = {REAL_VARIABLES(REAL_NAME)};
static const int int_start[N_INTEGERS] = {INTEGER_VARIABLES(INT_START)};
static const char *int_name[N_INTEGERS] = {INTEGER_VARIABLES(INT_NAME)};

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

static fmi2Status fail(Instance *c, const char *fn, const char *fmt, const char *detail) {
    char buf[400];
    snprintf(buf, sizeof buf, fmt, detail);
    log_msg(c, fmi2Error, "logStatusError", "%s: %s", fn, buf);
    return fmi2Error;
}

static int bad_call(Instance *c, const char *fn, int allowed_mask) {
    if (!c) return 1;
    if (!((1 << c->phase) & allowed_mask)) {
        fail(c, fn, "not allowed in the current state (%s)",
             c->phase == ST_ERROR ? "error" : c->phase == ST_TERMINATED ? "terminated" : "other");
        return 1;
    }
    return 0;
}

#define M_ANY ((1 << ST_INSTANTIATED) | (1 << ST_INIT) | (1 << ST_STEP) | (1 << ST_TERMINATED) | (1 << ST_ERROR))
#define M_SET_REAL ((1 << ST_INSTANTIATED) | (1 << ST_INIT) | (1 << ST_STEP))
#define M_GET ((1 << ST_INIT) | (1 << ST_STEP) | (1 << ST_TERMINATED) | (1 << ST_ERROR))
#define M_STEP (1 << ST_STEP)
#define M_STATE ((1 << ST_INSTANTIATED) | (1 << ST_INIT) | (1 << ST_STEP) | (1 << ST_TERMINATED) | (1 << ST_ERROR))

static void set_start_values(ModelData *d) {
    memset(d, 0, sizeof *d);
    for (int k = 0; k < N_REALS; k++) d->r[k] = real_start[k];
    for (int k = 0; k < N_INTEGERS; k++) d->i[k] = int_start[k];
}

/* Outputs at the initial state: the port is at rest (e = f = b = 0, so b^0 = 0). */
static void initial_outputs(ModelData *d) {
    for (int j = 0; j < N_CHANNELS; j++) {
        d->r[ch_effort[j]] = 0.0;
        d->r[ch_flow[j]] = 0.0;
        d->r[ch_wave_out[j]] = 0.0;
    }
    d->r[VR_H] = model_energy(d);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)n; (void)cats;
    if (!c) return fmi2Error;
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
        fail(&tmp, "fmi2Instantiate", "%s supports co-simulation only", MODEL_IDENTIFIER_STR);
        return NULL;
    }
    if (!guid || strcmp(guid, MODEL_GUID) != 0) {
        fail(&tmp, "fmi2Instantiate", "GUID %s does not match this binary", guid ? guid : "(null)");
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
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stop;
    Instance *c = comp;
    if (bad_call(c, "fmi2SetupExperiment", 1 << ST_INSTANTIATED)) return fmi2Error;
    c->d.time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    Instance *c = comp;
    if (bad_call(c, "fmi2EnterInitializationMode", 1 << ST_INSTANTIATED)) return fmi2Error;
    c->phase = ST_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    Instance *c = comp;
    if (bad_call(c, "fmi2ExitInitializationMode", 1 << ST_INIT)) return fmi2Error;
    int mode = c->d.i[VRI_port_mode];
    if (mode != PORT_MODE_WAVE && mode != PORT_MODE_PHYSICAL) {
        c->phase = ST_ERROR;
        return fail(c, "fmi2ExitInitializationMode", "port_mode must be 0 (wave) or 1 (physical), %s",
                    "got another value");
    }
    if (!(c->d.r[VR_gamma] > 0.0)) {
        c->phase = ST_ERROR;
        return fail(c, "fmi2ExitInitializationMode", "%s must be > 0", "gamma");
    }
    char msg[300] = "";
    if (model_initialize(&c->d, msg, sizeof msg) != 0) {
        c->phase = ST_ERROR;
        return fail(c, "fmi2ExitInitializationMode", "%s", msg);
    }
    initial_outputs(&c->d);
    for (int k = 0; k < N_REALS; k++) {
        if (!isfinite(c->d.r[k])) {
            c->phase = ST_ERROR;
            return fail(c, "fmi2ExitInitializationMode", "%s is not finite at the start", real_name[k]);
        }
    }
    c->phase = ST_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    Instance *c = comp;
    if (bad_call(c, "fmi2Terminate", (1 << ST_STEP) | (1 << ST_ERROR))) return fmi2Error;
    c->phase = ST_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    Instance *c = comp;
    if (bad_call(c, "fmi2Reset", M_ANY)) return fmi2Error;
    set_start_values(&c->d);
    c->phase = ST_INSTANTIATED;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Instance *c = comp;
    if (bad_call(c, "fmi2GetReal", M_GET | (1 << ST_INSTANTIATED))) return fmi2Error;
    if (n > 0 && (!vr || !value)) return fail(c, "fmi2GetReal", "%s", "null argument");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= N_REALS) return fail(c, "fmi2GetReal", "unknown value reference%s", "");
        value[k] = c->d.r[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
    Instance *c = comp;
    if (bad_call(c, "fmi2GetInteger", M_GET | (1 << ST_INSTANTIATED))) return fmi2Error;
    if (n > 0 && (!vr || !value)) return fail(c, "fmi2GetInteger", "%s", "null argument");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] < INTEGER_VR_BASE || vr[k] >= INTEGER_VR_BASE + N_INTEGERS)
            return fail(c, "fmi2GetInteger", "unknown value reference%s", "");
        value[k] = c->d.i[vr[k] - INTEGER_VR_BASE];
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]) {
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : fail(comp, "fmi2GetBoolean", "%s", "this model has no Boolean variables");
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : fail(comp, "fmi2GetString", "%s", "this model has no String variables");
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Instance *c = comp;
    if (bad_call(c, "fmi2SetReal", M_SET_REAL)) return fmi2Error;
    if (n > 0 && (!vr || !value)) return fail(c, "fmi2SetReal", "%s", "null argument");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= N_REALS) return fail(c, "fmi2SetReal", "unknown value reference%s", "");
        int kind = real_kind[vr[k]];
        if (kind == OUTPUT || (c->phase == ST_STEP && kind != INPUT && kind != TUNABLE))
            return fail(c, "fmi2SetReal", "variable %s cannot be set now", real_name[vr[k]]);
        c->d.r[vr[k]] = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[]) {
    Instance *c = comp;
    if (bad_call(c, "fmi2SetInteger", (1 << ST_INSTANTIATED) | (1 << ST_INIT))) return fmi2Error;
    if (n > 0 && (!vr || !value)) return fail(c, "fmi2SetInteger", "%s", "null argument");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] < INTEGER_VR_BASE || vr[k] >= INTEGER_VR_BASE + N_INTEGERS)
            return fail(c, "fmi2SetInteger", "unknown value reference%s", "");
        c->d.i[vr[k] - INTEGER_VR_BASE] = value[k];
    }
    (void)int_name;
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[]) {
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : fail(comp, "fmi2SetBoolean", "%s", "this model has no Boolean variables");
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2String value[]) {
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : fail(comp, "fmi2SetString", "%s", "this model has no String variables");
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
    if (bad_call(c, "fmi2GetFMUstate", M_STATE)) return fmi2Error;
    if (!state) return fail(c, "fmi2GetFMUstate", "%s", "null argument");
    SavedState *s = *state;
    if (!s) {
        s = malloc(sizeof *s);
        if (!s) return fail(c, "fmi2GetFMUstate", "%s", "out of memory");
        *state = s;
    }
    s->magic = STATE_MAGIC;
    s->phase = c->phase;
    s->d = c->d;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state) {
    Instance *c = comp;
    if (bad_call(c, "fmi2SetFMUstate", M_STATE)) return fmi2Error;
    const SavedState *s = state;
    if (!s || s->magic != STATE_MAGIC) return fail(c, "fmi2SetFMUstate", "%s", "not a state of this model");
    c->phase = s->phase;
    c->d = s->d;
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
    if (size != sizeof(SavedState)) return fail(c, "fmi2SerializeFMUstate", "%s", "wrong buffer size");
    memcpy(bytes, state, sizeof(SavedState));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state) {
    Instance *c = comp;
    if (!c || !bytes || !state) return fmi2Error;
    if (size != sizeof(SavedState)) return fail(c, "fmi2DeSerializeFMUstate", "%s", "wrong size for this model");
    SavedState tmp;
    memcpy(&tmp, bytes, sizeof tmp);
    if (tmp.magic != STATE_MAGIC) return fail(c, "fmi2DeSerializeFMUstate", "%s", "not a state of this model");
    if (!*state) {
        *state = malloc(sizeof(SavedState));
        if (!*state) return fail(c, "fmi2DeSerializeFMUstate", "%s", "out of memory");
    }
    memcpy(*state, &tmp, sizeof tmp);
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                        fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return fail(comp, "fmi2GetDirectionalDerivative", "%s", "not provided");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)n; (void)order; (void)value;
    return fail(comp, "fmi2SetRealInputDerivatives", "%s", "inputs are held constant over a step");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)n; (void)order; (void)value;
    return fail(comp, "fmi2GetRealOutputDerivatives", "%s", "not provided");
}

/* The step: pick the port closure from the mode, run the model's discrete-gradient step, then
 * write the stage port values and the outgoing wave b = sqrt(h) (e - gamma f) / sqrt(2 gamma). */
fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    (void)noSetPrior;
    Instance *c = comp;
    if (bad_call(c, "fmi2DoStep", M_STEP)) return fmi2Error;
    if (!(h > 0.0) || !isfinite(h)) return fail(c, "fmi2DoStep", "%s", "communication step size must be > 0");
    ModelData *d = &c->d;
    double gamma = d->r[VR_gamma];
    if (!(gamma > 0.0) || !isfinite(gamma)) return fail(c, "fmi2DoStep", "%s", "gamma must be finite and > 0");
    int wave = d->i[VRI_port_mode] == PORT_MODE_WAVE;
    PortClosure p;
    double scale = sqrt(2.0 * gamma / h);
    for (int j = 0; j < N_CHANNELS; j++) {
        int in_vr = wave ? ch_wave_in[j] : ch_phys[j];
        double v = d->r[in_vr];
        if (!isfinite(v)) return fail(c, "fmi2DoStep", "input %s is not finite", real_name[in_vr]);
        if (!wave) {
            p.c[j] = v;
            p.s[j] = 0.0;
        } else if (ch_kind[j] == FLOW_INPUT) { /* e + gamma f = alpha, f is the input */
            p.c[j] = scale * v / gamma;
            p.s[j] = 1.0 / gamma;
        } else { /* effort is the input: e = alpha - gamma f */
            p.c[j] = scale * v;
            p.s[j] = gamma;
        }
    }
    ModelData backup = *d;
    double e[N_CHANNELS], f[N_CHANNELS];
    char msg[300] = "";
    if (model_step(d, h, &p, e, f, msg, sizeof msg) != 0) {
        *d = backup;
        char where[360];
        snprintf(where, sizeof where, "at t = %.17g: %s", t, msg);
        return fail(c, "fmi2DoStep", "%s", where);
    }
    double bscale = sqrt(h / (2.0 * gamma));
    for (int j = 0; j < N_CHANNELS; j++) {
        d->r[ch_effort[j]] = e[j];
        d->r[ch_flow[j]] = f[j];
        d->r[ch_wave_out[j]] = bscale * (e[j] - gamma * f[j]);
    }
    d->r[VR_H] = model_energy(d);
    for (int k = 0; k < N_REALS; k++) {
        if (!isfinite(d->r[k])) {
            *d = backup;
            char where[200];
            snprintf(where, sizeof where, "at t = %.17g: %s is not finite after the step", t, real_name[k]);
            return fail(c, "fmi2DoStep", "%s", where);
        }
    }
    d->time = t + h;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component comp) {
    return fail(comp, "fmi2CancelStep", "%s", "steps are synchronous");
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value) {
    (void)s; (void)value;
    return fail(comp, "fmi2GetStatus", "%s", "steps are synchronous");
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    Instance *c = comp;
    if (!c || !value) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) { *value = c->d.time; return fmi2OK; }
    return fail(c, "fmi2GetRealStatus", "%s", "unsupported status kind");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s; (void)value;
    return fail(comp, "fmi2GetIntegerStatus", "%s", "unsupported status kind");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)s; (void)value;
    return fail(comp, "fmi2GetBooleanStatus", "%s", "unsupported status kind");
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value) {
    (void)s; (void)value;
    return fail(comp, "fmi2GetStringStatus", "%s", "unsupported status kind");
}
