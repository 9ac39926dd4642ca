/* The fast path of the DR master (masters/dr_fast.py drives it through kernel/drkernel.py).
 *
 * One call of dr_macro_step() runs Algorithm 1 of the paper for one macro-step, lines 3-22: save
 * x_i^n, K inner iterations (each queries every frozen port map S_i^n once), a = P b^*, and the
 * commit Phi_i(x_i^n, a_i). FMUs are called through their own fmi2 function pointers, so the
 * kernel works for any FMI 2.0 co-simulation FMU that can get and set its state.
 *
 * The arithmetic follows kernel/linalg.py and masters/dr.py operation by operation
 * (sums from 0.0, left to right; compiled with -ffp-contract=off), so the numbers are
 * bit-identical to the Python reference.
 *
 * Threads: subsystem i is evaluated by thread thread_of[i] (0 = the caller). Every thread writes
 * only its own subsystems' slices and the caller does the DR arithmetic alone, so any thread
 * plan gives the same numbers as the serial one.
 */
#ifndef WAVECOSIM_DRKERNEL_H
#define WAVECOSIM_DRKERNEL_H

#include <stddef.h>
#include "fmi2FunctionTypes.h"

#define DR_MAX_THREADS 64

/* Termination reasons (StepLog.reason in Python, kernel/drkernel.py REASONS); the kernel never gives
 * DR_CONVERGED (the iterating classical masters' reason in Python). */
enum DRReason { DR_BUDGET = 0, DR_TOLERANCE = 1, DR_DEADLINE = 2, DR_EXPLICIT = 3, DR_CONVERGED = 4,
                DR_ENERGY_GUARD = 5 };

/* The energy ledger's columns at the end of each dr_run_steps log row: I^n, L^n, the cumulative
 * traffic, s, action (DR_LEDGER_*), redo rounds (evaluation rounds of every subsystem the redo made:
 * continued inner iterations, probes and commits), the step's wall time (s), the
 * running time of one evaluation round (s) and, under a step deadline, the step's CPU time on the
 * calling thread (s; else NaN). Without the ledger: NaN, NaN, NaN, 1, 0, 0, wall time, round, NaN
 * (kernel/drkernel.py LEDGER_LOG); DR_LEDGER_COLUMNS of them. */
enum DRLedgerLog { DR_LOG_SUPPLIED, DR_LOG_LEDGER, DR_LOG_TRAFFIC, DR_LOG_SCALE, DR_LOG_ACTION, DR_LOG_ROUNDS,
                   DR_LOG_STEP_S, DR_LOG_ROUND_S, DR_LOG_CPU_S, DR_LEDGER_COLUMNS };

/* DRStep.failed_subsystem when the held signals or a subsystem stepped alone failed (signals.c). */
#define DR_FAILED_EXTRA (-2)

/* The energy ledger's actions (kernel/drkernel.py LEDGER_ACTIONS). */
enum DRLedgerAction { DR_LEDGER_KEPT = 0, DR_LEDGER_SCALED = 1, DR_LEDGER_ZERO = 2, DR_LEDGER_ITERATED = 3, DR_LEDGER_PROJECTED = 4,
       DR_LEDGER_BLENDED = 5, DR_LEDGER_ANCHORED = 6 };

/* FMU functions, as reported in DRStep.failed_function. */
enum { DR_FN_NONE = 0, DR_FN_GET_STATE, DR_FN_SET_STATE, DR_FN_SET_REAL, DR_FN_DO_STEP, DR_FN_GET_REAL };

/* The FMU functions the kernel calls, taken from the FMU's own shared library. */
typedef struct {
    fmi2GetFMUstateTYPE *getFMUstate;
    fmi2SetFMUstateTYPE *setFMUstate;
    fmi2FreeFMUstateTYPE *freeFMUstate;
    fmi2SetRealTYPE *setReal;
    fmi2DoStepTYPE *doStep;
    fmi2GetRealTYPE *getReal;
} DRFunctions;

