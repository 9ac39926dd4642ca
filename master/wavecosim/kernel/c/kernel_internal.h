/* What drkernel.c shares with the other routes built on its subsystem evaluation (classical.c);
 * not part of the ctypes interface: hidden, so libdrkernel.so exports only what its headers declare
 * for Python (wavecosim/kernel/contract.py). */
#ifndef WAVECOSIM_KERNEL_INTERNAL_H
#define WAVECOSIM_KERNEL_INTERNAL_H

#include "drkernel.h"

#pragma GCC visibility push(hidden)

/* A square matrix (P, J_L, the classical masters' input map G) in compressed rows, one block:
 * row i holds col[start[i] .. start[i+1]) (ascending) and val. */
typedef struct {
    size_t n, nnz;
    int *start, *col;
    double *val;
} Csr;

/* A copy of compressed rows (freed with free), or NULL if they are malformed or memory is short. */
Csr *dr_csr_copy(const int *start, const int *col, const double *val, size_t n);

/* Rows r0 .. r1 - 1 of y = M x, each summed over its stored entries left to right from 0.0
 * (linalg.matvec_rows): the same bits as the dense sum, whose other terms are exact zeros added to
 * a sum that is never -0.0. Inline: a step makes several of a few rows each. */
static inline void dr_csr_rows(const Csr *M, const double *x, double *y, size_t r0, size_t r1) {
    for (size_t i = r0; i < r1; i++) {
        double acc = 0.0;
        for (int p = M->start[i]; p < M->start[i + 1]; p++) acc += M->val[p] * x[M->col[p]];
        y[i] = acc;
    }
}

size_t dr_channels(const DRKernel *k);
int dr_subsystems(const DRKernel *k);

/* Offset of subsystem i's first channel in the stacked vectors, and its channel count. */
void dr_span(const DRKernel *k, int i, size_t *offset, size_t *m);

/* A new macro-step: the first evaluation of each subsystem saves x_i^n; failures cleared. */
void dr_begin(DRKernel *k, DRStep *io);

/* How an evaluation round treats each subsystem: a query from x_i^n (state discarded), the commit from
 * x_i^n, or a step forward from the current state with nothing saved (dr_advance). */
enum { DR_QUERY = 0, DR_COMMIT = 1, DR_FORWARD = 2 };

/* Every subsystem at in -> out on its channels, each on the thread of the plan (dr_set_threads), in
 * one round; measure times each evaluation (dr_costs). The first failing subsystem in subsystem
 * order, or -1. */
int dr_evaluate_all(DRKernel *k, const double *in, double *out, double t, double h, int how, int measure);

/* Subsystem i at in -> out on its channels (commit = 0: from x_i^n, state discarded; 1: kept);
 * nonzero when an FMU call failed. */
int dr_evaluate(DRKernel *k, int i, const double *in, double *out, double t, double h, int commit);

/* Called before (at x^n) and after each step n of dr_run_steps_of (after the ledger's redo); a
 * nonzero return of `before` ends the call before step n. */
typedef int (*DRHookFn)(void *ctx, DRStep *io, int n);
void dr_set_hooks(DRKernel *k, DRHookFn before, DRHookFn after, void *ctx);

/* The caller's u^0 and u^K buffers and the trace (NULL when not recording) with its capacity. */
void dr_iterates(DRKernel *k, double **u0, double **uK, double **trace, int *capacity);

/* count values of subsystem i's FMU (fmi2GetReal); nonzero when the call failed. */
int dr_read(DRKernel *k, int i, const fmi2ValueReference *vr, int count, double *out);

/* Subsystem i back at x_i^n after queries made from it (FrozenPortMap.thaw); nonzero when
 * setFMUstate failed. */
int dr_thaw(DRKernel *k, int i);

/* Subsystem i one step forward from its current state, nothing saved first (masters that never
 * roll back: frozen_port_map.py's begin + advance). */
int dr_advance(DRKernel *k, int i, const double *in, double *out, double t, double h);

/* Report subsystem i's failed call in io; returns -1. */
int dr_fail(DRKernel *k, DRStep *io, int i);

/* |x - y|, squares summed left to right (linalg.distance). */
double dr_distance(const double *x, const double *y, size_t n);

double dr_now_ns(void);

/* One macro-step of a route at io->t (returns 0, or -1 with io->failed_* set), leaving what it logs
 * in dr_outputs (b^{n+1}, or the classical masters' y^{n+1}) and dr_inputs (a, or their inputs). */
typedef int (*DRStepFn)(void *ctx, DRStep *io);

/* dr_run_steps with step(ctx, io) making each macro-step: the same log, observed values and stop. */
int dr_run_steps_of(DRKernel *k, DRStep *io, int n0, int count, double *rows, long ld, double H_cap, DRStepFn step,
                    void *ctx);

/* What a route adds around each step of dr_run_steps_of (signals.c): before(ctx, io, n) first, at
 * t_n (nonzero: it failed, and the call ends before step n with failed_subsystem DR_FAILED_EXTRA);
 * observe(ctx, out, ld) writes `rows` more observed values after the subsystems' (value j at
 * out[j ld]; nonzero: it failed, as before). */
typedef struct {
    int (*before)(void *ctx, DRStep *io, int n);
    int (*observe)(void *ctx, double *out, size_t ld);
    size_t rows;
    void *ctx;
} DRExtra;
void dr_set_extra(DRKernel *k, const DRExtra *extra);

/* The caller's buffers the log reads: b (outputs) and a_hat (inputs), n each. */
double *dr_outputs(DRKernel *k);
double *dr_inputs(DRKernel *k);

#pragma GCC visibility pop

#endif
