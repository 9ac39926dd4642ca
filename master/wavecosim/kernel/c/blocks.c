/* What the runner does with a block of macro-steps made in one kernel call (wavecosim/kernel/blocks.py), in
 * one pass over the kernel's log each, with the operation order of the step-by-step Python, so that
 * every number is the same to the last bit. block_rows_steps and passivity_steps are DRPassFns
 * (drkernel.h): the kernel makes them over the steps it logs, a few at a time (dr_set_passes), and the
 * runner over the rest; as they go on from the figures the steps before left, in step order, a
 * block made in parts gives the numbers of one pass over it:
 * - block_rows_steps: the rows' grid time, iterations, residual and reason, and the trajectory's rows
 *   (wavecosim/run/runner.py, LiveRun._after_block);
 * - passivity_steps: Condition 2, per step the energy into each port and into all of them,
 *   r_i = (H_i - H_i before) - supplied_i (eq. 27) and H_total, and the running figures
 *   (wavecosim/run/observers/passivity.py, Passivity.after_block; builtin sum() from 0, left to right);
 * - freeze_steps: the freeze watch, per subsystem the steps whose outputs equal the step's before while
 *   its inputs changed, and its longest such stretch (wavecosim/run/observers/freeze_watch.py,
 *   FreezeWatch.after_step);
 * - sampled_block and watch_block: the certificates' columns of the steps from the rows the
 *   certificates' kernel made (wavecosim/run/observers/certificates.py CertificateSampler and
 *   observers/fne_watch.py FneWatch, after_block). */
#include <math.h>
#include <stddef.h>

#include "abi.h"
#include "blocks.h"

/* Python's grow_max_pos: the running max(0, x), NaN ignored (NaN until a number arrives). Over the
 * steps of one pass it is applied once, to their largest number: max(0, x) is never -0, so the
 * running maximum does not depend on the order of the numbers. */
static double grow_max_pos(double current, double x) {
    if (x != x) return current;
    x = x > 0.0 ? x : 0.0;
    return current >= x ? current : x;
}

/* Energy into port i over step s: 1/2 (|a|^2 - |b|^2) (wave) or dt e.f, channel j's values at
 * x[j][s] (x: a, b, e, f); all0, all1 gather the sums of squares over every channel so far (wave). */
static double port_supply(const double *const *x[4], size_t s, int first, int last, int wave, double dt,
                          double *all0, double *all1) {
    double in = 0.0, out = 0.0;
    if (!wave) {
        for (int j = first; j < last; j++) in += x[2][j][s] * x[3][j][s];
        return dt * in;
    }
    for (int j = first; j < last; j++) {
        double v = x[0][j][s] * x[0][j][s];
        in += v;
        *all0 += v;
    }
    for (int j = first; j < last; j++) {
        double v = x[1][j][s] * x[1][j][s];
        out += v;
        *all1 += v;
    }
    return 0.5 * (in - out);
}

/* One block (blocks.py, PassBlock), made over `count` steps of it from `log` (its first step's column)
 * into `out` (the same step's row). The values are rows of `log`, ld doubles apart, one value per
 * step: a_hat, b, e, f (channel j: row a[j] ...; port i holds channels port[i] .. port[i + 1] - 1)
 * and the k subsystems' H_i (rows h[i]; NaN where has_h[i] is 0). The
 * columns go to `out` (ldo doubles apart): r_i of each subsystem with H, then the energy into the port
 * of each one without and its running sum (started from ledger[i], left at the last step's), then
 * supply, and H_total when every subsystem has H. prev[k]: the H_i before the block, left at the last
 * step's. fig[k + 4]: the running max_r_i, max_supply, drift, H_max, carried on, and H_final. */
typedef struct {
    int k, wave;
    double dt;
    double *out;                   /* the block's first step's row of the columns */
    long ldo;
    const int *port, *a, *b, *e, *f, *h;
    double *prev, *fig;
    const int *has_h;
    double *ledger;
} PassBlock;

enum { CHUNK = 128 };          /* steps per round of the subsystems: the step sums stay in L1 */

/* The sums over the subsystems of steps s0 .. s0 + m - 1, in subsystem order as Passivity.after_step. */
typedef struct {
    double physical[CHUNK], total[CHUNK], all0[CHUNK], all1[CHUNK];
} StepSums;

/* Subsystem i's columns over steps s0 .. s0 + m - 1, its terms added into the step sums; last: its
 * H before s0, left at the last step's. */
