/* Signal connections, sources and subsystems stepped alone inside the kernel's blocks of macro-steps
 * (signals.h): wavecosim/core/signals.py's Signals.begin_step before each step and the reading of the
 * subsystems stepped alone after it, making the same FMU calls in the same order and the same
 * arithmetic (a Real input: factor * from + offset; Integer and Boolean values as they are), so a
 * block gives the numbers of the Python route. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "abi.h"
#include "signals.h"

typedef struct {
    int column;                    /* -1, or the source table column it reads */
    int to;                        /* its input's category: SG_REAL (scaled), SG_INTEGER (in lo .. hi), SG_BOOLEAN */
    double factor, offset, lo, hi;
} Signal;

/* One get or set call of type type[g] (SG_REAL, SG_INTEGER, SG_BOOLEAN): FMU fmu[g], value references
 * vr[start[g] .. start[g + 1]) of the signals signal[start[g] ..]. */
typedef struct {
    int n, *fmu, *type, *start, *signal;
    fmi2ValueReference *vr;
} Groups;

struct SGPlan {
    DRKernel *k;
    int n_fmus, n_signals, n_alone;
    SGFmu *fmu;
    Signal *signal;
    Groups reads, writes;
    int *alone_fmu, *alone_start;                  /* subsystem a stepped alone: its outputs alone_vr[start[a] ..] */
    fmi2ValueReference *alone_vr;
    double *value, *scratch;       /* the signals' values at t_n; a write's or a read's values */
    int *ints;                     /* a write's or a read's Integer or Boolean values */
    const double *table;           /* column c at step n: table[c ld + n - table_n0] */
    long table_ld;
    int table_n0, table_count;
    int n_table;
    SGFailure failure;
};

static void *grab(void **all, size_t *used, size_t bytes) {
    void *p = (char *)*all + *used;
    *used += (bytes + 15) / 16 * 16;
    return p;
}

/* g's arrays carved from the plan's block, copied from the caller's. */
static void groups(Groups *g, void **all, size_t *used, int n, const int *fmu, const int *type, const int *start,
                   const fmi2ValueReference *vr, const int *signal) {
    size_t count = (size_t)start[n];
    g->n = n;
    g->type = grab(all, used, (size_t)n * sizeof(int));
    memcpy(g->type, type, (size_t)n * sizeof(int));
    g->fmu = grab(all, used, (size_t)n * sizeof(int));
    g->start = grab(all, used, ((size_t)n + 1) * sizeof(int));
    g->signal = grab(all, used, count * sizeof(int));
    g->vr = grab(all, used, count * sizeof(fmi2ValueReference));
    memcpy(g->fmu, fmu, (size_t)n * sizeof(int));
    memcpy(g->start, start, ((size_t)n + 1) * sizeof(int));
    memcpy(g->signal, signal, count * sizeof(int));
    memcpy(g->vr, vr, count * sizeof(fmi2ValueReference));
}

