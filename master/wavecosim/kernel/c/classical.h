/* The classical masters on the kernel route (classical.c; wavecosim/kernel/classical.py drives it
 * through ctypes). A CLKernel works on a DRKernel whose subsystems were set up with their physical
 * input and output value references (the FMUs in physical port mode); it owns only G and scratch. */
#ifndef WAVECOSIM_CLASSICAL_H
#define WAVECOSIM_CLASSICAL_H

#include "drkernel.h"

typedef struct CLKernel CLKernel;

/* On kernel k (which must outlive it), with the input map G (inputs = G outputs, n x n) in
 * compressed rows (columns ascending), copied; cl_run_steps makes the steps of the explicit (explicit_ = 1)
 * or fixed-point master, sequential (Gauss-Seidel) or not. NULL on malformed rows or no memory. */
CLKernel *cl_create(DRKernel *k, const int *G_start, const int *G_col, const double *G_val, int explicit_,
                    int sequential);

/* One macro-step of fixed-point iteration with rollback from the outputs y_n (n): K passes (all
 * subsystems from the old iterate, or sequential: Gauss-Seidel), stopped by io->K, io->eps (>= 0)
 * or io->deadline_s, then the commit with inputs G y^K. Writes y^{n+1} into y_next and the committed
 * inputs into u (n each, the caller's); io gets iterations, reason and residual as dr_macro_step.
 * Returns 0, or -1 when an FMU call failed (io->failed_*). */
int cl_fixed_point_step(CLKernel *c, DRStep *io, const double *y_n, double *y_next, double *u, int sequential);

/* One Jacobi pass from the iterate y for a master whose update is not Picard (aitken, iqn-ils: the
 * update stays in Python): every subsystem from x_i^n with inputs G y, on the kernel's threads;
 * outputs into y_new, the inputs handed out into `inputs` (n each, the caller's). first: a new
 * macro-step at io->t (x_i^n is saved on its first evaluation); commit: the state is kept (the
 * step's one commit). Returns 0, or -1 when an FMU call failed (io->failed_*). */
int cl_pass(CLKernel *c, DRStep *io, const double *y, double *y_new, double *inputs, int commit, int first);

/* One macro-step of explicit coupling (no state saved): every subsystem steps once with inputs
 * G y_n (sequential: Gauss-Seidel, the newest outputs), outputs into y_next (the caller's, not y_n).
 * Returns like cl_fixed_point_step. */
int cl_explicit_step(CLKernel *c, DRStep *io, const double *y_n, double *y_next, int sequential);

/* Macro-steps n0 .. n0 + count - 1 of the master named in cl_create in one call,
 * from y^n in the DR kernel's b buffer (updated step by step to y^{n+1}), each exactly the step
 * function above at t = (double)n dt, logged as dr_run_steps logs (a: the inputs handed out, b: y^{n+1};
 * the ledger's columns as without it: io->ledger_on must be 0), with its stop after a non-finite
 * observed value or a stored energy that may exceed H_cap. Returns the steps done, as dr_run_steps. */
int cl_run_steps(CLKernel *c, DRStep *io, int n0, int count, double *rows, long ld, double H_cap);

void cl_destroy(CLKernel *c);

#endif