/* One macro-step: the caller fills the inputs, the kernel the results. */
typedef struct {
    double t, dt;        /* in: t_n and the macro-step size */
    int K;               /* in: inner-iteration budget */
    double eps;          /* in: tolerance of lines 14-16; < 0 = off */
    double deadline_s;   /* in: wall-clock budget of the inner loop; <= 0 = none */
    int measure;         /* in: time every evaluation (per-subsystem cost, see dr_costs) */
    int iterations;      /* out: inner iterations done */
    int reason;          /* out: DR_BUDGET, DR_TOLERANCE, DR_DEADLINE or DR_EXPLICIT (K = 0) */
    double residual;     /* out: |u^k - u^{k-1}| of the last iteration (NaN if none) */
    int failed_subsystem; /* out: -1, or the first subsystem whose FMU call failed */
    int failed_function; /* out: DR_FN_* of that call */
    int failed_status;   /* out: the fmi2Status it returned */
    int stopped;         /* out (dr_run_steps): 1 if it stopped early, after the last step it logged */
    int ledger_on;       /* in (dr_run_steps): keep the interface energy ledger (wavecosim/masters/ledger.py) */
    double ledger;       /* in/out: L, the energy the interface supplied so far (steps accepted) */
    double traffic;      /* in/out: the interface's cumulative traffic 1/2 (|a|^2 + |b|^2) */
    double ledger_rtol;  /* in: a step with L + I^n > (rtol + the adapters' noise, dr_set_adapter) (traffic + its
                          * own) is redone with its inputs scaled */
    double step_deadline_s; /* in (dr_run_steps, ledger): wall-clock budget of a step, redo included; <= 0 = none */
    double round_s;      /* in/out (dr_run_steps, ledger): running time of one evaluation round (all subsystems) */
    double tail_s;       /* in/out (dr_run_steps, ledger): running time a step takes past its inner loop's deadline */
    double t0;           /* in (dr_run_steps): the start time; step n is at t0 + n dt */
    int at;              /* in (dr_run_steps): the block's log column of this call's first step (the block's
                          * steps before it were logged by the calls before, from column 0) */
    int passes;          /* in (dr_run_steps): the passes (dr_set_passes) over the steps as they are logged, a
                          * DRPasses */
    int passed;          /* out (dr_run_steps, passes): the block's steps, from column 0, the passes went over */
} DRStep;

/* A pass over logged steps (the runner's, wavecosim/kernel/c/blocks.c): steps first .. first + count - 1 of
 * the block that begins with macro-step n0, whose column 0 is at log (a value's steps contiguous, ld
 * doubles between values). */
typedef void DRPassFn(void *args, int n0, const double *log, long ld, int first, int count);

typedef struct DRKernel DRKernel;

/* A kernel for n_sub subsystems with n channels in all. P and J_L (n x n, dense row-major) are
 * copied as sparse rows, or NULL: then dr_set_maps gives them (sparse) before the first macro-step.
 * b (b^n, updated to b^{n+1} by each macro-step), a_hat, u0 and uK (length n) stay the caller's. */
DRKernel *dr_create(int n_sub, int n, const double *P, const double *J_L, double *b, double *a_hat,
                    double *u0, double *uK);

/* Subsystem i: its functions, instance, value references of the wave inputs and outputs (m each)
 * and the offset of its first channel in the stacked vectors. x_i^n is saved into *state (the
 * caller's handle, which the caller frees) or, if state is NULL, into a handle of the kernel's
 * own (freed by dr_destroy). Returns 0, or -1 on bad arguments. */
int dr_set_subsystem(DRKernel *k, int i, const DRFunctions *fn, fmi2Component comp, fmi2FMUstate *state,
                     const fmi2ValueReference *in_vr, const fmi2ValueReference *out_vr, int m, int offset);

/* noSetFMUStatePriorToCurrentPoint for subsystem i's doSteps (0 unless set; frozen_port_map.py,
 * Subsystem.no_prior). Returns 0, or -1 for a bad index. */
int dr_set_no_prior(DRKernel *k, int i, int no_prior);

/* New P and J_L (copied), e.g. after gamma was re-tuned between macro-steps, in compressed rows:
 * row i of P holds the columns P_col[P_start[i] .. P_start[i+1]) (ascending, for the order of the
 * sums) with values P_val, P_start[0] = 0; J_L alike. Returns 0, or -1 on malformed rows or no
 * memory (the maps in force stay). */
int dr_set_maps(DRKernel *k, const int *P_start, const int *P_col, const double *P_val, const int *J_start,
                const int *J_col, const double *J_val);