SGPlan *sg_create(DRKernel *k, int n_fmus, const SGFmu *fmus, int n_signals, const SGSignal *signals, int n_reads,
                  const int *read_fmu, const int *read_type, const int *read_start, const fmi2ValueReference *read_vr,
                  const int *read_signal, int n_writes, const int *write_fmu, const int *write_type,
                  const int *write_start, const fmi2ValueReference *write_vr, const int *write_signal, int n_alone,
                  const int *alone_fmu, const int *alone_start, const fmi2ValueReference *alone_vr) {
    if (n_fmus < 0 || n_signals < 0 || n_reads < 0 || n_writes < 0 || n_alone < 0) return NULL;
    size_t reads = (size_t)read_start[n_reads], writes = (size_t)write_start[n_writes];
    size_t alone = (size_t)alone_start[n_alone], widest = writes;
    if (reads > widest) widest = reads;
    if (alone > widest) widest = alone;
    size_t ints = 4 * (size_t)n_reads + 4 * (size_t)n_writes + 2 * (size_t)n_alone + 3 + reads + writes + widest;
    size_t bytes = 16 * 24 + sizeof(SGPlan) + (size_t)n_fmus * sizeof(SGFmu) + (size_t)n_signals * sizeof(Signal)
                   + ints * sizeof(int) + (reads + writes + alone) * sizeof(fmi2ValueReference)
                   + ((size_t)n_signals + widest) * sizeof(double);
    void *all = calloc(1, bytes);
    if (!all) return NULL;
    size_t used = 0;
    SGPlan *p = grab(&all, &used, sizeof *p);
    p->k = k;
    p->n_fmus = n_fmus, p->n_signals = n_signals, p->n_alone = n_alone;
    p->fmu = grab(&all, &used, (size_t)n_fmus * sizeof(SGFmu));
    p->signal = grab(&all, &used, (size_t)n_signals * sizeof(Signal));
    groups(&p->reads, &all, &used, n_reads, read_fmu, read_type, read_start, read_vr, read_signal);
    groups(&p->writes, &all, &used, n_writes, write_fmu, write_type, write_start, write_vr, write_signal);
    p->alone_fmu = grab(&all, &used, (size_t)n_alone * sizeof(int));
    p->alone_start = grab(&all, &used, ((size_t)n_alone + 1) * sizeof(int));
    p->alone_vr = grab(&all, &used, alone * sizeof(fmi2ValueReference));
    p->value = grab(&all, &used, (size_t)n_signals * sizeof(double));
    p->scratch = grab(&all, &used, widest * sizeof(double));
    p->ints = grab(&all, &used, widest * sizeof(int));
    memcpy(p->fmu, fmus, (size_t)n_fmus * sizeof(SGFmu));
    for (int s = 0; s < n_signals; s++) {
        Signal *g = &p->signal[s];
        const SGSignal *in = &signals[s];
        g->column = in->column, g->to = in->to, g->factor = in->factor, g->offset = in->offset;
        g->lo = in->lo, g->hi = in->hi;
        if (g->column >= p->n_table) p->n_table = g->column + 1;
    }
    memcpy(p->alone_fmu, alone_fmu, (size_t)n_alone * sizeof(int));
    memcpy(p->alone_start, alone_start, ((size_t)n_alone + 1) * sizeof(int));
    memcpy(p->alone_vr, alone_vr, alone * sizeof(fmi2ValueReference));
    return p;
}

void sg_set_table(SGPlan *p, const double *table, long ld, int n0, int count) {
    p->table = table, p->table_ld = ld, p->table_n0 = n0, p->table_count = count;
}

/* A failed call of FMU fmu (fmicall.h recorded it in p->failure.call) is the step's failure. */
static int fmu_failed(SGPlan *p, int fmu) {
    p->failure.kind = SG_FMU, p->failure.index = fmu;
    return 1;
}

/* Read call r of g into the signals' values: Reals as they are, Integers as numbers, Booleans as 0 or 1. */
static int read_group(SGPlan *p, const Groups *g, int r) {
    SGFmu *f = &p->fmu[g->fmu[r]];
    int a = g->start[r], b = g->start[r + 1];
    size_t n = (size_t)(b - a);
    FmiFailure *fail = &p->failure.call;
    int failed = g->type[r] == SG_REAL ? fmi_get_real(f->getReal, f->calls, f->comp, g->vr + a, n, p->scratch, fail)
               : g->type[r] == SG_INTEGER ? fmi_get_integer(f->getInteger, f->calls, f->comp, g->vr + a, n, p->ints, fail)
               : fmi_get_boolean(f->getBoolean, f->calls, f->comp, g->vr + a, n, p->ints, fail);
    if (failed) return fmu_failed(p, g->fmu[r]);
    for (int j = a; j < b; j++)
        p->value[g->signal[j]] = g->type[r] == SG_REAL ? p->scratch[j - a]
                               : g->type[r] == SG_INTEGER ? (double)p->ints[j - a] : (p->ints[j - a] ? 1.0 : 0.0);
    return 0;
}

