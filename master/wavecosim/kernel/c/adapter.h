/* The wave adapter (paper eq. 12 for an FMU with only a physical port) in C, as a shim with the
 * fmi2 signatures the DR kernel calls (DRFunctions in drkernel.h): its fmi2Component is a
 * WaveAdapterC wrapping the FMU's own function table and component (or any other table with the
 * fmi2 contract, e.g. a shim over FMI 3). The kernel sees a wave port:
 *   setReal(w, vr, m, a)   stores the incident waves a (value reference j = channel j);
 *   doStep(w, t, h, ...)   solves the held input u with e + gamma f = c a after one doStep of the
 *                          FMU from x_i^n (restoring x_i^n between its own doSteps);
 *   getReal(w, vr, m, b)   returns b = k (e - gamma f);
 *   getFMUstate(w, &s)     saves x_i^n into s (the FMU's own handle) and starts a macro-step;
 *   setFMUstate(w, s)      marks the FMU as moved away from x_i^n (the next doStep restores it);
 *   freeFMUstate(w, &s)    frees the FMU's handle.
 * The arithmetic mirrors wavecosim/core/ports.py::WaveAdapter operation by operation (compiled with
 * -ffp-contract=off), so both give the same numbers to the last bit. The struct is allocated and
 * filled by the caller (wavecosim/kernel/adapter.py mirrors its layout with ctypes); the adapter
 * allocates nothing.
 */
#ifndef WAVECOSIM_ADAPTER_H
#define WAVECOSIM_ADAPTER_H

#include "fmicall.h"

/* WaveAdapterC.failure */
enum { AD_OK = 0, AD_FMU = 1, AD_SINGULAR = 2, AD_STALLED = 3 };

typedef struct {
    /* the FMU (set by the caller) */
    DRFunctions fn;
    fmi2Component comp;
    fmi2FMUstate *state;             /* the handle x_i^n is saved in and restored from */
    const fmi2ValueReference *in_vr, *out_vr;   /* the FMU's physical input and output, m each */
    int m;
    int no_prior;                    /* noSetFMUStatePriorToCurrentPoint of the FMU's doSteps */
    const int *effort_in;            /* channel j: the FMU's input is the effort (else the flow) */
    const double *sign;              /* power into the FMU = sign e f, per channel */
    /* the waves' impedance (set by the caller, wavecosim/core/ports.py::AdapterPort.weights) */
    double gamma, c, k;
    const double *wu, *wy;
    /* limits (wavecosim/core/ports.py's constants) */
    double tol, accept, slope_rel;
    int max_iter, stall;
    /* the solver's memory (ports.py::WaveAdapter's attributes; D and J_inv m x m row-major) */
    int *dirty;                      /* the FMU moved away from x_i^n: the Subsystem's own flag (Subsystem._dirty) */
    int have_slope;                  /* y, D and J_inv hold for this macro-step */
    double *u, *y, *D, *J_inv;
    double h2, u_scale;
    long evaluations, do_steps, accepted;
    double worst_accepted;
    /* one query */
    double *a, *e, *f, *b;           /* incident wave, stage effort and flow, outgoing wave */
    /* the failure of the last query: AD_*, the FMU call (fmicall.h: its DR_FN_* and status), residual */
    int failure;
    FmiFailure failed;
    double failed_rel;
    double *failed_r;
    double *work;                    /* scratch: adapter_work_size(m) doubles */
} WaveAdapterC;

/* Doubles of scratch a WaveAdapterC of m channels needs in `work`. */
size_t adapter_work_size(int m);

/* New impedance (c, k, wu, wy already set by the caller): the Newton matrix follows if a slope is
 * held. Returns fmi2OK, or fmi2Error with failure = AD_SINGULAR. */
fmi2Status adapter_reinvert(WaveAdapterC *w);

/* S_i^n(a) with a in w->a: e, f and b of the solved step; the FMU is left at Phi(x_i^n, u). */
fmi2Status adapter_solve(WaveAdapterC *w, double t, double h);

/* The fmi2 shim (see above). */
fmi2Status adapter_getFMUstate(fmi2Component c, fmi2FMUstate *state);
fmi2Status adapter_setFMUstate(fmi2Component c, fmi2FMUstate state);
fmi2Status adapter_freeFMUstate(fmi2Component c, fmi2FMUstate *state);
fmi2Status adapter_setReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]);
fmi2Status adapter_doStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior);
fmi2Status adapter_getReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]);

#endif
