/* The sampled certificates inside the DR kernel's block loop (certs.c; wavecosim/certs_path.py
 * drives it through ctypes): before a sampled macro-step n (n % every == 0), at x^n, u* = P b* by
 * the interface Newton (newton.c) and the FNE margins of every frozen map on random pairs; after
 * the step (and the ledger's redo) the Fejer part of Theorem 1's residual and, every step, the
 * Condition 1 watch's secant margins from the inner loop's trace. The arithmetic is that of
 * wavecosim/certificates.py and wavecosim/observers/fne_watch.py, operation by operation. Their FMU
 * calls go through a kernel of their own, so the master's kernel counts only its own. */
#ifndef WAVECOSIM_CERTS_H
#define WAVECOSIM_CERTS_H

#include "drkernel.h"
#include "newton.h"

typedef struct DCCerts DCCerts;

/* Settings: sample every `every` steps; `pairs` FNE pairs per subsystem (0: none) at `scale`;
 * `augmented`: u* and the Fejer term; `watch`: the secant margins (pairs kept above `floor`). */
typedef struct {
    int every, pairs, augmented, watch;
    double scale, floor;
} DCSettings;

/* On the master's kernel k, with u*'s Newton nt on the certificates' own kernel q (both must
 * outlive it). NULL on no memory. */
DCCerts *dc_create(DRKernel *k, NTKernel *nt, DRKernel *q, const DCSettings *set);

/* Doubles per step row: fne (n_sub), fejer, watch margins (n_sub), watch pairs kept (n_sub). */
int dc_width(const DCCerts *c);

/* Arm the hooks for the next dr_run_steps call from step n0: `normals` hold the sampled steps'
 * normals in order (per subsystem 2 pairs x m), `rows` one row per step; NULL rows disarms. */
void dc_arm(DCCerts *c, int n0, const double *normals, double *rows);

/* After a call: 0, -1 (an FMU call of the certificates failed: failed[0..2] = subsystem, DR_FN_*,
 * status), or newton.h's NT_* (out[0..1] = residual, wave scale); the normals used so far. */
int dc_status(const DCCerts *c, int *failed, double *out, long *normals_used);

void dc_destroy(DCCerts *c);

#endif