/* Write call w of g from the signals' values, in its type. */
static int write_group(SGPlan *p, const Groups *g, int w) {
    SGFmu *f = &p->fmu[g->fmu[w]];
    int a = g->start[w], b = g->start[w + 1];
    size_t n = (size_t)(b - a);
    FmiFailure *fail = &p->failure.call;
    for (int j = a; j < b; j++) {
        double v = p->value[g->signal[j]];
        p->scratch[j - a] = v;
        p->ints[j - a] = g->type[w] == SG_BOOLEAN ? (v != 0.0) : (int)v;
    }
    int failed = g->type[w] == SG_REAL ? fmi_set_real(f->setReal, f->calls, f->comp, g->vr + a, n, p->scratch, fail)
               : g->type[w] == SG_INTEGER ? fmi_set_integer(f->setInteger, f->calls, f->comp, g->vr + a, n, p->ints, fail)
               : fmi_set_boolean(f->setBoolean, f->calls, f->comp, g->vr + a, n, p->ints, fail);
    return failed ? fmu_failed(p, g->fmu[w]) : 0;
}

/* Signals.hold(n) and the steps of the subsystems stepped alone (Scene.begin_step). */
static int before(void *ctx, DRStep *io, int n) {
    SGPlan *p = ctx;
    memset(&p->failure, 0, sizeof p->failure);
    p->failure.step = n;
    const Groups *g = &p->reads;                                 /* every value read before any is set */
    for (int r = 0; r < g->n; r++)
        if (read_group(p, g, r)) return 1;
    for (int s = 0; s < p->n_signals; s++) {
        const Signal *sig = &p->signal[s];
        if (sig->column >= 0) {
            if (!p->table || n < p->table_n0 || n >= p->table_n0 + p->table_count) {
                p->failure.kind = SG_NO_TABLE;
                return 1;
            }
            p->value[s] = p->table[(long)sig->column * p->table_ld + (n - p->table_n0)];
        }
        if (sig->to == SG_REAL) p->value[s] = sig->factor * p->value[s] + sig->offset;  /* else taken as read */
        else if (sig->to == SG_BOOLEAN) p->value[s] = p->value[s] != 0.0 ? 1.0 : 0.0;
    }
    for (int s = 0; s < p->n_signals; s++)
        if (!isfinite(p->value[s]) || (p->signal[s].to == SG_INTEGER &&
                                       !(p->signal[s].lo <= p->value[s] && p->value[s] <= p->signal[s].hi))) {
            p->failure.kind = SG_NONFINITE, p->failure.index = s, p->failure.value = p->value[s];
            return 1;
        }
    g = &p->writes;
    for (int w = 0; w < g->n; w++)
        if (write_group(p, g, w)) return 1;
    for (int a = 0; a < p->n_alone; a++) {                       /* Subsystem.step_alone: never rolled back */
        SGFmu *f = &p->fmu[p->alone_fmu[a]];
        if (fmi_do_step(f->doStep, f->calls, f->comp, io->t, io->dt, 1, &p->failure.call)) return fmu_failed(p, p->alone_fmu[a]);
    }
    return 0;
}

/* The outputs of the subsystems stepped alone (Sampler.alone), after the step. */
static int observe(void *ctx, double *out, size_t ld) {
    SGPlan *p = ctx;
    for (int a = 0; a < p->n_alone; a++) {
        SGFmu *f = &p->fmu[p->alone_fmu[a]];
        int first = p->alone_start[a], count = p->alone_start[a + 1] - first;
        if (!count) continue;
        if (fmi_get_real(f->getReal, f->calls, f->comp, p->alone_vr + first, (size_t)count, p->scratch, &p->failure.call))
            return fmu_failed(p, p->alone_fmu[a]);
        for (int j = 0; j < count; j++) out[(size_t)(first + j) * ld] = p->scratch[j];
    }
    return 0;
}

void sg_attach(SGPlan *p) {
    DRExtra extra = {before, observe, (size_t)p->alone_start[p->n_alone], p};
    dr_set_extra(p->k, &extra);
}

const SGFailure *sg_failure(const SGPlan *p) { return &p->failure; }

void sg_destroy(SGPlan *p) {
    if (!p) return;
    dr_set_extra(p->k, NULL);
    free(p);
}

MIRRORED(SGFmu)
MIRRORED(SGSignal)
MIRRORED(SGFailure)