static inline void subsystem_steps_of(const PassBlock *p, const double *const *x[4], const double *H, int i,
                                      size_t s0, size_t m, double *last, double *r, double *cum, double *worst,
                                      int *seen, StepSums *sums, const int wave, const int has_h) {
    int first = p->port[i], end = p->port[i + 1];
    double dt = p->dt, before = *last, ledger = p->ledger[i], most = *worst;
    int numbers = 0;
    for (size_t j = 0; j < m; j++) {
        size_t s = s0 + j;
        double supplied = port_supply(x, s, first, end, wave, dt, &sums->all0[j], &sums->all1[j]);
        double Hi = H[s], ri = (Hi - before) - supplied;
        sums->physical[j] += supplied;
        sums->total[j] += Hi;
        before = Hi;
        if (!has_h) {                                           /* the port's own ledger */
            ledger += supplied;
            r[s] = supplied;
            cum[s] = ledger;
            continue;
        }
        r[s] = ri;
        most = ri > most ? ri : most;                           /* branch-free (maxsd), NaN skipped */
        numbers += ri == ri;
    }
    *last = before;
    *worst = most;
    *seen += numbers;
    p->ledger[i] = ledger;
}

static void subsystem_steps(const PassBlock *p, const double *const *x[4], const double *H, int i, size_t s0,
                            size_t m, double *last, double *r, double *cum, double *worst, int *seen,
                            StepSums *sums) {
    int wave = p->wave, has_h = p->has_h[i];
    if (wave && has_h) subsystem_steps_of(p, x, H, i, s0, m, last, r, cum, worst, seen, sums, 1, 1);
    else if (wave) subsystem_steps_of(p, x, H, i, s0, m, last, r, cum, worst, seen, sums, 1, 0);
    else if (has_h) subsystem_steps_of(p, x, H, i, s0, m, last, r, cum, worst, seen, sums, 0, 1);
    else subsystem_steps_of(p, x, H, i, s0, m, last, r, cum, worst, seen, sums, 0, 0);
}

static void passivity_block(const PassBlock *p, const double *log, size_t ld, double *out, int count) {
    int k = p->k, wave = p->wave;
    double *prev = p->prev, *fig = p->fig;
    const int *a = p->a, *b = p->b, *e = p->e, *f = p->f;
    int n = p->port[k];
    const double *rows[4][n > 0 ? n : 1], *H[k], *const *x[4] = {rows[0], rows[1], rows[2], rows[3]};
    double *r[k + 2], *cum[k], worst[k + 1], drift = fig[k + 1], H_max = fig[k + 2], total = fig[k + 3];
    int seen[k + 1], complete = 1, c = 0;
    for (int j = 0; j < n; j++) {
        rows[0][j] = log + (size_t)a[j] * ld;
        rows[1][j] = wave ? log + (size_t)b[j] * ld : NULL;
        rows[2][j] = wave ? NULL : log + (size_t)e[j] * ld;
        rows[3][j] = wave ? NULL : log + (size_t)f[j] * ld;
    }
    for (int i = 0; i < k; i++) H[i] = log + (size_t)p->h[i] * ld;
    for (int i = 0; i < k; i++)                                /* Passivity.columns */
        if (p->has_h[i]) r[i] = out + (size_t)c++ * (size_t)p->ldo;
    for (int i = 0; i < k; i++) {
        cum[i] = NULL;
        if (!p->has_h[i]) {
            r[i] = out + (size_t)c++ * (size_t)p->ldo;
            cum[i] = out + (size_t)c++ * (size_t)p->ldo;
            complete = 0;
        }
    }
    for (int i = 0; i <= k; i++) {
        worst[i] = -INFINITY;
        seen[i] = 0;
    }
    r[k] = out + (size_t)c * (size_t)p->ldo;
    r[k + 1] = complete ? out + (size_t)(c + 1) * (size_t)p->ldo : NULL;
    StepSums sums;
    for (size_t s0 = 0; s0 < (size_t)count; s0 += CHUNK) {
        size_t m = (size_t)count - s0 < CHUNK ? (size_t)count - s0 : CHUNK;
        for (size_t j = 0; j < m; j++) sums.physical[j] = sums.total[j] = sums.all0[j] = sums.all1[j] = 0.0;
        for (int i = 0; i < k; i++)
            subsystem_steps(p, x, H[i], i, s0, m, &prev[i], r[i], cum[i], &worst[i], &seen[i], &sums);
        for (size_t j = 0; j < m; j++) {
            size_t s = s0 + j;
            double supply = wave ? 0.5 * (sums.all0[j] - sums.all1[j]) : sums.physical[j];
            total = sums.total[j];
            r[k][s] = supply;
            if (complete) r[k + 1][s] = total;
            worst[k] = supply > worst[k] ? supply : worst[k];
            seen[k] += supply == supply;
            drift += supply;
            H_max = total == total ? (total > H_max ? total : H_max) : total;
        }
    }
    for (int i = 0; i <= k; i++)
        if (seen[i]) fig[i] = grow_max_pos(fig[i], worst[i]);
    fig[k + 1] = drift;
    fig[k + 2] = H_max;
    fig[k + 3] = total;
}

