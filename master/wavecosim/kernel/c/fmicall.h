/* The kernel's FMI call table: one wrapper per fmi2 function the kernel calls (drkernel.c, adapter.c,
 * signals.c, queries.c), each through the one status check, fmi_check, which records the function
 * that failed and the status it returned; the Python twin is wavecosim/fmi/fmu.py (Fmu.status_error).
 * Header only: every wrapper is inlined into its caller, so a call costs what the bare call costs. */
#ifndef WAVECOSIM_FMICALL_H
#define WAVECOSIM_FMICALL_H

#include "drkernel.h"
#include "linalg.h"

/* The FMU functions of the signals' Integer and Boolean calls, numbered past DR_FN_* (drkernel.h). */
enum { SG_FN_GET_INTEGER = 16, SG_FN_GET_BOOLEAN = 17, SG_FN_SET_INTEGER = 18, SG_FN_SET_BOOLEAN = 19 };

/* fmi2FreeFMUstate, as the call in progress names it (its failure is never reported). */
enum { FN_FREE_STATE = 20 };

/* The FMU call in progress: the component it was made with and its DR_FN_*, SG_FN_* or FN_*, 0 between
 * calls. A supervised run points fmi_call_now into the status page its parent shares
 * (wavecosim/kernel/fmicall.py trace_calls), so a watchdog that finds the process stuck in an FMU that
 * holds every signal names the subsystem and the call: two stores before a call, one after. */
typedef struct {
    void *volatile instance;
    volatile int function;
    int spare;
} FmiCallNow;

/* One per library (weak: every C file of a library shares it); its own slot until a run points it away. */
__attribute__((weak)) FmiCallNow fmi_call_idle;
__attribute__((weak)) FmiCallNow *volatile fmi_call_now = &fmi_call_idle;

/* The call `function` of component c begins. */
WC_INLINE void fmi_enter(fmi2Component c, int function) {
    FmiCallNow *now = fmi_call_now;
    now->instance = c;
    now->function = function;
}

/* The call returned its status: none is in progress. */
WC_INLINE fmi2Status fmi_leave(fmi2Status status) {
    fmi_call_now->function = 0;
    return status;
}

/* The FMU call that failed: its DR_FN_* or SG_FN_*, and the fmi2Status it returned. */
typedef struct {
    int function, status;
} FmiFailure;

/* Whether a status fails the call: worse than fmi2Warning (Discard, Error, Fatal, Pending). */
WC_INLINE int fmi_fails(fmi2Status status) { return status > fmi2Warning; }

/* The one status check: 0 when the call went through, else 1 with the function and status in *f. */
WC_INLINE int fmi_check(FmiFailure *f, int function, fmi2Status status) {
    if (!fmi_fails(status)) return 0;
    f->function = function;
    f->status = (int)status;
    return 1;
}

WC_INLINE int fmi_get_state(fmi2GetFMUstateTYPE *call, fmi2Component c, fmi2FMUstate *state, FmiFailure *f) {
    fmi_enter(c, DR_FN_GET_STATE);
    return fmi_check(f, DR_FN_GET_STATE, fmi_leave(call(c, state)));
}

WC_INLINE int fmi_set_state(fmi2SetFMUstateTYPE *call, fmi2Component c, fmi2FMUstate state, FmiFailure *f) {
    fmi_enter(c, DR_FN_SET_STATE);
    return fmi_check(f, DR_FN_SET_STATE, fmi_leave(call(c, state)));
}

/* Freeing a state is not checked: the handle is gone whatever the FMU answers. */
WC_INLINE void fmi_free_state(fmi2FreeFMUstateTYPE *call, fmi2Component c, fmi2FMUstate *state) {
    fmi_enter(c, FN_FREE_STATE);
    (void)fmi_leave(call(c, state));
}

WC_INLINE int fmi_do_step(fmi2DoStepTYPE *call, fmi2Component c, double t, double h, int no_prior, FmiFailure *f) {
    fmi_enter(c, DR_FN_DO_STEP);
    return fmi_check(f, DR_FN_DO_STEP, fmi_leave(call(c, t, h, no_prior ? fmi2True : fmi2False)));
}

WC_INLINE int fmi_get_real(fmi2GetRealTYPE *call, fmi2Component c, const fmi2ValueReference *vr, size_t n,
                           double *values, FmiFailure *f) {
    fmi_enter(c, DR_FN_GET_REAL);
    return fmi_check(f, DR_FN_GET_REAL, fmi_leave(call(c, vr, n, values)));
}

WC_INLINE int fmi_set_real(fmi2SetRealTYPE *call, fmi2Component c, const fmi2ValueReference *vr, size_t n,
                           const double *values, FmiFailure *f) {
    fmi_enter(c, DR_FN_SET_REAL);
    return fmi_check(f, DR_FN_SET_REAL, fmi_leave(call(c, vr, n, values)));
}

WC_INLINE int fmi_get_integer(fmi2GetIntegerTYPE *call, fmi2Component c, const fmi2ValueReference *vr, size_t n,
                              int *values, FmiFailure *f) {
    fmi_enter(c, SG_FN_GET_INTEGER);
    return fmi_check(f, SG_FN_GET_INTEGER, fmi_leave(call(c, vr, n, values)));
}

WC_INLINE int fmi_set_integer(fmi2SetIntegerTYPE *call, fmi2Component c, const fmi2ValueReference *vr, size_t n,
                              const int *values, FmiFailure *f) {
    fmi_enter(c, SG_FN_SET_INTEGER);
    return fmi_check(f, SG_FN_SET_INTEGER, fmi_leave(call(c, vr, n, values)));
}

WC_INLINE int fmi_get_boolean(fmi2GetBooleanTYPE *call, fmi2Component c, const fmi2ValueReference *vr, size_t n,
                              int *values, FmiFailure *f) {
    fmi_enter(c, SG_FN_GET_BOOLEAN);
    return fmi_check(f, SG_FN_GET_BOOLEAN, fmi_leave(call(c, vr, n, values)));
}

WC_INLINE int fmi_set_boolean(fmi2SetBooleanTYPE *call, fmi2Component c, const fmi2ValueReference *vr, size_t n,
                              const int *values, FmiFailure *f) {
    fmi_enter(c, SG_FN_SET_BOOLEAN);
    return fmi_check(f, SG_FN_SET_BOOLEAN, fmi_leave(call(c, vr, n, values)));
}

#endif
