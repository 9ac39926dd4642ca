/* The runner's per-block passes over the kernel's log (blocks.c, libblocks.so; wavecosim/kernel/blocks.py
 * binds it through wavecosim/kernel/contract.py). The structs are blocks.c's, mirrored there. */
#ifndef WAVECOSIM_BLOCKS_H
#define WAVECOSIM_BLOCKS_H

#include "drkernel.h"

struct SampledBlock;
struct WatchBlock;

/* The rows' columns and the trajectory of steps first .. first + count - 1 of a block (args: a BlockRows). */
void block_rows_steps(void *args, int n0, const double *log, long ld, int first, int count);
/* Condition 2 over the same steps (args: a PassBlock). */
void passivity_steps(void *args, int n0, const double *log, long ld, int first, int count);
/* The freeze watch over the same steps (args: a FreezeBlock). */
void freeze_steps(void *args, int n0, const double *log, long ld, int first, int count);
DRPassFn block_rows_steps, passivity_steps, freeze_steps;      /* the kernel calls them as DRPassFns (dr_set_passes) */

/* CertificateSampler's columns and running figures of one block. */
void sampled_block(const struct SampledBlock *p);
/* FneWatch's column and running figures of one block; 1, writing nothing, when a margin falls below
 * -tol or one estimated is NaN or zero (the caller books those steps one by one), else 0. */
int watch_block(struct WatchBlock *p);

#endif