void passivity_steps(void *args, int n0, const double *log, long ld, int first, int count) {
    PassBlock *p = args;
    (void)n0;
    passivity_block(p, log + first, (size_t)ld, p->out + first, count);
}

/* One block (blocks.py, BlockRows) from macro-step n0: the grid points after its steps are (n0 + 1 + s) /
 * inverse (inverse > 0: 1/dt a whole number) or (n0 + 1 + s) dt, as runner.grid_clock. The kernel log holds
 * iterations, reason and residual at rows 0, 1, 2 and the outputs at rows outputs[j]. The steps'
 * columns time, iterations, inner_residual, reason go to `steps` (lds doubles apart), the trajectory's
 * time and outputs to `trajectory` (ldt apart), from the block's first step's row. The iterations'
 * sum and max over every step made so far are carried on (the run's). The rows counted: with
 * counted[j] not NULL (a durable run's tables, run/recorder.py), counted[j][0] is set to base[j] +
 * the block's rows written so far once the pass is over (j = 0 the steps', 1 the trajectory's), so a
 * process killed outright has told its parent how many rows its mapped blocks hold (made the last of
 * the passes, the other passes' columns of those rows are written too). */
typedef struct {
    int n_out;
    double inverse, dt;
    const int *outputs;
    double *steps;
    long lds;
    double *trajectory;
    long ldt;
    double iterations_sum, iterations_max;
    double t0;          /* the start time: grid point k is t0 + k / inverse (or t0 + k dt) */
    long *counted[2];   /* the steps' and the trajectory's rows counted, or NULL */
    long base[2];       /* their rows before the block's first step */
} BlockRows;

/* Steps first .. first + count - 1 of the block (a DRPassFn). */
void block_rows_steps(void *args, int block_n0, const double *log, long ld_, int first, int n) {
    BlockRows *p = args;
    size_t ld = (size_t)ld_, lds = (size_t)p->lds, ldt = (size_t)p->ldt, count = (size_t)n;
    log += first;
    const double *iterations = log, *reason = log + ld, *residual = log + 2 * ld;
    const double n0 = (double)block_n0 + (double)first, inverse = p->inverse, dt = p->dt,
                 t0 = p->t0;                                   /* locals: no store aliases them */
    double *steps = p->steps + first, *trajectory = p->trajectory + first, sum = p->iterations_sum,
           most = p->iterations_max;
    for (size_t s = 0; s < count; s++) {
        double k = n0 + 1.0 + (double)s, t = t0 + (inverse > 0.0 ? k / inverse : k * dt);
        steps[s] = t;
        steps[lds + s] = iterations[s];
        steps[2 * lds + s] = residual[s];
        steps[3 * lds + s] = reason[s];
        trajectory[s] = t;
        sum += iterations[s];
        most = iterations[s] > most ? iterations[s] : most;
    }
    for (int j = 0; j < p->n_out; j++) {
        const double *from = log + (size_t)p->outputs[j] * ld;
        double *to = trajectory + (size_t)(j + 1) * ldt;
        for (size_t s = 0; s < count; s++) to[s] = from[s];
    }
    p->iterations_sum = sum;
    p->iterations_max = most;
    for (int j = 0; j < 2; j++)                 /* after the rows' values: another process reads them */
        if (p->counted[j]) __atomic_store_n(p->counted[j], p->base[j] + (long)first + n, __ATOMIC_RELEASE);
}

