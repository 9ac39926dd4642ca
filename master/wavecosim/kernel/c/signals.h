/* Signals, sources and subsystems stepped alone in the kernel's blocks (signals.c, in libdrkernel.so;
 * wavecosim/kernel/signals.py drives it through ctypes).
 *
 * An SGPlan attached to a DRKernel runs before each macro-step n of dr_run_steps_of what
 * wavecosim/core/scene.py's Scene.begin_step(n) does for Real signals: read every signal (one getReal
 * per driven group of FMU variables, or a source table's value at t_n given per block by
 * sg_set_table), scale it (factor * value + offset), check that all are finite, set them on their
 * inputs (one setReal per group, in the given order), then one doStep(t_n, dt, true) of each
 * subsystem stepped alone.
 * After the step it reads those subsystems' outputs into the log, after the subsystems' observed values.
 */
#ifndef WAVECOSIM_SIGNALS_H
#define WAVECOSIM_SIGNALS_H

#include "fmicall.h"
#include "kernel_internal.h"

/* One FMU's functions (its own fmi2 ones, or fmi3shim.c's) and instance; the Integer and Boolean
 * ones only where a signal reads or drives such a variable (an FMI 2 FMU), else NULL. */
typedef struct {
    fmi2GetRealTYPE *getReal;
    fmi2SetRealTYPE *setReal;
    fmi2DoStepTYPE *doStep;
    fmi2GetIntegerTYPE *getInteger;
    fmi2SetIntegerTYPE *setInteger;
    fmi2GetBooleanTYPE *getBoolean;
    fmi2SetBooleanTYPE *setBoolean;
    fmi2Component comp;
    long *calls;                 /* the FMU's call counters (fmicall.h FmiCall), or NULL: not counted */
} SGFmu;

/* The categories of values a signal carries (wavecosim/fmi/values.py): a call's type, an input's. */
enum SGType { SG_REAL = 0, SG_INTEGER = 1, SG_BOOLEAN = 2 };

/* One signal: its source table column (or -1: read by a get call), its input's category, the
 * scaling of a Real input (factor * value + offset) and the range of an integer one (lo .. hi). */
typedef struct {
    int column, to;
    double factor, offset, lo, hi;
} SGSignal;

/* SGFailure.kind */
enum { SG_OK = 0, SG_FMU = 1, SG_NONFINITE = 2, SG_NO_TABLE = 3 };

/* Why the last step's signals failed: an FMU call (index: the FMU; call: its DR_FN_* or SG_FN_* and
 * status, fmicall.h), a value its input cannot take (non-finite, an integer out of range; index: the
 * signal, value), or a table not given for the step. */
typedef struct {
    int kind, index;
    FmiFailure call;
    int step;
    double value;
} SGFailure;

typedef struct SGPlan SGPlan;

/* Over kernel k: n_fmus FMUs; n_signals signals (SGSignal: a table column or -1, read then by one of
 * the get calls); n_reads get calls, call g of type read_type[g] (SG_*) to FMU read_fmu[g] reading
 * read_vr[j] into signal read_signal[j] for j in read_start[g] .. read_start[g + 1); the n_writes set
 * calls alike (write_*); n_alone subsystems stepped alone, subsystem a being FMU alone_fmu[a] with
 * the Real outputs alone_vr[alone_start[a] .. alone_start[a + 1]). All copied. NULL on bad arguments
 * or no memory. A non-finite value, or an integer outside its input's range, fails the step. */
SGPlan *sg_create(DRKernel *k, int n_fmus, const SGFmu *fmus, int n_signals, const SGSignal *signals, int n_reads,
                  const int *read_fmu, const int *read_type, const int *read_start, const fmi2ValueReference *read_vr,
                  const int *read_signal, int n_writes, const int *write_fmu, const int *write_type,
                  const int *write_start, const fmi2ValueReference *write_vr, const int *write_signal, int n_alone,
                  const int *alone_fmu, const int *alone_start, const fmi2ValueReference *alone_vr);

/* The source tables' values for steps n0 .. n0 + count - 1: column c at step n is
 * table[c ld + n - n0] (the caller's, read during the next dr_run_steps). */
void sg_set_table(SGPlan *p, const double *table, long ld, int n0, int count);

/* Run the plan in k's blocks from now on (dr_set_extra); sg_destroy detaches it. */
void sg_attach(SGPlan *p);

const SGFailure *sg_failure(const SGPlan *p);

void sg_destroy(SGPlan *p);

#endif
