/* The sampled certificates inside the DR kernel's block loop (certs.c; wavecosim/kernel/certs.py
 * drives it through ctypes): before a sampled macro-step n (n % every == 0), at x^n, u* = P b* by
 * the interface Newton (newton.c) and the FNE margins of every frozen map on random pairs; after
 * the step (and the ledger's redo) the Fejer part of Theorem 1's residual and, every step, the
 * Condition 1 watch's secant margins from the inner loop's trace. The arithmetic is that of
 * wavecosim/core/certificates.py and wavecosim/run/observers/fne_watch.py, operation by operation. Their FMU
 * calls go through a kernel of their own, so the master's kernel counts only its own. */
#ifndef WAVECOSIM_CERTS_H
#define WAVECOSIM_CERTS_H

#include "drkernel.h"
#include "newton.h"

typedef struct DCCerts DCCerts;

/* Settings: sample every `every` steps; `pairs` FNE pairs per subsystem (0: none) at `scale`;
 * `augmented`: u* and the Fejer term; `watch`: the secant margins (pairs kept above `floor`);
 * `probe`: instead, at the sampled steps, the watch's finite-difference probe of every frozen map
 * (core/gamma.py probe_port, one channel each) with the relative step `probe_rel`. */
typedef struct {
    int every, pairs, augmented, watch, probe;
    double scale, floor, probe_rel;
} DCSettings;

/* On the master's kernel k, with u*'s Newton nt on the certificates' own kernel q (both must
 * outlive it); with the probe, stage_vr[2 i .. 2 i + 1] are subsystem i's effort and flow (copied).
 * NULL on no memory. */
DCCerts *dc_create(DRKernel *k, NTKernel *nt, DRKernel *q, const DCSettings *set, const fmi2ValueReference *stage_vr);

/* Doubles per step row: fne (n_sub), fejer, watch margins (n_sub), watch pairs kept (n_sub). */
int dc_width(const DCCerts *c);

/* Arm the hooks for the next dr_run_steps call from step n0: `normals` hold the sampled steps'
 * normals in order (per subsystem 2 pairs x m), `rows` one row per step, `gammas` each subsystem's
 * (the probe's); NULL rows disarms. */
void dc_arm(DCCerts *c, int n0, const double *normals, double *rows, const double *gammas);

/* After a call: 0, -1 (an FMU call of the certificates failed: failed[0..2] = subsystem, DR_FN_*,
 * status), or newton.h's NT_* (out[0..1] = residual, wave scale); the normals used so far. */
int dc_status(const DCCerts *c, int *failed, double *out, long *normals_used);

void dc_destroy(DCCerts *c);

#endif