/* One freeze watch (blocks.py, FreezeBlock). Its values are FreezeWatch's (every H_i, then every
 * channel's e, then its f), value v at log row rows[v]; subsystem i's outputs are the values
 * outs[out_at[i]] .. outs[out_at[i + 1] - 1], its inputs likewise (ins, in_at). last[v]: value v at the
 * step before, left at the last step's. Per subsystem: count, the steps of its current stretch of equal
 * outputs whose inputs changed, from step since (-1: none); found_from and found_steps, its longest
 * stretch that reached frozen_steps (-1: none), found_at the step where the first one did, first_from
 * where that one began; *found_count counts the subsystems found. */
typedef struct FreezeBlock {
    int k, frozen_steps, n_values;
    const int *rows, *out_at, *outs, *in_at, *ins;
    double *last;
    int *count, *since, *found_from, *found_steps, *found_at, *first_from, *found_count;
} FreezeBlock;

/* Whether any of the values which[from .. to - 1] differs at step s from the step before (x[v]: value
 * v's row from the pass's first step; last before it). NaN differs from everything, as in Python. */
static int changed(const double *const *x, const double *last, const int *which, int from, int to, size_t s) {
    for (int j = from; j < to; j++) {
        const double *row = x[which[j]];
        if (row[s] != (s ? row[s - 1] : last[which[j]])) return 1;
    }
    return 0;
}

/* Subsystem i's stretch reached frozen_steps at step n (count: its steps so far, since: its first step):
 * its longest stretch is this one when it is the first, goes on or is longer (FreezeWatch._count). */
static void freeze_found(const FreezeBlock *p, int i, int n, int since) {
    int steps = n + 1 - since;
    if (p->found_from[i] < 0) {
        p->found_at[i] = n;
        p->first_from[i] = since;
        ++*p->found_count;
    } else if (p->found_from[i] != since && steps <= p->found_steps[i]) {
        return;
    }
    p->found_from[i] = since;
    p->found_steps[i] = steps;
}

/* Subsystem i over steps n .. n + count - 1 (x: the values' rows from the first), step by step as
 * FreezeWatch.after_step and _count: a step whose outputs changed ends the stretch, one with the same
 * outputs starts or goes on with it, and counts when its inputs changed. */
static void freeze_subsystem(const FreezeBlock *p, const double *const *x, int i, int n, int count) {
    int since = p->since[i], stretch = p->count[i];
    const int *outs = p->outs, *ins = p->ins;
    int o0 = p->out_at[i], o1 = p->out_at[i + 1], i0 = p->in_at[i], i1 = p->in_at[i + 1];
    for (int s = 0; s < count; s++) {
        if (changed(x, p->last, outs, o0, o1, (size_t)s)) {
            stretch = 0;
            since = -1;
            continue;
        }
        if (since < 0) since = n + s;
        stretch += changed(x, p->last, ins, i0, i1, (size_t)s);
        if (stretch >= p->frozen_steps) freeze_found(p, i, n + s, since);
    }
    p->since[i] = since;
    p->count[i] = stretch;
}

/* Steps first .. first + count - 1 of the block from macro-step n0 (a DRPassFn). */
void freeze_steps(void *args, int n0, const double *log, long ld, int first, int count) {
    FreezeBlock *p = args;
    int n_values = p->n_values;
    const double *x[n_values > 0 ? n_values : 1];
    for (int v = 0; v < n_values; v++) x[v] = log + (size_t)p->rows[v] * (size_t)ld + first;
    for (int i = 0; i < p->k; i++) freeze_subsystem(p, x, i, n0 + first, count);
    for (int v = 0; v < n_values && count > 0; v++) p->last[v] = x[v][count - 1];
}

/* Whether step s of a block is sampled: s = first, first + every, ... */
static int sampled(int s, int first, int every) { return s >= first && (s - first) % every == 0; }

/* One block (blocks.py, SampledBlock) for CertificateSampler: steps 0 .. count - 1, the certificates'
 * kernel's row of step s at certs + s ldc (fne_0 .. fne_{k-1}, the Fejer term, ...). Columns to `out`
 * (ldo apart): fne_i of every step (fne), then augmented (NaN but at the sampled steps) = ((H - H
 * before) + Fejer) - 1/2 (|a_hat|^2 - |B|^2), NaN after a ledger redo (log row `rounds` > 0); the
 * kernel's log rows: a_hat (n: a), B (nb: b), H_i (k: h). min_fne[k] and max_aug[1] are folded as
 * builtin min and grow_max_pos fold, step after step; H_prev[1]: the summed H before, left at the
 * last step's. */
