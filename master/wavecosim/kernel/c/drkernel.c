/* Algorithm 1 of the paper for one macro-step, in C, calling the FMUs through their own fmi2
 * function pointers (see drkernel.h). The Python reference is masters/dr.py::algorithm1
 * with core/frozen_port_map.py::Subsystem; each line below names the line it mirrors. */
#define _POSIX_C_SOURCE 200809L
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "drkernel.h"
#include "fmicall.h"
#include "kernel_internal.h"
#include "linalg.h"
#include "dr_options.h"
#include "abi.h"

/* A thread waiting for the other spins this long, then sleeps on a condition variable: spinning
 * answers within a microsecond when both have a core, sleeping leaves the core to the other
 * thread (or another process) when they do not. */
#define SPIN_NS 50000.0

/* Evaluations timed per subsystem for dr_costs (the median is robust to a preemption; a timing reads
 * the clock twice, tens of ns, which cheap FMUs feel). */
#define MAX_SAMPLES 16

typedef struct {
    DRFunctions fn;
    fmi2Component comp;
    fmi2FMUstate *state;           /* x_i^n, saved once per macro-step into this handle: */
    fmi2FMUstate own_state;        /* the kernel's own, or the caller's (see dr_set_subsystem) */
    fmi2ValueReference *in_vr, *out_vr;
    fmi2ValueReference *obs_vr;    /* values read after each commit of dr_run_steps (first: H_i) */
    size_t m, offset, n_obs;
    fmi2GetRealTYPE *obs_get;      /* reads them (the FMU's getReal, or a view's: dr_set_observed_view) */
    fmi2Component obs_comp;
    int obs_no_H;                  /* the first observed value is no stored energy (NaN): not checked */
    const double *noise;           /* a wave adapter's worst kept residual (dr_set_adapter), or NULL */
    const long *fmu_do_steps;      /* a wave adapter's count of its FMU's doSteps, or NULL */
    int thread;
    int frozen, dirty;             /* x_i^n saved this macro-step / instance moved away from it */
    int no_prior;                  /* noSetFMUStatePriorToCurrentPoint of its doSteps (dr_set_no_prior) */
    FmiFailure failed;             /* the FMU call that failed this macro-step (fmicall.h) */
    long n_do_step, n_save, n_restore;
    double sample_ns[MAX_SAMPLES];
    int n_samples;
} Sub;

typedef struct {
    DRKernel *k;
    int id, started;
    pthread_t thread;
    pthread_mutex_t mutex;
    pthread_cond_t cond, done_cond;
    unsigned posted, done;         /* task generations, accessed atomically */
    int sleeping, caller_sleeping, stop; /* accessed atomically */
    int failed;                    /* first failing subsystem of this thread's last task, or -1 */
} Worker;

/* Where the ledger's plain rows were written last: `count` steps from `at`, ld apart, each its value. */
typedef struct {
    double *at;
    size_t ld;
    int count;
    double value[DR_LEDGER_COLUMNS];
} PlainRows;

struct DRKernel {
    int n_sub;
    size_t n;
    Sub *sub;
    Csr *P, *J_L;                  /* one malloc each (freed with free) */
    double *b, *a_hat, *u0, *uK;   /* the caller's */
    double *work;                  /* one block: the two iterate buffers, b_hat, z, w, the safe anchor (u, b) */
    double *u, *u_next, *b_hat, *z, *w; /* u and u_next trade buffers as the loop goes */
    double *u_last, *safe;         /* the energy ledger's anchors: the last query (u_last, b_hat), the latest safe one */
    double last_supply, safe_supply;
    int last_it, safe_it;          /* their iterations (-1: none this step) */
    int anchors_on;                /* keep them (a run with the ledger; dr_set_anchors) */
    double *trace;                 /* the caller's, or NULL */
    double *redo;                  /* the ledger's redo: a, b^{n+1}, the probe's b, zeros (4 n) */
    double *obs;                   /* one subsystem's observed values, read before they are logged */
    int trace_capacity;
    int n_threads;
    unsigned generation;
    Worker worker[DR_MAX_THREADS]; /* worker[0] is unused: thread 0 is the caller */
    /* the task all threads work on: evaluate their subsystems at task_in -> task_out */
    const double *task_in;
    double *task_out;
    double task_t, task_h;
    int task_how, task_measure;    /* DR_QUERY, DR_COMMIT or DR_FORWARD (kernel_internal.h) */
    DROptions *opt;                /* the DR master's named options, or NULL (the paper's Algorithm 1) */
    DRHookFn hook_before, hook_after; /* around each step of dr_run_steps_of (certs.c), or NULL */
    int *bounded, n_bounded;       /* observed values (index over all subsystems') bounded by `bound` */
    double bound;                  /* run/bounds.py's growth limit: |value| above it stops run_steps */
    void *hook_ctx;
    DRExtra extra;                 /* signals and subsystems stepped alone (signals.c), or zeros */
    long redo_do_steps;            /* the FMUs' doSteps in the ledger's redos so far */
    DRPassFn *pass_fn[DR_MAX_PASSES]; /* the runner's passes over logged steps (dr_set_passes) */
    void *pass_args[DR_MAX_PASSES];
    int n_passes;
    PlainRows plain;               /* the ledger's plain rows written last (none: at NULL) */
};

static double now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return 1e9 * (double)ts.tv_sec + (double)ts.tv_nsec;
}

/* This thread's CPU time: a step's wall time beyond it is time the machine ran something else. */
static double cpu_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return 1e9 * (double)ts.tv_sec + (double)ts.tv_nsec;
}

