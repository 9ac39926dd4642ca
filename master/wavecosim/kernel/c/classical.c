/* The classical masters on the kernel route: explicit and gauss-seidel (wavecosim/masters/explicit.py,
 * gauss_seidel.py), jacobi-iter and gauss-seidel-iter (fixed_point.py), each made of the passes of
 * wavecosim/masters/physical.py, with the FMUs in
 * their physical port mode, evaluated by drkernel.c's subsystem evaluation (kernel_internal.h).
 * The arithmetic follows the Python reference operation by operation (inputs G y by
 * linalg.matvec_rows, the residual by linalg.distance), so the numbers are bit-identical. */
#include <math.h>
#include <stdlib.h>

#include "classical.h"
#include "kernel_internal.h"
#include "linalg.h"

struct CLKernel {
    DRKernel *k;
    Csr *G;                        /* inputs = G outputs */
    double *y, *y_new, *inputs;    /* scratch: the iterate, its image, a pass's inputs */
    double *y_out;                 /* scratch of cl_run_steps: y^{n+1} before it becomes y^n */
    int explicit_, sequential;     /* the master cl_run_steps runs (cl_create) */
};

CLKernel *cl_create(DRKernel *k, const int *G_start, const int *G_col, const double *G_val, int explicit_,
                    int sequential) {
    CLKernel *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    size_t n = dr_channels(k);
    c->k = k;
    c->explicit_ = explicit_;
    c->sequential = sequential;
    c->G = dr_csr_copy(G_start, G_col, G_val, n);
    c->y = calloc(4 * n + 1, sizeof(double));                  /* n = 0: signals only */
    if (!c->G || !c->y) {
        cl_destroy(c);
        return NULL;
    }
    c->y_new = c->y + n;
    c->inputs = c->y + 2 * n;
    c->y_out = c->y + 3 * n;
    return c;
}

enum { QUERY = DR_QUERY, COMMIT = DR_COMMIT, FORWARD = DR_FORWARD };

/* One pass (PhysicalMaster.sweep): y_new = y, then each subsystem in order gets inputs G y (or,
 * sequential, G y_new with its predecessors' new outputs) and writes its outputs into y_new; the
 * inputs handed out are left in `inputs`. how: QUERY from x_i^n (state discarded), COMMIT from x_i^n,
 * FORWARD from the current state with nothing saved. A Jacobi pass takes every input first and
 * evaluates the subsystems in one round on the kernel's threads (measure: timed, dr_costs): the same
 * numbers, as no subsystem reads another's new outputs. The first failing subsystem, or -1. */
static int sweep(CLKernel *c, const double *y, double *y_new, double *inputs, double t, double h, int how,
                 int sequential, int measure) {
    DRKernel *k = c->k;
    if (y_new != y) copy_doubles(y_new, y, dr_channels(k));
    if (!sequential) {
        dr_csr_rows(c->G, y, inputs, 0, dr_channels(k));
        return dr_evaluate_all(k, inputs, y_new, t, h, how, measure);
    }
    const double *source = y_new;
    for (int i = 0; i < dr_subsystems(k); i++) {
        size_t off, m;
        dr_span(k, i, &off, &m);
        dr_csr_rows(c->G, source, inputs, off, off + m);
        if (how == FORWARD ? dr_advance(k, i, inputs, y_new, t, h) : dr_evaluate(k, i, inputs, y_new, t, h, how))
            return i;
    }
    return -1;
}

int cl_fixed_point_step(CLKernel *c, DRStep *io, const double *y_n, double *y_next, double *u, int sequential) {
    DRKernel *k = c->k;
    size_t n = dr_channels(k);
    dr_begin(k, io);
    double deadline = io->deadline_s > 0.0 ? dr_now_ns() + 1e9 * io->deadline_s : 0.0;
    double *y = c->y, *y_new = c->y_new;
    copy_doubles(y, y_n, n);                                     /* y^0 = y^n */
    int it = 0, reason = DR_BUDGET;
    double residual = NAN;
    while (it < io->K) {
        int f = sweep(c, y, y_new, c->inputs, io->t, io->dt, QUERY, sequential, io->measure);   /* y~ = S^n(G y) */
        if (f >= 0) return dr_fail(k, io, f);
        residual = dr_distance(y_new, y, n);
        double *swap = y;                                        /* y^{k+1} = y~ (Picard) */
        y = y_new;
        y_new = swap;
        it++;
        if (io->eps >= 0.0 && residual <= io->eps) {
            reason = DR_TOLERANCE;
            break;
        }
        if (deadline > 0.0 && dr_now_ns() >= deadline) {
            reason = DR_DEADLINE;
            break;
        }
    }
    io->iterations = it;
    io->residual = residual;
    io->reason = io->K ? reason : DR_EXPLICIT;
    int f = sweep(c, y, y_next, u, io->t, io->dt, COMMIT, sequential, io->measure);  /* the commit, inputs G y^K */
    return f >= 0 ? dr_fail(k, io, f) : 0;
}

int cl_pass(CLKernel *c, DRStep *io, const double *y, double *y_new, double *inputs, int commit, int first) {
    if (first) dr_begin(c->k, io);
    int f = sweep(c, y, y_new, inputs, io->t, io->dt, commit ? COMMIT : QUERY, 0, io->measure);
    return f >= 0 ? dr_fail(c->k, io, f) : 0;
}

/* y^{n+1} = Phi(x^n, G y^n), the inputs handed out into `inputs`; y_next may be y_n (sweep). */
static int explicit_pass(CLKernel *c, DRStep *io, const double *y_n, double *y_next, double *inputs, int sequential) {
    dr_begin(c->k, io);
    io->iterations = 0;
    io->residual = NAN;
    io->reason = DR_EXPLICIT;
    int f = sweep(c, y_n, y_next, inputs, io->t, io->dt, FORWARD, sequential, io->measure);
    return f >= 0 ? dr_fail(c->k, io, f) : 0;
}

int cl_explicit_step(CLKernel *c, DRStep *io, const double *y_n, double *y_next, int sequential) {
    return explicit_pass(c, io, y_n, y_next, c->inputs, sequential);
}

/* One macro-step of cl_run_steps from y^n in the kernel's outputs: y^{n+1} replaces it, the inputs
 * handed out (the commit's, or the explicit pass's) go into the kernel's inputs. The explicit pass
 * works in place: sweep reads every input from y^n before the first doStep (Jacobi), or each
 * subsystem's from the outputs so far (sequential), as it does from its copy. */
static int block_step(void *ctx, DRStep *io) {
    CLKernel *c = ctx;
    double *y = dr_outputs(c->k), *u = dr_inputs(c->k);
    if (c->explicit_) return explicit_pass(c, io, y, y, u, c->sequential);
    int f = cl_fixed_point_step(c, io, y, c->y_out, u, c->sequential);
    if (f) return f;
    copy_doubles(y, c->y_out, dr_channels(c->k));
    return 0;
}

int cl_run_steps(CLKernel *c, DRStep *io, int n0, int count, double *rows, long ld, double H_cap) {
    return dr_run_steps_of(c->k, io, n0, count, rows, ld, H_cap, block_step, c);
}

void cl_destroy(CLKernel *c) {
    if (!c) return;
    free(c->G);
    free(c->y);
    free(c);
}