typedef struct SampledBlock {
    int count, k, n, nb, first, every, fne, augmented, rounds;
    const double *log;
    long ld;
    const double *certs;
    long ldc;
    double *out;
    long ldo;
    const int *a, *b, *h;
    double *min_fne, *max_aug, *H_prev;
} SampledBlock;

static double sum_squares(const double *log, size_t ld, const int *rows, int count, size_t s) {
    double acc = 0.0;
    for (int j = 0; j < count; j++) {
        double v = log[(size_t)rows[j] * ld + s];
        acc += v * v;
    }
    return acc;
}

void sampled_block(const SampledBlock *p) {
    size_t ld = (size_t)p->ld, ldo = (size_t)p->ldo;
    int k = p->k, fne = p->fne;
    double *aug = p->out + (size_t)(fne ? k : 0) * ldo, H_prev = *p->H_prev;
    for (int s = 0; s < p->count; s++) {
        const double *row = p->certs + (size_t)s * (size_t)p->ldc;
        double H = 0.0;
        for (int i = 0; i < k; i++) H += p->log[(size_t)p->h[i] * ld + (size_t)s];
        for (int j = 0; j < k && fne; j++) p->out[(size_t)j * ldo + (size_t)s] = row[j];
        if (p->augmented) aug[s] = NAN;
        if (sampled(s, p->first, p->every)) {
            for (int j = 0; j < k && fne; j++)
                if (row[j] < p->min_fne[j]) p->min_fne[j] = row[j];
            if (p->augmented) {
                double supplied = 0.5 * (sum_squares(p->log, ld, p->a, p->n, (size_t)s)
                                         - sum_squares(p->log, ld, p->b, p->nb, (size_t)s));
                double r = ((H - H_prev) + row[k]) - supplied;
                aug[s] = p->log[(size_t)p->rounds * ld + (size_t)s] > 0.0 ? NAN : r;
                *p->max_aug = grow_max_pos(*p->max_aug, aug[s]);
            }
        }
        H_prev = H;
    }
    *p->H_prev = H_prev;
}

/* One block (blocks.py, WatchBlock) for FneWatch: the certificates' kernel's rows as above, with the
 * secant margin of subsystem i at column k + 1 + i and whether it was estimated at 2 k + 1 + i (> 0),
 * at every step (every = 1) or the probed ones (first, first + every, ...). Column fne_watch (`out`):
 * the smallest estimated margin of each such step, NaN at the others; min_margin[k] folded with each
 * column's smallest; *probed += the steps with an estimate. Returns 1, writing nothing, when a margin
 * falls below -tol or one estimated is NaN or zero (the caller books those steps one by one). */
typedef struct WatchBlock {
    int count, k, first, every;
    double tol;
    const double *certs;
    long ldc;
    double *out, *min_margin;
    long probed;
} WatchBlock;

static int watch_is_plain(const WatchBlock *p) {
    int k = p->k;
    for (int s = p->first; s < p->count; s += p->every) {
        const double *row = p->certs + (size_t)s * (size_t)p->ldc;
        double worst = INFINITY;
        for (int i = 0; i < k; i++) {
            double m = row[k + 1 + i];
            if (!(row[2 * k + 1 + i] > 0.0)) continue;
            if (m != m || m == 0.0) return 0;
            worst = m < worst ? m : worst;
        }
        if (worst < -p->tol) return 0;
    }
    return 1;
}

int watch_block(WatchBlock *p) {
    int k = p->k;
    if (!watch_is_plain(p)) return 1;
    for (int s = 0; s < p->count; s++) p->out[s] = NAN;
    for (int s = p->first; s < p->count; s += p->every) {
        const double *row = p->certs + (size_t)s * (size_t)p->ldc;
        double worst = INFINITY;
        int some = 0;
        for (int i = 0; i < k; i++) {
            if (!(row[2 * k + 1 + i] > 0.0)) continue;
            double m = row[k + 1 + i];
            worst = m < worst ? m : worst;
            p->min_margin[i] = m < p->min_margin[i] ? m : p->min_margin[i];
            some = 1;
        }
        p->out[s] = some ? worst : NAN;
        p->probed += some;
    }
    return 0;
}

MIRRORED(PassBlock)
MIRRORED(BlockRows)
MIRRORED(SampledBlock)
MIRRORED(WatchBlock)
MIRRORED(FreezeBlock)