/* Record the inner loop's queries: trace[2 n k .. 2 n k + n) = u^k and the next n values S(u^k),
 * for k < capacity; trace = NULL stops recording. The buffer stays the caller's. */
void dr_set_trace(DRKernel *k, double *trace, int capacity);

/* Evaluate subsystem i on thread thread_of[i] of n_threads (0 = the caller); starts or stops the
 * persistent worker threads as needed (the same count keeps them and only moves subsystems). Returns
 * 0, or -1 on a bad plan or if a thread cannot be started (the kernel then stays serial). */
int dr_set_threads(DRKernel *k, int n_threads, const int *thread_of);

/* The plan in force: thread_of[i] for each subsystem (n_sub values); returns the number of threads. */
int dr_thread_plan(const DRKernel *k, int *thread_of);

/* Starts of the inner iteration, u^{n,0} (masters/dr_options.py STARTS): the paper's P b^n, P (2 b^n - b^{n-1}),
 * or a^{n-1}, the incident wave committed at the previous macro-step (a_hat as the caller's buffer
 * holds it when the step begins). */
enum DRStart { DR_START_PAPER = 0, DR_START_EXTRAPOLATED = 1, DR_START_PREVIOUS = 2 };

/* The DR master's named options (wavecosim/masters/dr_options.py): relaxation lambda in (0, 2) of
 * line 12, Anderson window (0: off, at most 16), the start (DR_START_*). Each call forgets b^{n-1}
 * and a^{n-1}; (1, 0, DR_START_PAPER) is the paper's Algorithm 1. Returns 0, or -1 on bad values or
 * no memory. */
int dr_set_options(DRKernel *k, double relaxation, int anderson, int start);
/* Keep the energy ledger's anchors (each query's supply, the latest with supply <= 0) in the inner
 * loop: on in a run with the ledger, whose redo (dr_ledger_redo, dr_run_steps) needs them; off (the
 * default) saves that arithmetic. */
void dr_set_anchors(DRKernel *k, int on);

/* After a macro-step was undone: a^{n-1} again (what the caller's a_hat holds when the step begins), or
 * NULL when the step undone was the first (no a^{n-1}: the start is then P b^n). */
void dr_set_previous(DRKernel *k, const double *a_prev);
/* After dr_set_options with an Anderson window: keep its differences across macro-steps (memory) and
 * commit the Anderson combination of the responses (extrapolate). Returns -1 without a window. */
int dr_set_anderson_modes(DRKernel *k, int memory, int extrapolate);

/* Algorithm 1, lines 3-22, for one macro-step. Returns 0, or -1 when an FMU call failed
 * (see io->failed_*); the instances are then left where the failure happened. */
int dr_macro_step(DRKernel *k, DRStep *io);

/* Values to read from subsystem i after each commit of dr_run_steps (value references, copied);
 * the first is its stored energy H_i. Returns 0, or -1 on bad arguments or no memory. */
int dr_set_observed(DRKernel *k, int i, const fmi2ValueReference *vrs, int count);

/* run_steps also stops after a step where an observed value of `indices` (0-based over every
 * subsystem's observed values, in order) is above `bound` in magnitude (run/bounds.py). Returns 0, or
 * -1 on bad arguments or no memory. */
int dr_set_bound(DRKernel *k, double bound, const int *indices, int count);

/* Observed values of subsystem i read by get(comp, ...) instead of its FMU's getReal (a port view:
 * portview.c); no_H: its first value is no stored energy (NaN), left out of dr_run_steps' checks.
 * Call after dr_set_observed. Returns 0, or -1 on bad arguments. */
int dr_set_observed_view(DRKernel *k, int i, fmi2GetRealTYPE *get, fmi2Component comp, int no_H);

/* Where subsystem i's wave adapter keeps the worst relative residual it accepted (read at each step:
 * the ledger's tolerance is (io->ledger_rtol + the largest of them) times the traffic) and its count
 * of the FMU's doSteps, or NULLs. Returns 0, or -1 on bad arguments. */
int dr_set_adapter(DRKernel *k, int i, const double *worst, const long *do_steps);

/* doSteps of the FMUs in the ledger's redos (dr_run_steps) so far. */
long dr_redo_do_steps(const DRKernel *k);

/* Doubles per row of dr_run_steps' log: 3 + 2 n + every subsystem's observed count + the values
 * observed by signals.c (subsystems stepped alone) + DR_LEDGER_COLUMNS. */