static void cpu_relax(void) {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

/* ---- the arithmetic of kernel/linalg.py, in the same operation order ---- */

/* y = M x (linalg.matvec). */
static void csr_matvec(const Csr *M, const double *x, double *y, size_t n) {
    dr_csr_rows(M, x, y, 0, n);
}

/* A Csr of n rows with nnz entries in one block (val first, so it stays aligned), or NULL. */
static Csr *csr_alloc(size_t n, size_t nnz) {
    Csr *M = malloc(sizeof *M + nnz * sizeof(double) + (n + 1 + nnz) * sizeof(int));
    if (!M) return NULL;
    M->n = n;
    M->nnz = nnz;
    M->val = (double *)(M + 1);
    M->start = (int *)(M->val + nnz);
    M->col = M->start + n + 1;
    return M;
}

/* The nonzero entries of a dense row-major n x n matrix. */
static Csr *csr_from_dense(const double *D, size_t n) {
    size_t nnz = 0;
    for (size_t j = 0; j < n * n; j++) nnz += D[j] != 0.0;
    Csr *M = csr_alloc(n, nnz);
    if (!M) return NULL;
    size_t p = 0;
    for (size_t i = 0; i < n; i++) {
        M->start[i] = (int)p;
        for (size_t j = 0; j < n; j++)
            if (D[i * n + j] != 0.0) {
                M->col[p] = (int)j;
                M->val[p++] = D[i * n + j];
            }
    }
    M->start[n] = (int)p;
    return M;
}

/* A copy of the caller's compressed rows, or NULL if they are malformed (or no memory). */
Csr *dr_csr_copy(const int *start, const int *col, const double *val, size_t n) {
    if (start[0] != 0) return NULL;
    for (size_t i = 0; i < n; i++)
        if (start[i + 1] < start[i]) return NULL;
    size_t nnz = (size_t)start[n];
    for (size_t p = 0; p < nnz; p++)
        if (col[p] < 0 || (size_t)col[p] >= n) return NULL;
    Csr *M = csr_alloc(n, nnz);
    if (!M) return NULL;
    memcpy(M->start, start, (n + 1) * sizeof(int));
    memcpy(M->col, col, nnz * sizeof(int));
    memcpy(M->val, val, nnz * sizeof(double));
    return M;
}

/* ---- one subsystem: the frozen port map (frozen_port_map.Subsystem) ---- */

/* S_i^n(a) (commit = 0, eq. 12) or Phi_i(x_i^n, a) (commit = 1, eq. 21) on the channels of s:
 * save x_i^n on the first call of the macro-step (line 3), restore it if an earlier query moved
 * the instance, set the incident waves, one doStep, read the outgoing waves. */
WC_INLINE int evaluate(Sub *s, const double *in, double *out, double t, double h, int commit, int measure) {
    measure = measure && s->n_samples < MAX_SAMPLES;       /* a clock read costs tens of ns: only those kept */
    double t0 = measure ? now_ns() : 0.0;
    if (!s->frozen) {
        if (fmi_get_state(s->fn.getFMUstate, s->comp, s->state, &s->failed)) return 1;
        s->n_save++;
        s->frozen = 1;
        s->dirty = 0;
    }
    if (s->dirty) {
        if (fmi_set_state(s->fn.setFMUstate, s->comp, *s->state, &s->failed)) return 1;
        s->n_restore++;
    }
    s->dirty = !commit;
    if (fmi_set_real(s->fn.setReal, s->comp, s->in_vr, s->m, in + s->offset, &s->failed)) return 1;
    /* noSetFMUStatePriorToCurrentPoint as in the reference (Subsystem.no_prior): x_i^n is restored
     * only at t, this doStep's own communication point. */
    if (fmi_do_step(s->fn.doStep, s->comp, t, h, s->no_prior, &s->failed)) return 1;
    s->n_do_step++;
    if (fmi_get_real(s->fn.getReal, s->comp, s->out_vr, s->m, out + s->offset, &s->failed)) return 1;
    if (measure) s->sample_ns[s->n_samples++] = now_ns() - t0;
    return 0;
}

/* Every subsystem of one thread on the current task; the first that failed, or -1. DR_FORWARD steps
 * from the current state with nothing saved (dr_advance). */
WC_INLINE int run_group(DRKernel *k, int thread) {
    int forward = k->task_how == DR_FORWARD;
    for (int i = 0; i < k->n_sub; i++) {
        Sub *s = &k->sub[i];
        if (s->thread != thread) continue;
        if (forward) s->frozen = 1, s->dirty = 0;
        if (evaluate(s, k->task_in, k->task_out, k->task_t, k->task_h, k->task_how != DR_QUERY, k->task_measure))
            return i;
    }
    return -1;
}

/* ---- persistent workers: spin on a task generation, then sleep on a condition variable ---- */

/* Spin until *word != value (or stop is set), for at most SPIN_NS; returns 1 if it changed. */
static int spin_while(const unsigned *word, unsigned value, const int *stop) {
    double start = -1.0;
    for (int spins = 1;; spins++) {
        if (__atomic_load_n(word, __ATOMIC_ACQUIRE) != value) return 1;
        if (stop && __atomic_load_n(stop, __ATOMIC_ACQUIRE)) return 1;
        cpu_relax();
        if (spins % 256) continue;
        if (start < 0.0) start = now_ns();
        else if (now_ns() - start > SPIN_NS) return 0;
    }
}

/* Sleep until *word != value (or stop): the waker stores *word, then reads *sleeping (both
 * seq_cst), so either it sees us asleep and signals under the mutex, or we see its store. */
static void sleep_while(Worker *w, pthread_cond_t *cond, int *sleeping, const unsigned *word, unsigned value) {
    pthread_mutex_lock(&w->mutex);
    __atomic_store_n(sleeping, 1, __ATOMIC_SEQ_CST);
    while (__atomic_load_n(word, __ATOMIC_SEQ_CST) == value && !__atomic_load_n(&w->stop, __ATOMIC_SEQ_CST))
        pthread_cond_wait(cond, &w->mutex);
    __atomic_store_n(sleeping, 0, __ATOMIC_SEQ_CST);
    pthread_mutex_unlock(&w->mutex);
}

static void wake(Worker *w, pthread_cond_t *cond, int *sleeping, unsigned *word, unsigned value) {
    __atomic_store_n(word, value, __ATOMIC_SEQ_CST);
    if (__atomic_load_n(sleeping, __ATOMIC_SEQ_CST)) {
        pthread_mutex_lock(&w->mutex);
        pthread_cond_signal(cond);
        pthread_mutex_unlock(&w->mutex);
    }
}

static void *worker_main(void *arg) {
    Worker *w = arg;
    unsigned seen = 0;
    for (;;) {
        if (!spin_while(&w->posted, seen, &w->stop)) sleep_while(w, &w->cond, &w->sleeping, &w->posted, seen);
        if (__atomic_load_n(&w->stop, __ATOMIC_ACQUIRE)) return NULL;
        unsigned g = __atomic_load_n(&w->posted, __ATOMIC_ACQUIRE);
        if (g == seen) continue;
        seen = g;
        w->failed = run_group(w->k, w->id);
        wake(w, &w->done_cond, &w->caller_sleeping, &w->done, g);
    }
}

static void post(Worker *w, unsigned g) {
    wake(w, &w->cond, &w->sleeping, &w->posted, g);
}

static void wait_done(Worker *w, unsigned g) {
    unsigned last = g - 1;       /* done holds the previous generation until this task is finished */
    if (!spin_while(&w->done, last, NULL)) sleep_while(w, &w->done_cond, &w->caller_sleeping, &w->done, last);
}

static void stop_workers(DRKernel *k) {
    for (int id = 1; id < DR_MAX_THREADS; id++) {
        Worker *w = &k->worker[id];
        if (!w->started) continue;
        __atomic_store_n(&w->stop, 1, __ATOMIC_SEQ_CST);
        pthread_mutex_lock(&w->mutex);
        pthread_cond_broadcast(&w->cond);
        pthread_mutex_unlock(&w->mutex);
        pthread_join(w->thread, NULL);
        pthread_cond_destroy(&w->done_cond);
        pthread_cond_destroy(&w->cond);
        pthread_mutex_destroy(&w->mutex);
        w->started = 0;
    }
    k->n_threads = 1;
    for (int i = 0; i < k->n_sub; i++) k->sub[i].thread = 0;
}

/* Evaluate every subsystem at in -> out (line 10 when how = DR_QUERY, lines 20-22 when DR_COMMIT),
 * each on its thread; the first failing subsystem in subsystem order, or -1. */
static int evaluate_all(DRKernel *k, const double *in, double *out, double t, double h, int how, int measure) {
    k->task_in = in;
    k->task_out = out;
    k->task_t = t;
    k->task_h = h;
    k->task_how = how;
    k->task_measure = measure;
    if (k->n_threads == 1) return run_group(k, 0);
    unsigned g = ++k->generation;
    for (int id = 1; id < k->n_threads; id++) post(&k->worker[id], g);
    int first = run_group(k, 0);
    for (int id = 1; id < k->n_threads; id++) {
        wait_done(&k->worker[id], g);
        int f = k->worker[id].failed;
        if (f >= 0 && (first < 0 || f < first)) first = f;
    }
    return first;
}

static int report_failure(DRKernel *k, DRStep *io, int i) {
    io->failed_subsystem = i;
    io->failed_function = k->sub[i].failed.function;
    io->failed_status = k->sub[i].failed.status;
    return -1;
}

static void begin_macro_step(DRKernel *k, DRStep *io) {
    for (int i = 0; i < k->n_sub; i++) {
        k->sub[i].frozen = 0;
        k->sub[i].failed.function = DR_FN_NONE;
        k->sub[i].failed.status = 0;
    }
    io->failed_subsystem = -1;
    io->failed_function = DR_FN_NONE;
    io->failed_status = 0;
}

/* ---- the DR master's named options (dr_options.h; wavecosim/masters/dr_options.py) ---- */

/* Start of a macro-step: forget the Anderson history (kept with its memory); u^0 of the start
 * (dr_options.start_point) once b^{n-1} and a^{n-1} are known: P (2 b^n - b^{n-1}), or a^{n-1}, which
 * the caller's a_hat still holds; b^n is remembered for the next step. */
static void options_begin(DRKernel *k, double *u) {
    DROptions *o = k->opt;
    if (!o->memory) o->count = o->start = 0;                     /* the Anderson memory keeps its differences */
    o->have_acc = o->candidate = 0;
    if (o->start_mode == DR_START_PAPER) return;
    if (o->have_prev && o->start_mode == DR_START_EXTRAPOLATED) {
        for (size_t j = 0; j < k->n; j++) o->z[j] = 2.0 * k->b[j] - o->b_prev[j];
        csr_matvec(k->P, o->z, u, k->n);
    } else if (o->have_prev) {
        copy_doubles(u, k->a_hat, k->n);
    }
    copy_doubles(o->b_prev, k->b, k->n);
    o->have_prev = 1;
}

/* Line 12 relaxed (dr_options.relaxed_update), then the safeguarded Anderson step. */
static void options_step(DRKernel *k, const double *u, double *u_next, const double **b_star) {
    DROptions *o = k->opt;
    if (o->lambda != 1.0)
        for (size_t j = 0; j < k->n; j++) u_next[j] = u[j] + o->lambda * (k->w[j] - k->b_hat[j]);
    if (o->m > 0) options_anderson(o, u, u_next, k->b_hat, b_star);
}

int dr_set_options(DRKernel *k, double relaxation, int anderson, int start) {
    options_free(k->opt);
    k->opt = NULL;
    if (relaxation == 1.0 && anderson == 0 && start == DR_START_PAPER) return 0;
    if (!(relaxation > 0.0 && relaxation < 2.0) || anderson < 0 || anderson > DR_ANDERSON_MAX
        || start < DR_START_PAPER || start > DR_START_PREVIOUS)
        return -1;
    k->opt = options_create(relaxation, anderson, start, k->n);
    return k->opt ? 0 : -1;
}

void dr_set_anchors(DRKernel *k, int on) { k->anchors_on = on; }

void dr_set_previous(DRKernel *k, const double *a_prev) {
    if (!k->opt) return;
    k->opt->have_prev = a_prev != NULL;
    if (a_prev) memcpy(k->a_hat, a_prev, k->n * sizeof *a_prev);
}

/* The Anderson memory across macro-steps and the extrapolated b^* (after dr_set_options); -1 without Anderson. */
int dr_set_anderson_modes(DRKernel *k, int memory, int extrapolate) {
    if (!memory && !extrapolate) return 0;
    if (!k->opt || k->opt->m == 0) return -1;
    k->opt->memory = memory;
    k->opt->extrapolate = extrapolate;
    return 0;
}

/* ---- the public API ---- */

/* The supply 1/2 (|in|^2 - |out|^2) and traffic 1/2 (|in|^2 + |out|^2) of a commit or query with
 * inputs `in` and outputs `out` (masters/base.py WaveMaster.supply: sums from 0.0, left to right). */
static void supply_of(const double *in, const double *out, size_t n, double *supplied, double *traffic) {
    double aa = 0.0, bb = 0.0;
    for (size_t j = 0; j < n; j++) aa += in[j] * in[j];
    for (size_t j = 0; j < n; j++) bb += out[j] * out[j];
    *supplied = 0.5 * (aa - bb);
    *traffic = 0.5 * (aa + bb);
}

/* A query (u, b_hat) of the step as an anchor of the energy ledger (masters/dr.py Anchors.add): the
 * last query is the one in k->u_last, k->b_hat; the latest with supply <= 0 is copied. */
static void add_anchor(DRKernel *k, const double *u, int it) {
    double traffic;
    supply_of(u, k->b_hat, k->n, &k->last_supply, &traffic);
    k->last_it = it;
    if (k->last_supply <= 0.0) {
        copy_doubles(k->safe, u, k->n);
        copy_doubles(k->safe + k->n, k->b_hat, k->n);
        k->safe_supply = k->last_supply;
        k->safe_it = it;
    }
}

/* Lines 9-17 from the iterate in k->u, iterations it .. K - 1 (the tolerance exit when use_eps; a
 * deadline in ns, or 0): b_star becomes the last response (line 13), u^K goes to k->uK and the
 * last query point to k->u_last. Returns the iterations made, or -1 when an FMU call failed. */
static int iterate(DRKernel *k, DRStep *io, int it, int K, int use_eps, double deadline, const double **b_star) {
    size_t n = k->n;
    double *u = k->u, *u_next = k->u_next;
    int first = it;
    io->reason = DR_BUDGET;
    while (it < K) {                                             /* line 9 */
        int f = evaluate_all(k, u, k->b_hat, io->t, io->dt, 0, io->measure); /* line 10, eq. (17) response */
        if (f >= 0) return report_failure(k, io, f);
        if (k->trace && it < k->trace_capacity) {
            copy_doubles(k->trace + 2 * n * (size_t)it, u, n);
            copy_doubles(k->trace + 2 * n * (size_t)it + n, k->b_hat, n);
        }
        if (k->anchors_on) add_anchor(k, u, it);
        for (size_t j = 0; j < n; j++) k->z[j] = 2.0 * k->b_hat[j] - u[j];
        csr_matvec(k->J_L, k->z, k->w, n);                           /* line 11, eq. (17): w = J_L(2b - u) */
        for (size_t j = 0; j < n; j++) u_next[j] = u[j] + k->w[j] - k->b_hat[j]; /* line 12, eq. (17) update */
        *b_star = k->b_hat;                                      /* line 13, eq. (20): b^* = last b */
        if (k->opt) options_step(k, u, u_next, b_star);          /* relaxation, Anderson acceleration */
        io->residual = distance(u_next, u, n);
        double *swap = u;
        u = u_next;
        u_next = swap;
        it++;
        if (use_eps && io->eps >= 0.0 && io->residual <= io->eps) { /* lines 14-16: optional exit */
            io->reason = DR_TOLERANCE;
            break;
        }
        if (deadline > 0.0 && now_ns() >= deadline) {
            io->reason = DR_DEADLINE;
            break;
        }
    }
    if (it > first) {
        k->u_last = u_next;
        k->u_next = u_next;                                      /* the next loop leaves the query alone */
        k->u = u;
    }
    copy_doubles(k->uK, u, n);
    return it - first;
}

int dr_macro_step(DRKernel *k, DRStep *io) {
    size_t n = k->n;
    begin_macro_step(k, io);
    double deadline = io->deadline_s > 0.0 ? now_ns() + 1e9 * io->deadline_s : 0.0;
    double *u = k->u;
    csr_matvec(k->P, k->b, u, n);                                    /* line 6, eq. (19): u^0 = P b^n */
    if (k->opt) options_begin(k, u);                             /* other starts (dr_options.start_point) */
    copy_doubles(k->u0, u, n);
    const double *b_star = k->b;                                 /* line 7, eq. (19): b^* = b^n */
    k->last_it = k->safe_it = -1;                                /* no anchors yet */
    io->residual = NAN;
    int it = iterate(k, io, 0, io->K, 1, deadline, &b_star);
    if (it < 0) return -1;
    csr_matvec(k->P, b_star, k->a_hat, n);                           /* line 19, eq. (21): a = P b^* */
    io->iterations = it;
    if (!io->K) io->reason = DR_EXPLICIT;
    /* lines 20-22, eq. (21): commit Phi_i(x_i^n, a_i); the outgoing waves are b^{n+1} */
    int f = evaluate_all(k, k->a_hat, k->b, io->t, io->dt, 1, io->measure);
    return f >= 0 ? report_failure(k, io, f) : 0;
}

int dr_set_observed(DRKernel *k, int i, const fmi2ValueReference *vrs, int count) {
    if (i < 0 || i >= k->n_sub || count < 0) return -1;
    Sub *s = &k->sub[i];
    size_t largest = (size_t)count;
    for (int j = 0; j < k->n_sub; j++)
        if (j != i && k->sub[j].n_obs > largest) largest = k->sub[j].n_obs;
    fmi2ValueReference *copy = malloc(((size_t)count + 1) * sizeof *copy);
    double *obs = malloc((largest + 1) * sizeof *obs);
    if (!copy || !obs) {
        free(copy);
        free(obs);
        return -1;
    }
    memcpy(copy, vrs, (size_t)count * sizeof *vrs);
    free(s->obs_vr);
    free(k->obs);
    s->obs_vr = copy;
    s->n_obs = (size_t)count;
    s->obs_get = s->fn.getReal;
    s->obs_comp = s->comp;
    s->obs_no_H = 0;
    k->obs = obs;
    return 0;
}

int dr_set_bound(DRKernel *k, double bound, const int *indices, int count) {
    int *copy = count > 0 ? malloc((size_t)count * sizeof *copy) : NULL;
    if (count < 0 || (count > 0 && !copy)) return -1;
    if (count > 0) memcpy(copy, indices, (size_t)count * sizeof *indices);
    free(k->bounded);
    k->bounded = copy;
    k->n_bounded = count;
    k->bound = bound;
    return 0;
}

int dr_set_observed_view(DRKernel *k, int i, fmi2GetRealTYPE *get, fmi2Component comp, int no_H) {
    if (i < 0 || i >= k->n_sub || !get) return -1;
    k->sub[i].obs_get = get;
    k->sub[i].obs_comp = comp;
    k->sub[i].obs_no_H = no_H;
    return 0;
}

int dr_set_adapter(DRKernel *k, int i, const double *worst, const long *do_steps) {
    if (i < 0 || i >= k->n_sub) return -1;
    k->sub[i].noise = worst;
    k->sub[i].fmu_do_steps = do_steps;
    return 0;
}

long dr_redo_do_steps(const DRKernel *k) { return k->redo_do_steps; }

void dr_set_extra(DRKernel *k, const DRExtra *extra) {
    static const DRExtra none = {0};
    k->extra = extra ? *extra : none;
}

size_t dr_log_width(const DRKernel *k) {
    size_t width = 3 + 2 * k->n;
    for (int i = 0; i < k->n_sub; i++) width += k->sub[i].n_obs;
    return width + k->extra.rows + DR_LEDGER_COLUMNS;
}

/* Whether v is infinite or NaN: its exponent bits all set (integer operations, no chain of
 * floating-point additions through the step's values). */
static inline int not_finite(double v) {
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    return (bits & 0x7ff0000000000000u) == 0x7ff0000000000000u;
}

/* Log step s after its commit, column-major: value c at rows[c ld + s]; the first failing subsystem's
 * read, or -1. *finite: whether every observed value checked by stop_after is finite. */
static int log_step(DRKernel *k, const DRStep *io, double *rows, size_t ld, size_t s, int *finite) {
    size_t n = k->n, c = 3 + 2 * n;         /* locals: the stores into rows may alias k's arrays */
    const double *a_hat = k->a_hat, *b = k->b, *obs = k->obs;
    double *row = rows + s;
    int bad = 0;
    row[0] = (double)io->iterations;
    row[ld] = (double)io->reason;
    row[2 * ld] = io->residual;
    for (size_t j = 0; j < n; j++) {
        row[(3 + j) * ld] = a_hat[j];
        row[(3 + n + j) * ld] = b[j];
    }
    for (int i = 0; i < k->n_sub; i++) {
        Sub *s_i = &k->sub[i];
        size_t n_obs = s_i->n_obs, j = 0;
        if (!n_obs) continue;
        if (fmi_get_real(s_i->obs_get, s_i->obs_comp, s_i->obs_vr, n_obs, k->obs, &s_i->failed)) return i;
        double *to = row + c * ld;
        if (s_i->obs_no_H) to[0] = obs[j++];                         /* no stored energy: NaN, not checked */
        for (; j < n_obs; j++) {
            double v = obs[j];
            to[j * ld] = v;
            bad |= not_finite(v);
        }
        c += n_obs;
    }
    if (k->extra.rows && k->extra.observe(k->extra.ctx, rows + c * ld + s, ld)) return DR_FAILED_EXTRA;
    for (size_t j = 0; j < k->extra.rows; j++) bad |= not_finite(rows[(c + j) * ld + s]);
    *finite = !bad;
    return -1;
}

/* Stop after this step? When an observed value is not finite (log_step's `finite`), when a bounded
 * one (obs: the step's column of them, stride ld) is above the bound (dr_set_bound), or when the
 * stored energy (the sum of every subsystem's first observed value) may exceed H_cap: the bound
 * 4 n_sub eps sum|H_i| covers any order of summation, so the caller's exact test never sees a step
 * above the cap go by. */
static int stop_after(const DRKernel *k, const double *obs, size_t ld, double H_cap, int finite) {
    if (!finite) return 1;
    for (int b = 0; b < k->n_bounded; b++)
        if (fabs(obs[(size_t)k->bounded[b] * ld]) > k->bound) return 1;
    if (!isfinite(H_cap)) return 0;
    double sum = 0.0, magnitude = 0.0;
    for (int i = 0; i < k->n_sub; i++) {
        const Sub *s = &k->sub[i];
        if (s->n_obs && !s->obs_no_H) {
            sum += obs[0];
            magnitude += fabs(obs[0]);
        }
        obs += s->n_obs * ld;
    }
    return sum + 4.0 * k->n_sub * DBL_EPSILON * magnitude > H_cap;
}

/* ---- the interface energy ledger and its scaled redo (wavecosim/masters/ledger.py) ---- */

#define LEDGER_TARGET 0.9          /* ledger.TARGET */
#define LEDGER_SMOOTH 0.1          /* ledger.SMOOTH */
#define LEDGER_MIN_INNER_S 1e-9    /* masters/base.py MIN_INNER_S */

/* The supply of the input q + s (a - q), its outputs interpolated between yq (at q) and ya (at a)
 * (ledger.segment_root's model). */
static double blended_supply(const double *q, const double *a, const double *yq, const double *ya, size_t n,
                             double s) {
    double aa = 0.0, bb = 0.0;
    for (size_t j = 0; j < n; j++) {
        double x = q[j] + s * (a[j] - q[j]);
        aa += x * x;
    }
    for (size_t j = 0; j < n; j++) {
        double y = yq[j] + s * (ya[j] - yq[j]);
        bb += y * y;
    }
    return 0.5 * (aa - bb);
}

/* ledger.largest_root, operation for operation (Python's max keeps the first of equals). */
static double largest_root(double q0, double qh, double q1, double target) {
    double alpha = 2.0 * (q1 - 2.0 * qh + q0), beta = q1 - q0 - alpha, gamma = q0 - target;
    double roots[2];
    int count = 0;
    if (fabs(alpha) <= 1e-12 * (fabs(beta) + fabs(gamma))) {
        if (beta != 0.0) roots[count++] = -gamma / beta;
    } else {
        double disc = beta * beta - 4.0 * alpha * gamma;
        if (0.0 > disc) disc = 0.0;
        double sq = beta != 0.0 ? copysign(sqrt(disc), beta) : sqrt(disc);
        double big = -0.5 * (beta + sq);                          /* the stable pair of quadratic roots */
        roots[count++] = big / alpha;
        if (big != 0.0) roots[count++] = gamma / big;
    }
    int found = 0;
    double best = 0.0;
    for (int i = 0; i < count; i++)
        if (0.0 <= roots[i] && roots[i] < 1.0 && (!found || roots[i] > best)) {
            best = roots[i];
            found = 1;
        }
    return best;
}

/* Every subsystem back at x_i^n after the commit (masters/base.py undo_step); the first failing one, or -1. */
static int restore_all(DRKernel *k) {
    for (int i = 0; i < k->n_sub; i++) {
        Sub *s = &k->sub[i];
        if (fmi_set_state(s->fn.setFMUstate, s->comp, *s->state, &s->failed)) return i;
        s->n_restore++;
        s->dirty = 0;
    }
    return -1;
}

/* The running time of one evaluation round (every subsystem once), as EnergyLedger._time_round: a
 * sample is taken at most at twice the estimate, so that a step the machine descheduled does not
 * shorten the next steps' inner loops (a real rise is followed within a few steps). */
static void track(double *estimate, double seconds) {
    if (*estimate > 0.0 && seconds > 2.0 * *estimate) seconds = 2.0 * *estimate;
    *estimate = *estimate > 0.0 ? (1.0 - LEDGER_SMOOTH) * *estimate + LEDGER_SMOOTH * seconds : seconds;
}

static void track_round(DRStep *io, double seconds) { track(&io->round_s, seconds); }

/* ledger.segment_root: the fraction s in [0, 1) where the supply of q + s (a - q) reaches target. */
static double segment_root(const double *q, const double *a, const double *yq, const double *ya, size_t n,
                           double supplied_a, double target) {
    return largest_root(blended_supply(q, a, yq, ya, n, 0.0), blended_supply(q, a, yq, ya, n, 0.5), supplied_a, target);
}

/* One redo (ledger.Redo): the step it corrects (inputs a and outputs y in k->redo, supply),
 * its allowance, the time left (s) and per round, the rounds made, and the result out[0..4]. */
typedef struct {
    DRKernel *k;
    DRStep *io;
    double budget, supplied, left, round;
    int rounds;
    double *out;
} Redo;

enum { REDO_DONE = -1, REDO_NEXT = -2 };   /* or >= 0: the first failing subsystem */

/* Redo.has: whether `rounds` evaluation rounds are left before the deadline, the redo's own counted. */
static int redo_has(const Redo *r, int rounds) { return r->left - r->rounds * r->round >= rounds * r->round; }

/* Redo.kept: the commit just made (k->a_hat -> k->b) is the result if it fits (or is zero); else the
 * step is undone and, after a continued iteration, that commit is the one the next stages correct. */
static int redo_kept(Redo *r, double s, int action) {
    DRKernel *k = r->k;
    size_t n = k->n;
    double supplied, traffic;
    supply_of(k->a_hat, k->b, n, &supplied, &traffic);
    if (supplied <= r->budget || action == DR_LEDGER_ZERO) {
        double *out = r->out;
        out[0] = s, out[1] = supplied, out[2] = traffic, out[3] = action, out[4] = r->rounds;
        return REDO_DONE;
    }
    int f = restore_all(k);
    if (f >= 0) return f;
    if (action == DR_LEDGER_ITERATED) {
        memcpy(k->redo, k->a_hat, n * sizeof *k->a_hat);
        memcpy(k->redo + n, k->b, n * sizeof *k->b);
        r->supplied = supplied;
    }
    return REDO_NEXT;
}

/* Redo.commit: commit k->a_hat (filled by the caller) after an undo, then redo_kept. */
static int redo_commit(Redo *r, double s, int action) {
    DRKernel *k = r->k;
    int f = evaluate_all(k, k->a_hat, k->b, r->io->t, r->io->dt, 1, 0);
    if (f >= 0) return f;
    r->rounds++;
    return redo_kept(r, s, action);
}

/* k->a_hat = q + s (a - q) (ledger.blend). */
static void blend_into(DRKernel *k, const double *q, const double *a, double s) {
    for (size_t j = 0; j < k->n; j++) k->a_hat[j] = q[j] + s * (a[j] - q[j]);
}

/* Stage 1 (EnergyLedger._iterated): the rest of the inner budget from u^K (three rounds of the
 * deadline left), without the tolerance exit, and its commit; the step's residual and reason stay. */
static int redo_iterated(Redo *r) {
    DRKernel *k = r->k;
    DRStep *io = r->io;
    if (io->K - io->iterations <= 0 || !redo_has(r, 3)) return REDO_NEXT;
    double deadline = isfinite(r->left) ? now_ns() + 1e9 * (r->left - 2.0 * r->round) : 0.0;
    double residual = io->residual;
    int reason = io->reason;
    const double *b_star = k->b;
    int made = iterate(k, io, io->iterations, io->K, 0, deadline, &b_star);
    io->residual = residual, io->reason = reason;
    if (made < 0) return io->failed_subsystem;
    csr_matvec(k->P, b_star, k->a_hat, k->n);
    r->rounds += made;
    return redo_commit(r, 1.0, DR_LEDGER_ITERATED);
}

/* ledger.projected into k->a_hat: a (k->redo) moved against the gradient g = a - rho y of the
 * step's supply (rho per subsystem: the secant to the last query, clamped to [0, 1]) to the smaller
 * root t of supplied - t |g|^2 + t^2 / 2 sum (1 - rho^2) g^2 = target. 0, or -1 without a root. */
static int project_into(DRKernel *k, double supplied, double target) {
    size_t n = k->n;
    const double *a = k->redo, *y = a + n, *u = k->u_last, *b = k->b_hat;
    double *g = k->w, *q = k->z;                                 /* the inner loop's scratch, free now */
    for (int i = 0; i < k->n_sub; i++) {
        size_t off = k->sub[i].offset, m = k->sub[i].m;
        double den = 0.0, num = 0.0;
        for (size_t j = off; j < off + m; j++) den += (a[j] - u[j]) * (a[j] - u[j]);
        for (size_t j = off; j < off + m; j++) num += (a[j] - u[j]) * (y[j] - b[j]);
        double rho = den > 0.0 ? num / den : 0.0;
        if (0.0 > rho) rho = 0.0;                                /* min(max(rho, 0), 1) as Python's */
        if (1.0 < rho) rho = 1.0;
        for (size_t j = off; j < off + m; j++) {
            g[j] = a[j] - rho * y[j];
            q[j] = 1.0 - rho * rho;
        }
    }
    double curve = 0.0, slope = 0.0, excess = supplied - target;
    for (size_t j = 0; j < n; j++) curve += q[j] * g[j] * g[j];
    curve = 0.5 * curve;
    slope = -dot(g, g, n);
    if (!(slope < 0.0)) return -1;
    double disc = slope * slope - 4.0 * curve * excess;
    if (!(disc >= 0.0)) return -1;
    double t = 2.0 * excess / (sqrt(disc) - slope);
    for (size_t j = 0; j < n; j++) k->a_hat[j] = a[j] - t * g[j];
    return 0;
}

/* Stage 2 (EnergyLedger._projected): the commit at project_into's input (two rounds left). */
static int redo_projected(Redo *r) {
    DRKernel *k = r->k;
    if (k->last_it < 0 || !redo_has(r, 2) || project_into(k, r->supplied, LEDGER_TARGET * r->budget)) return REDO_NEXT;
    double s = 1.0 - distance(k->a_hat, k->redo, k->n) / sqrt(dot(k->redo, k->redo, k->n));
    return redo_commit(r, s, DR_LEDGER_PROJECTED);
}

/* Stages 3 and 4 (EnergyLedger._anchored, ledger.best_anchor): of the anchors (the last query,
 * the latest safe one) whose supply fits, the one whose crossing of the target lies nearest a; the
 * commit there (two rounds left), else, or on a miss, at the anchor itself. */
static int redo_anchored(Redo *r) {
    DRKernel *k = r->k;
    size_t n = k->n;
    const double *a = k->redo, *y = a + n, *q = NULL;
    const double *cand[2][2] = {{k->u_last, k->b_hat}, {k->safe, k->safe + n}};
    double supply[2] = {k->last_supply, k->safe_supply}, target = LEDGER_TARGET * r->budget, best_d = 0.0, best_s = 0.0;
    int count = (k->last_it >= 0) + (k->safe_it >= 0 && k->safe_it != k->last_it), from = k->last_it >= 0 ? 0 : 1;
    for (int c = from; c < from + count; c++) {
        if (!(supply[c] <= target)) continue;
        double s = segment_root(cand[c][0], a, cand[c][1], y, n, r->supplied, target);
        double d = (1.0 - s) * distance(a, cand[c][0], n);
        if (!q || d < best_d) best_d = d, best_s = s, q = cand[c][0];
    }
    if (!q) return REDO_NEXT;
    if (redo_has(r, 2)) {
        blend_into(k, q, a, best_s);
        int f = redo_commit(r, best_s, DR_LEDGER_BLENDED);
        if (f != REDO_NEXT) return f;
    }
    memcpy(k->a_hat, q, n * sizeof *q);
    return redo_commit(r, 0.0, DR_LEDGER_ANCHORED);
}

/* Stage 5 (EnergyLedger._scaled): a probe at zero inputs and the commit at the fitted s (two rounds left). */
static int redo_scaled(Redo *r) {
    DRKernel *k = r->k;
    size_t n = k->n;
    double *a = k->redo, *y = a + n, *y0 = y + n, *zero = y0 + n;
    if (!redo_has(r, 2)) return REDO_NEXT;
    int f = evaluate_all(k, zero, y0, r->io->t, r->io->dt, 0, 0);
    if (f >= 0) return f;
    r->rounds++;
    double s = segment_root(zero, a, y0, y, n, r->supplied, LEDGER_TARGET * r->budget);
    blend_into(k, zero, a, s);
    return redo_commit(r, s, DR_LEDGER_SCALED);
}

/* Undo the step and make it again (EnergyLedger._redo): iterated, projected, blended or anchored, scaled, and
 * zero inputs (matched loads, always safe) as the last resort. out: s, supply, traffic, action,
 * rounds; k->a_hat ends as the inputs committed, k->b as b^{n+1}. The first failing subsystem, or -1. */
static int ledger_redo(DRKernel *k, DRStep *io, double supplied_1, double budget, double left, double round,
                       double *out) {
    size_t n = k->n;
    double *zero = k->redo + 3 * n;
    memcpy(k->redo, k->a_hat, n * sizeof *k->a_hat);
    memcpy(k->redo + n, k->b, n * sizeof *k->b);
    for (size_t j = 0; j < n; j++) zero[j] = 0.0;
    Redo r = {k, io, budget, supplied_1, left, round, 0, out};
    int f = restore_all(k);
    if (f >= 0) return f;
    f = redo_iterated(&r);
    if (f == REDO_NEXT) f = redo_projected(&r);
    if (f == REDO_NEXT) f = redo_anchored(&r);
    if (f == REDO_NEXT) f = redo_scaled(&r);
    if (f == REDO_NEXT) {
        memcpy(k->a_hat, zero, n * sizeof *zero);
        f = redo_commit(&r, 0.0, DR_LEDGER_ZERO);
    }
    return f == REDO_DONE ? -1 : f;
}

/* Scene.map_noise: the worst relative residual a wave adapter kept, 0.0 for exact maps. */
static double map_noise(const DRKernel *k) {
    double noise = 0.0;
    for (int i = 0; i < k->n_sub; i++)
        if (k->sub[i].noise && *k->sub[i].noise > noise) noise = *k->sub[i].noise;
    return noise;
}

/* doSteps the FMUs made so far (a wave adapter's own count: its queries take a varying number). */
static long fmu_do_steps(const DRKernel *k) {
    long n = 0;
    for (int i = 0; i < k->n_sub; i++) n += k->sub[i].fmu_do_steps ? *k->sub[i].fmu_do_steps : k->sub[i].n_do_step;
    return n;
}

/* Whether a step is timed: only a deadline reads the step and round times (a clock read costs
 * ~30 ns, a tenth of a macro-step at K = 0). */
static int clocked(const DRStep *io) { return io->step_deadline_s > 0.0 || io->deadline_s > 0.0; }

/* A step's ledger row: out = {scale, supplied, traffic, action, redo rounds} (LEDGER_UNTOUCHED before
 * the ledger sees the step), the wall and CPU seconds it took (NaN: not timed). */
#define LEDGER_UNTOUCHED {1.0, NAN, NAN, DR_LEDGER_KEPT, 0.0}
static void ledger_row(const DRStep *io, const double out[5], double wall, double cpu, double *logged) {
    const double row[DR_LEDGER_COLUMNS] = {out[1], io->ledger_on ? io->ledger : NAN,
                                           io->ledger_on ? io->traffic : NAN, out[0], out[3], out[4], wall,
                                           io->round_s, cpu};
    memcpy(logged, row, sizeof row);
}

/* Book the step just committed (EnergyLedger.after_step): I = 1/2 (|a|^2 - |b|^2); a step with
 * L + I > tol = rtol (traffic + its own) is redone by ledger_redo first. Its row goes into the log's
 * last DR_LEDGER_COLUMNS columns; io->reason becomes DR_ENERGY_GUARD when it was redone. timed:
 * clocked(io); t0, c0: the step's start, wall and CPU (ns). The first failing subsystem, or -1 (the
 * step then is neither booked nor logged). */
static int ledger_step(DRKernel *k, DRStep *io, int timed, double t0, double c0, double *row, size_t ld) {
    if (!io->ledger_on && !timed) return -1;                    /* its row: plain_ledger_rows */
    double out[5] = LEDGER_UNTOUCHED;
    if (io->ledger_on) {
        double now = timed ? now_ns() : 0.0, tol;
        if (timed)
            track_round(io, 1e-9 * (now - t0) / (io->iterations + 1));
        if (timed && io->reason == DR_DEADLINE && io->step_deadline_s > 0.0)      /* past the inner deadline */
            track(&io->tail_s, 1e-9 * (now - t0) - io->deadline_s);
        supply_of(k->a_hat, k->b, k->n, &out[1], &out[2]);
        tol = (io->ledger_rtol + map_noise(k)) * (io->traffic + out[2]);
        if (io->ledger + out[1] > tol) {
            double left = io->step_deadline_s > 0.0 ? io->step_deadline_s - 1e-9 * (now - t0) : INFINITY;
            long made = fmu_do_steps(k);
            int f = ledger_redo(k, io, out[1], tol - io->ledger, left, io->round_s, out);
            k->redo_do_steps += fmu_do_steps(k) - made;
            if (f >= 0) return f;
            if (timed)
                track_round(io, 1e-9 * (now_ns() - now) / out[4]);
            io->reason = DR_ENERGY_GUARD;
        }
        io->ledger += out[1];
        io->traffic += out[2];
    }
    /* the wall clock is read between the CPU clock's reads (system calls), which it so leaves out */
    double wall = timed ? 1e-9 * (now_ns() - t0) : NAN;
    double cpu = c0 > 0.0 ? 1e-9 * (cpu_ns() - c0) : NAN;
    double logged[DR_LEDGER_COLUMNS];
    ledger_row(io, out, wall, cpu, logged);
    for (int c = 0; c < DR_LEDGER_COLUMNS; c++) row[(size_t)c * ld] = logged[c];
    return -1;
}

/* The ledger's row of every step of a call without the ledger or a clock: the same each step
 * (untouched, untimed). */
static void plain_row(const DRStep *io, double logged[DR_LEDGER_COLUMNS]) {
    const double out[5] = LEDGER_UNTOUCHED;
    ledger_row(io, out, NAN, NAN, logged);
}

/* That row for `count` steps from rows, ld apart, remembered (k->plain). */
static void write_plain_rows(DRKernel *k, double *rows, size_t ld, int count,
                             const double logged[DR_LEDGER_COLUMNS]) {
    for (int c = 0; c < DR_LEDGER_COLUMNS; c++) {
        double v = logged[c], *to = rows + (size_t)c * ld;
        for (int s = 0; s < count; s++) to[s] = v;
    }
    k->plain.at = rows;
    k->plain.ld = ld;
    k->plain.count = count;
    memcpy(k->plain.value, logged, sizeof k->plain.value);
}

/* The plain rows of a call's `count` steps from rows, written before the steps unless the last ones
 * written hold them (same values and ld, these steps among theirs): only dr_run_steps_of and
 * dr_prepare_log write the log's ledger rows, and a call with the ledger or a clock forgets them. */
static void plain_ledger_rows(DRKernel *k, const DRStep *io, double *rows, size_t ld, int count) {
    double logged[DR_LEDGER_COLUMNS];
    plain_row(io, logged);
    const PlainRows *last = &k->plain;
    uintptr_t from = (uintptr_t)last->at, at = (uintptr_t)rows, size = sizeof *rows;
    int within = last->at && at >= from && at + (size_t)count * size <= from + (size_t)last->count * size;
    if (within && last->ld == ld && !memcmp(last->value, logged, sizeof logged)) return;
    write_plain_rows(k, rows, ld, count, logged);
}

void dr_prepare_log(DRKernel *k, const DRStep *io, double *rows, long ld, int count) {
    double logged[DR_LEDGER_COLUMNS];
    plain_row(io, logged);
    write_plain_rows(k, rows + (dr_log_width(k) - DR_LEDGER_COLUMNS) * (size_t)ld, (size_t)ld, count, logged);
}

int dr_ledger_redo(DRKernel *k, DRStep *io, double supplied, double budget, double left_s, double round_s,
                   double *out) {
    int f = ledger_redo(k, io, supplied, budget, left_s, round_s, out);
    return f >= 0 ? report_failure(k, io, f) : 0;
}

/* dr_macro_step; under a step deadline with the ledger, its inner loop stops early enough for its
 * last iteration's overrun and the commit to end by the deadline, so that an s = 0 redo ends within
 * a round of it: two rounds before it at first, then the running time steps took past the inner
 * deadline (io->tail_s, from ledger_step: on average half a round of overrun and the commit, whose
 * code may be cold when the caller ran between steps) plus a round for the spread of the overrun.
 * The inner deadline stays in io->deadline_s for ledger_step; dr_run_steps restores the caller's. */
static int guarded_macro_step(DRKernel *k, DRStep *io) {
    if (io->ledger_on && io->step_deadline_s > 0.0) {
        double reserve = io->tail_s > 0.0 ? io->tail_s + io->round_s : 2.0 * io->round_s;
        double inner = io->step_deadline_s - reserve;
        io->deadline_s = inner > LEDGER_MIN_INNER_S ? inner : LEDGER_MIN_INNER_S;
    }
    return dr_macro_step(k, io);
}

static int guarded_step_of(void *k, DRStep *io) { return guarded_macro_step(k, io); }

int dr_run_steps(DRKernel *k, DRStep *io, int n0, int count, double *rows, long ld, double H_cap) {
    return dr_run_steps_of(k, io, n0, count, rows, ld, H_cap, guarded_step_of, k);
}

int dr_set_passes(DRKernel *k, int n, DRPassFn *const *fns, void *const *args) {
    if (n < 0 || n > DR_MAX_PASSES) return -1;
    for (int j = 0; j < n; j++) {
        k->pass_fn[j] = fns[j];
        k->pass_args[j] = args[j];
    }
    k->n_passes = n;
    return 0;
}

/* The passes over steps io->passed .. upto - 1 of the block from macro-step n0 (log0: its column 0). */
static void make_passes(const DRKernel *k, DRStep *io, int n0, const double *log0, long ld, int upto) {
    if (upto <= io->passed) return;
    for (int j = 0; j < k->n_passes; j++)
        k->pass_fn[j](k->pass_args[j], n0, log0, ld, io->passed, upto - io->passed);
    io->passed = upto;
}

int dr_run_steps_of(DRKernel *k, DRStep *io, int n0, int count, double *rows, long ld, double H_cap, DRStepFn step,
                    void *ctx) {
    size_t m = (size_t)ld, first_observed = (3 + 2 * k->n) * m;
    double *ledger_rows = rows + (dr_log_width(k) - DR_LEDGER_COLUMNS) * m;
    const double *log0 = rows - io->at;
    int passing = io->passes && k->n_passes > 0;
    int every = io->passes == DR_PASSES_EACH ? 1 : DR_PASS_STEPS;
    io->stopped = 0;
    if (io->at == 0) io->passed = 0;
    for (int i = 0; io->measure && i < k->n_sub; i++) k->sub[i].n_samples = 0;   /* dr_costs: this call's */
    int timed = clocked(io), cpu_timed = io->ledger_on && io->step_deadline_s > 0.0;     /* the same every step */
    if (!io->ledger_on && !timed) plain_ledger_rows(k, io, ledger_rows, m, count);
    else k->plain.at = NULL;                                     /* ledger_step writes the rows */
    for (int s = 0; s < count; s++) {
        io->t = io->t0 + (double)(n0 + s) * io->dt;
        if (k->extra.before && k->extra.before(k->extra.ctx, io, n0 + s)) {      /* held signals: failed */
            io->failed_subsystem = DR_FAILED_EXTRA;
            return s;
        }
        if (k->hook_before && k->hook_before(k->hook_ctx, io, n0 + s)) return s;    /* not the step's time */
        double c0 = cpu_timed ? cpu_ns() : 0.0, t0 = timed ? now_ns() : 0.0;
        double caller = io->deadline_s;
        int failure = step(ctx, io);
        int f = failure ? -1 : ledger_step(k, io, timed, t0, c0, ledger_rows + s, m);
        io->deadline_s = caller;
        if (failure) return s;
        int finite = 1;
        if (f < 0) f = log_step(k, io, rows, m, (size_t)s, &finite);
        if (f == DR_FAILED_EXTRA) {                                  /* a subsystem stepped alone */
            io->failed_subsystem = DR_FAILED_EXTRA;
            return s;
        }
        if (f >= 0) {
            report_failure(k, io, f);
            return s;
        }
        if (k->hook_after) k->hook_after(k->hook_ctx, io, n0 + s);
        if (stop_after(k, rows + first_observed + s, m, H_cap, finite)) {
            io->stopped = 1;
            return s + 1;
        }
        if (passing && io->at + s + 1 - io->passed >= every)      /* the last steps still in cache */
            make_passes(k, io, n0 - io->at, log0, ld, io->at + s + 1);
    }
    if (passing) make_passes(k, io, n0 - io->at, log0, ld, io->at + count);
    return count;
}

DRKernel *dr_create(int n_sub, int n, const double *P, const double *J_L, double *b, double *a_hat,
                    double *u0, double *uK) {
    if (n_sub < 0 || n < 0 || (n_sub == 0) != (n == 0)) return NULL;   /* none: signals only (signals.c) */
    DRKernel *k = calloc(1, sizeof *k);
    if (!k) return NULL;
    size_t nn = (size_t)n, room = nn ? nn : 1;
    k->n_sub = n_sub;
    k->n = nn;
    k->sub = calloc((size_t)(n_sub ? n_sub : 1), sizeof *k->sub);
    k->P = P ? csr_from_dense(P, nn) : csr_alloc(nn, 0);
    k->J_L = J_L ? csr_from_dense(J_L, nn) : csr_alloc(nn, 0);
    k->work = calloc(7 * room, sizeof(double));
    k->redo = calloc(4 * room, sizeof(double));
    if (!k->sub || !k->P || !k->J_L || !k->work || !k->redo) {
        dr_destroy(k);
        return NULL;
    }
    if (!P) memset(k->P->start, 0, (nn + 1) * sizeof(int));
    if (!J_L) memset(k->J_L->start, 0, (nn + 1) * sizeof(int));
    k->u = k->work;
    k->u_next = k->work + nn;
    k->b_hat = k->work + 2 * nn;
    k->z = k->work + 3 * nn;
    k->w = k->work + 4 * nn;
    k->safe = k->work + 5 * nn;
    k->last_it = k->safe_it = -1;
    k->b = b;
    k->a_hat = a_hat;
    k->u0 = u0;
    k->uK = uK;
    k->n_threads = 1;
    return k;
}

int dr_set_subsystem(DRKernel *k, int i, const DRFunctions *fn, fmi2Component comp, fmi2FMUstate *state,
                     const fmi2ValueReference *in_vr, const fmi2ValueReference *out_vr, int m, int offset) {
    if (i < 0 || i >= k->n_sub || m < 1 || offset < 0 || (size_t)offset + (size_t)m > k->n) return -1;
    if (!fn->getFMUstate || !fn->setFMUstate || !fn->freeFMUstate || !fn->setReal || !fn->doStep || !fn->getReal)
        return -1;
    Sub *s = &k->sub[i];
    if (s->own_state) fmi_free_state(s->fn.freeFMUstate, s->comp, &s->own_state);
    free(s->in_vr);
    s->in_vr = malloc(2 * (size_t)m * sizeof *s->in_vr);
    if (!s->in_vr) return -1;
    s->out_vr = s->in_vr + m;
    memcpy(s->in_vr, in_vr, (size_t)m * sizeof *in_vr);
    memcpy(s->out_vr, out_vr, (size_t)m * sizeof *out_vr);
    s->fn = *fn;
    s->comp = comp;
    s->state = state ? state : &s->own_state;
    s->m = (size_t)m;
    s->offset = (size_t)offset;
    return 0;
}

int dr_set_no_prior(DRKernel *k, int i, int no_prior) {
    if (i < 0 || i >= k->n_sub) return -1;
    k->sub[i].no_prior = no_prior != 0;
    return 0;
}

int dr_set_maps(DRKernel *k, const int *P_start, const int *P_col, const double *P_val, const int *J_start,
                const int *J_col, const double *J_val) {
    Csr *P = dr_csr_copy(P_start, P_col, P_val, k->n), *J_L = dr_csr_copy(J_start, J_col, J_val, k->n);
    if (!P || !J_L) {
        free(P);
        free(J_L);
        return -1;
    }
    free(k->P);
    free(k->J_L);
    k->P = P;
    k->J_L = J_L;
    return 0;
}

void dr_set_trace(DRKernel *k, double *trace, int capacity) {
    k->trace = capacity > 0 ? trace : NULL;
    k->trace_capacity = capacity > 0 ? capacity : 0;
}

int dr_set_threads(DRKernel *k, int n_threads, const int *thread_of) {
    int valid = n_threads >= 1 && n_threads <= DR_MAX_THREADS;
    for (int i = 0; valid && n_threads > 1 && i < k->n_sub; i++)
        valid = thread_of[i] >= 0 && thread_of[i] < n_threads;
    if (valid && n_threads > 1 && n_threads == k->n_threads) {   /* the workers idle between tasks: re-plan only */
        for (int i = 0; i < k->n_sub; i++) k->sub[i].thread = thread_of[i];
        return 0;
    }
    stop_workers(k);
    if (!valid) return -1;
    if (n_threads == 1) return 0;
    for (int id = 1; id < n_threads; id++) {
        Worker *w = &k->worker[id];
        memset(w, 0, sizeof *w);
        w->k = k;
        w->id = id;
        w->failed = -1;
        pthread_mutex_init(&w->mutex, NULL);
        pthread_cond_init(&w->cond, NULL);
        pthread_cond_init(&w->done_cond, NULL);
        if (pthread_create(&w->thread, NULL, worker_main, w) != 0) {
            pthread_cond_destroy(&w->done_cond);
            pthread_cond_destroy(&w->cond);
            pthread_mutex_destroy(&w->mutex);
            stop_workers(k);
            return -1;
        }
        w->started = 1;
    }
    k->generation = 0;
    for (int i = 0; i < k->n_sub; i++) k->sub[i].thread = thread_of[i];
    k->n_threads = n_threads;
    return 0;
}

int dr_thread_plan(const DRKernel *k, int *thread_of) {
    for (int i = 0; i < k->n_sub; i++) thread_of[i] = k->sub[i].thread;
    return k->n_threads;
}

static int compare_doubles(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

void dr_costs(DRKernel *k, double *us_per_eval) {
    for (int i = 0; i < k->n_sub; i++) {
        Sub *s = &k->sub[i];
        int m = s->n_samples;
        qsort(s->sample_ns, (size_t)m, sizeof(double), compare_doubles);
        us_per_eval[i] = m == 0 ? 0.0 : 1e-3 * (m % 2 ? s->sample_ns[m / 2]
                                                      : 0.5 * (s->sample_ns[m / 2 - 1] + s->sample_ns[m / 2]));
        s->n_samples = 0;
    }
}

void dr_counts(const DRKernel *k, long *counts) {
    for (int i = 0; i < k->n_sub; i++) {
        counts[3 * i] = k->sub[i].n_do_step;
        counts[3 * i + 1] = k->sub[i].n_save;
        counts[3 * i + 2] = k->sub[i].n_restore;
    }
}

void dr_destroy(DRKernel *k) {
    if (!k) return;
    stop_workers(k);
    if (k->sub) {
        for (int i = 0; i < k->n_sub; i++) {
            Sub *s = &k->sub[i];
            if (s->own_state) fmi_free_state(s->fn.freeFMUstate, s->comp, &s->own_state);
            free(s->in_vr);
            free(s->obs_vr);
        }
    }
    free(k->sub);
    free(k->P);
    free(k->J_L);
    free(k->work);
    free(k->obs);
    free(k->redo);
    free(k->bounded);
    options_free(k->opt);
    free(k);
}

/* ---- for the other routes on the same subsystem evaluation (kernel_internal.h) ---- */

size_t dr_channels(const DRKernel *k) { return k->n; }

int dr_subsystems(const DRKernel *k) { return k->n_sub; }

void dr_span(const DRKernel *k, int i, size_t *offset, size_t *m) {
    *offset = k->sub[i].offset;
    *m = k->sub[i].m;
}

void dr_begin(DRKernel *k, DRStep *io) { begin_macro_step(k, io); }

int dr_evaluate_all(DRKernel *k, const double *in, double *out, double t, double h, int how, int measure) {
    return evaluate_all(k, in, out, t, h, how, measure);
}

int dr_evaluate(DRKernel *k, int i, const double *in, double *out, double t, double h, int commit) {
    return evaluate(&k->sub[i], in, out, t, h, commit, 0);
}

void dr_set_hooks(DRKernel *k, DRHookFn before, DRHookFn after, void *ctx) {
    k->hook_before = before, k->hook_after = after, k->hook_ctx = ctx;
}

void dr_iterates(DRKernel *k, double **u0, double **uK, double **trace, int *capacity) {
    *u0 = k->u0, *uK = k->uK, *trace = k->trace, *capacity = k->trace_capacity;
}

int dr_read(DRKernel *k, int i, const fmi2ValueReference *vr, int count, double *out) {
    Sub *s = &k->sub[i];
    return fmi_get_real(s->fn.getReal, s->comp, vr, (size_t)count, out, &s->failed);
}

int dr_thaw(DRKernel *k, int i) {
    Sub *s = &k->sub[i];
    if (!s->frozen || !s->dirty) return 0;
    if (fmi_set_state(s->fn.setFMUstate, s->comp, *s->state, &s->failed)) return 1;
    s->n_restore++;
    s->dirty = 0;
    return 0;
}

int dr_advance(DRKernel *k, int i, const double *in, double *out, double t, double h) {
    k->sub[i].frozen = 1;                                   /* nothing saved, nothing to restore */
    k->sub[i].dirty = 0;
    return evaluate(&k->sub[i], in, out, t, h, 1, 0);
}

int dr_fail(DRKernel *k, DRStep *io, int i) { return report_failure(k, io, i); }

double dr_distance(const double *x, const double *y, size_t n) { return distance(x, y, n); }

double dr_now_ns(void) { return now_ns(); }

double *dr_outputs(DRKernel *k) { return k->b; }

double *dr_inputs(DRKernel *k) { return k->a_hat; }

MIRRORED(DRFunctions)
MIRRORED(DRStep)
MIRRORED(FmiFailure)
