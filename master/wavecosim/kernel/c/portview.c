/* Physical ports on the kernel route (portview.h): a signed port as an fmi2 shim, and the view the
 * runner reads a physical port through after each commit. Both mirror wavecosim/core/ports.py and
 * readings.py operation by operation (products by +-1.0, the wave b = k (e - gamma f)), compiled
 * with -ffp-contract=off, so the numbers are the Python reference's to the last bit. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmicall.h"
#include "portview.h"

/* ---- the signed port: ports.DirectPort with in_scale and out_scale ---- */

struct SignedPort {
    DRFunctions fn;                /* the FMU's own */
    fmi2Component comp;
    size_t m;
    double *in_scale, *out_scale, *values;      /* m each */
};

SignedPort *sp_create(const DRFunctions *fn, fmi2Component comp, int m, const double *in_scale,
                      const double *out_scale) {
    if (m < 1) return NULL;
    SignedPort *p = calloc(1, sizeof *p);
    double *buf = calloc(3 * (size_t)m, sizeof(double));
    if (!p || !buf) {
        free(p);
        free(buf);
        return NULL;
    }
    p->fn = *fn;
    p->comp = comp;
    p->m = (size_t)m;
    p->in_scale = buf;
    p->out_scale = buf + m;
    p->values = buf + 2 * m;
    memcpy(p->in_scale, in_scale, (size_t)m * sizeof(double));
    memcpy(p->out_scale, out_scale, (size_t)m * sizeof(double));
    return p;
}

void sp_destroy(SignedPort *p) {
    if (!p) return;
    free(p->in_scale);
    free(p);
}

static fmi2Status sp_getFMUstate(fmi2Component c, fmi2FMUstate *state) {
    SignedPort *p = c;
    return p->fn.getFMUstate(p->comp, state);
}

static fmi2Status sp_setFMUstate(fmi2Component c, fmi2FMUstate state) {
    SignedPort *p = c;
    return p->fn.setFMUstate(p->comp, state);
}

static fmi2Status sp_freeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    SignedPort *p = c;
    return p->fn.freeFMUstate(p->comp, state);
}

/* DirectPort._through: the FMU gets s u on its inputs. */
static fmi2Status sp_setReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    SignedPort *p = c;
    if (nvr > p->m) return fmi2Error;
    for (size_t j = 0; j < nvr; j++) p->values[j] = p->in_scale[j] * value[j];
    return p->fn.setReal(p->comp, vr, nvr, p->values);
}

static fmi2Status sp_doStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    SignedPort *p = c;
    return p->fn.doStep(p->comp, t, h, no_prior);
}

/* DirectPort._through: the master gets s y of the FMU's outputs. */
static fmi2Status sp_getReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    SignedPort *p = c;
    if (nvr > p->m) return fmi2Error;
    fmi2Status status = p->fn.getReal(p->comp, vr, nvr, value);
    if (!fmi_fails(status))
        for (size_t j = 0; j < nvr; j++) value[j] = p->out_scale[j] * value[j];
    return status;
}

void sp_functions(DRFunctions *fn) {
    fn->getFMUstate = sp_getFMUstate;
    fn->setFMUstate = sp_setFMUstate;
    fn->freeFMUstate = sp_freeFMUstate;
    fn->setReal = sp_setReal;
    fn->doStep = sp_doStep;
    fn->getReal = sp_getReal;
}

/* ---- the observed view of a physical port: readings.Sampler._physical_part ---- */

struct PortView {
    fmi2GetRealTYPE *get;          /* the FMU's own getReal */
    fmi2Component comp;
    fmi2ValueReference *vr;        /* [H,] effort (m), flow (m), outputs (n_out) */
    size_t m, n_out, n_raw, size;  /* size: pv_size */
    int has_H;
    double *sign;                  /* m: power into the FMU = sign e f */
    const double *gamma, *k;       /* the wave adapter's impedance (its struct's fields), or NULL */
    double *raw;                   /* n_raw */
};

PortView *pv_create(fmi2GetRealTYPE *get, fmi2Component comp, const fmi2ValueReference *vr, int has_H, int m,
                    int n_out, const double *sign, const double *gamma, const double *k) {
    if (m < 1 || n_out < 0 || !get) return NULL;
    PortView *v = calloc(1, sizeof *v);
    size_t n_raw = (has_H ? 1 : 0) + 2 * (size_t)m + (size_t)n_out;
    if (!v) return NULL;
    v->vr = malloc(n_raw * sizeof *v->vr);
    v->sign = malloc((size_t)m * sizeof(double));
    v->raw = malloc(n_raw * sizeof(double));
    if (!v->vr || !v->sign || !v->raw) {
        pv_destroy(v);
        return NULL;
    }
    memcpy(v->vr, vr, n_raw * sizeof *vr);
    memcpy(v->sign, sign, (size_t)m * sizeof(double));
    v->get = get;
    v->comp = comp;
    v->m = (size_t)m;
    v->n_out = (size_t)n_out;
    v->n_raw = n_raw;
    v->has_H = has_H;
    v->gamma = gamma;
    v->k = k;
    v->size = 1 + 2 * v->m + (k ? v->m : 0) + v->n_out;
    return v;
}

size_t pv_size(const PortView *v) { return v->size; }

/* One raw read, then [H or NaN, e, sign f, (adapter) k (e - gamma f), outputs] into value (pv_size). */
fmi2Status pv_getReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    (void)vr;
    PortView *v = c;
    size_t m = v->m, h = v->has_H ? 1 : 0;
    if (nvr != v->size) return fmi2Error;
    fmi2Status status = v->get(v->comp, v->vr, v->n_raw, v->raw);
    if (fmi_fails(status)) return status;
    const double *e = v->raw + h, *f = e + m;
    double *out = value;
    *out++ = h ? v->raw[0] : NAN;
    for (size_t j = 0; j < m; j++) out[j] = e[j];
    for (size_t j = 0; j < m; j++) out[m + j] = v->sign[j] * f[j];
    out += 2 * m;
    if (v->k) {
        for (size_t j = 0; j < m; j++) out[j] = *v->k * (e[j] - *v->gamma * value[1 + m + j]);
        out += m;
    }
    copy_doubles(out, f + m, v->n_out);
    return status;
}

void pv_destroy(PortView *v) {
    if (!v) return;
    free(v->vr);
    free(v->sign);
    free(v->raw);
    free(v);
}
