/* The classical masters on the kernel route (classical.c; wavecosim/classical_path.py drives it
 * through ctypes). A CLKernel works on a DRKernel whose subsystems were set up with their physical
 * input and output value references (the FMUs in physical port mode); it owns only G and scratch. */
#ifndef WAVECOSIM_CLASSICAL_H
#define WAVECOSIM_CLASSICAL_H

#include "drkernel.h"

typedef struct CLKernel CLKernel;

/* On kernel k (which must outlive it), with the input map G (inputs = G outputs, n x n) in
 * compressed rows (columns ascending), copied. NULL on malformed rows or no memory. */
CLKernel *cl_create(DRKernel *k, const int *G_start, const int *G_col, const double *G_val);

/* One macro-step of fixed-point iteration with rollback from the outputs y_n (n): K passes (all
 * subsystems from the old iterate, or sequential: Gauss-Seidel), stopped by io->K, io->eps (>= 0)
 * or io->deadline_s, then the commit with inputs G y^K. Writes y^{n+1} into y_next and the committed
 * inputs into u (n each, the caller's); io gets iterations, reason and residual as dr_macro_step.
 * Returns 0, or -1 when an FMU call failed (io->failed_*). */
int cl_fixed_point_step(CLKernel *c, DRStep *io, const double *y_n, double *y_next, double *u, int sequential);

/* One macro-step of explicit coupling (no state saved): every subsystem steps once with inputs
 * G y_n (sequential: Gauss-Seidel, the newest outputs), outputs into y_next (the caller's, not y_n).
 * Returns like cl_fixed_point_step. */
int cl_explicit_step(CLKernel *c, DRStep *io, const double *y_n, double *y_next, int sequential);

void cl_destroy(CLKernel *c);

#endif
