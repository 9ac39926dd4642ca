/* The newton master on the kernel route (newton.c; wavecosim/kernel/newton.py drives it through
 * ctypes): the interface Newton of wavecosim/masters/monolithic.py (solve_interface) and the commit, on a
 * DRKernel whose subsystems run in wave port mode. It owns only P and its scratch. */
#ifndef WAVECOSIM_NEWTON_H
#define WAVECOSIM_NEWTON_H

#include "drkernel.h"

typedef struct NTKernel NTKernel;

/* Outcomes of nt_step besides 0 and -1 (an FMU call failed, io->failed_*). */
enum { NT_NONFINITE = 1, NT_SINGULAR = 2, NT_NOT_CONVERGED = 3, NT_NO_MEMORY = 4 };

/* Newton's constants (monolithic.py: TOL, ACCEPT, ACCEPT_REL, MAX_ITER, STALL). */
typedef struct {
    double tol, accept, accept_rel;
    int max_iter, stall;
} NTSettings;

/* On kernel k (which must outlive it), with the wave map P (n x n) in compressed rows (columns
 * ascending), copied. NULL on malformed rows or no memory. */
NTKernel *nt_create(DRKernel *k, const int *P_start, const int *P_col, const double *P_val, const NTSettings *set);

/* A new P (gamma retuned); nonzero on malformed rows or no memory (the old P is kept). */
int nt_set_map(NTKernel *c, const int *P_start, const int *P_col, const double *P_val);

/* One macro-step from b^n (b_n, n): Newton on b = S^n(P b) from b^n, then the commit with
 * a_hat = P b*, its outgoing waves into b_next (the caller's). io gets the Newton iterations and
 * the residual |b* - S(P b*)|; out[0] the S-evaluations, out[1] the port-wave scale |a| + |b|.
 * Returns 0, -1 (FMU failure) or NT_* (io->residual, out[1] then say why). */
int nt_step(NTKernel *c, DRStep *io, const double *b_n, double *b_next, double *a_hat, double *out);

/* The interface Newton alone (monolithic.solve_interface at x^n from b^n, e.g. u* = P b* of the
 * certificates): b* into b_star, io and out as nt_step; every subsystem is left at x_i^n. */
int nt_solve(NTKernel *c, DRStep *io, const double *b_n, double *b_star, double *out);

/* y = P x, rows summed left to right from 0.0 over their stored entries (linalg.matvec). */
void nt_apply_map(const NTKernel *c, const double *x, double *y);

void nt_destroy(NTKernel *c);

#endif
