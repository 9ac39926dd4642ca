/* The batched queries of a frozen port map (queries.c, libqueries.so; wavecosim/kernel/queries.py
 * binds it through wavecosim/kernel/contract.py). */
#ifndef WAVECOSIM_QUERIES_H
#define WAVECOSIM_QUERIES_H

#include "fmicall.h"

/* Queries q = 0 .. count-1 with inputs[q m ..] into outputs[q m ..]; each restores x_i^n (from
 * *state) only when *dirty (the caller's flag: the instance moved away from x_i^n), which it sets
 * once the instance moves. Returns how many were made; on a failed FMU call (fmicall.h) *failed holds
 * its DR_FN_* and status, and that query is not counted. The doSteps
 * get noSetFMUStatePriorToCurrentPoint = no_prior (Subsystem.no_prior). */
int fq_queries(const DRFunctions *fn, fmi2Component comp, fmi2FMUstate *state, const fmi2ValueReference *in_vr,
               const fmi2ValueReference *out_vr, int m, double t, double dt, const double *inputs, int count,
               double *outputs, int *dirty, int no_prior, FmiFailure *failed);

#endif