size_t dr_log_width(const DRKernel *k);

/* A new log (dr_run_steps' layout, room for `count` steps from rows) made ready: the ledger's rows of
 * steps without the ledger or a clock, the same for every such step, written now rather than by each
 * call that logs there. */
void dr_prepare_log(DRKernel *k, const DRStep *io, double *rows, long ld, int count);

/* Macro-steps n0 .. n0 + count - 1, each exactly dr_macro_step at t = (double)n dt, logged
 * column-major (value c of step s at rows[c ld + s], ld >= count, so each value is one contiguous
 * column; a call may go on in the columns after an earlier call's):
 * iterations, reason, residual, a (n), b^{n+1} (n), then every subsystem's observed values in
 * subsystem order, then the ledger's DR_LEDGER_COLUMNS. With io->ledger_on it keeps the interface
 * energy ledger of wavecosim/masters/ledger.py, bit for bit: a step that would lift L above
 * tol is undone and committed again with its inputs scaled (a, b and the observed values logged are
 * the redo's, its reason DR_ENERGY_GUARD); with io->step_deadline_s the inner loop stops early enough
 * for its overrun and the commit to end by the deadline (two rounds at first, then the time steps
 * took past the inner deadline, io->tail_s, plus a round) and the fitted scale is tried only when
 * two rounds are left (else s = 0), so a step ends within about one round of the deadline. A call of
 * one step is the guarded step of a step-by-step run (wavecosim/masters/dr_fast.py). It stops right
 * after a step whose observed values are not all finite or whose stored energy may exceed H_cap
 * (pass INFINITY for none; the caller decides exactly), setting io->stopped (also when that step was
 * the last of the call). Returns the number of steps done and logged; when an FMU call failed, io->failed_* name it and the step it
 * failed in (the one after those done) has no entries. */
int dr_run_steps(DRKernel *k, DRStep *io, int n0, int count, double *rows, long ld, double H_cap);

/* When dr_run_steps makes the passes (io->passes): none; over each DR_PASS_STEPS steps logged, while
 * they are in cache; after every step (a durable run's rows counted as each step is made). */
enum DRPasses { DR_PASSES_NONE, DR_PASSES_CACHED, DR_PASSES_EACH };

/* The passes dr_run_steps makes with io->passes: fns[j](args[j], ...) over each DR_PASS_STEPS steps
 * logged (each step: DR_PASSES_EACH) and over the rest when the call made all its steps (not over a
 * step it stopped after, nor one an FMU call failed in: io->passed says how far they went, from the
 * block's column 0; the caller makes them over the rest). At most DR_MAX_PASSES; n = 0: none. Returns
 * 0, or -1 for too many. */
enum { DR_MAX_PASSES = 4, DR_PASS_STEPS = 128 };
int dr_set_passes(DRKernel *k, int n, DRPassFn *const *fns, void *const *args);

/* The energy ledger's redo of the step dr_macro_step just committed (a_hat and b as it left them),
 * whose commit supplied `supplied` beyond the ledger's `budget` (wavecosim/masters/ledger.py
 * _redo), with left_s seconds to the step's deadline (INFINITY: none) and round_s per evaluation
 * round: every subsystem back at x_i^n, then the stages iterated, projected, blended, anchored, scaled, zero,
 * each when the one before did not fit. a_hat becomes the inputs committed, b the new b^{n+1};
 * out[0..4] = s, supply, traffic, action (DR_LEDGER_*), rounds. Returns 0, or -1 when an FMU call
 * failed (see io->failed_*). */
int dr_ledger_redo(DRKernel *k, DRStep *io, double supplied, double budget, double left_s, double round_s,
                   double *out);

/* Median wall time (microseconds) of one evaluation of each subsystem over the macro-steps run
 * with io->measure set (the first 16 evaluations; a dr_run_steps call with it set starts afresh),
 * then resets the measurement. */
void dr_costs(DRKernel *k, double *us_per_eval);

/* Calls made so far per subsystem: counts[3 i + 0..2] = doStep, getFMUstate, setFMUstate. */
void dr_counts(const DRKernel *k, long *counts);

/* Stops the workers, frees the kernel's own saved FMU states (call it before the instances are
 * freed) and the kernel. */
void dr_destroy(DRKernel *k);

#endif
