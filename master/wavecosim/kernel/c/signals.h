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

#include "kernel_internal.h"

/* One FMU's functions (its own fmi2 ones, or fmi3shim.c's) and instance. */
typedef struct {
    fmi2GetRealTYPE *getReal;
    fmi2SetRealTYPE *setReal;
    fmi2DoStepTYPE *doStep;
    fmi2Component comp;
} SGFmu;

/* SGFailure.kind */
enum { SG_OK = 0, SG_FMU = 1, SG_NONFINITE = 2, SG_NO_TABLE = 3 };

/* Why the last step's signals failed: an FMU call (index: the FMU, function DR_FN_*, status), a
 * non-finite value (index: the signal, value), or a table not given for the step. */
typedef struct {
    int kind, index, function, status, step, alone_done;
    double value;
} SGFailure;

typedef struct SGPlan SGPlan;

/* Over kernel k: n_fmus FMUs; n_signals signals, signal s scaled by factor[s] and offset[s] and read
 * from source table column column[s] or, with column[s] = -1, by one of the n_reads getReal calls;
 * call g of FMU read_fmu[g] reads read_vr[j] into signal read_signal[j] for j in read_start[g] ..
 * read_start[g + 1); the n_writes setReal calls alike (write_*); n_alone subsystems stepped alone,
 * subsystem a being FMU alone_fmu[a] with the outputs alone_vr[alone_start[a] .. alone_start[a + 1]).
 * All copied. NULL on bad arguments or no memory. */
SGPlan *sg_create(DRKernel *k, int n_fmus, const SGFmu *fmus, int n_signals, const int *column, const double *factor,
                  const double *offset, int n_reads, const int *read_fmu, const int *read_start,
                  const fmi2ValueReference *read_vr, const int *read_signal, int n_writes, const int *write_fmu,
                  const int *write_start, const fmi2ValueReference *write_vr, const int *write_signal, int n_alone,
                  const int *alone_fmu, const int *alone_start, const fmi2ValueReference *alone_vr);

/* The source tables' values for steps n0 .. n0 + count - 1: column c at step n is
 * table[c ld + n - n0] (the caller's, read during the next dr_run_steps). */
void sg_set_table(SGPlan *p, const double *table, long ld, int n0, int count);

/* Run the plan in k's blocks from now on (dr_set_extra); sg_destroy detaches it. */
void sg_attach(SGPlan *p);

const SGFailure *sg_failure(const SGPlan *p);

/* sizeof(SGFmu), sizeof(SGFailure): for the caller to check its copy of the layouts. */
void sg_sizes(size_t *out);

void sg_destroy(SGPlan *p);

#endif
