/* FaultySide: a damped mass, mass dv/dt = -F - damping v (implicit midpoint), and the fault of
 * config.h at step fault_step. */
#define _GNU_SOURCE
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "model.h"

enum { FAULT_NONE, FAULT_SEGFAULT, FAULT_EXIT, FAULT_HANG, FAULT_ABORT, FAULT_BLIND_HANG, FAULT_STOP_SELF,
       FAULT_OWN_HANDLERS, FAULT_THREAD_CRASH, FAULT_FORK_CRASH, FAULT_KILL_SELF, FAULT_CHDIR,
       FAULT_RESTORE_DRIFT, FAULT_RESTORE_HANG, FAULT_NAN_AT_INIT, FAULT_ERROR, FAULT_NAN, FAULT_RESTORE,
       FAULT_UNDERSCORE_EXIT, FAULT_CLOSE_FDS, FAULT_LAST = FAULT_CLOSE_FDS };

static int *volatile nowhere = NULL;      /* read at run time, so the compiler keeps the store */
static volatile int spin = 1;
static double step_size = 0.0;            /* the last doStep's h: when the restore starts drifting */

static void hang(void) {
    while (spin) {}
}

static int hang_asked(const char *where) {
    const char *what = getenv("FAULTYSIDE_HANG");
    return what && strcmp(what, where) == 0;
}

__attribute__((constructor)) static void on_load(void) {
    if (hang_asked("load")) hang();
}

static void nothing(int sig) { (void)sig; }

static void *crash_thread(void *arg) {
    (void)arg;
    *nowhere = 1;
    return NULL;
}

static void own_handlers(void) {
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = nothing;
    sigaction(SIGUSR2, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
}

void model_hook(ModelData *m, const char *call) {
    int fault = m->i[VRI_fault];
    if (strcmp(call, "fmi2Instantiate") == 0 && hang_asked("instantiate")) hang();
    if (strcmp(call, "fmi2ExitInitializationMode") == 0 && fault == FAULT_NAN_AT_INIT) m->r[VR_b] = m->r[VR_e] = NAN;
    if (strcmp(call, "fmi2SetFMUstate") != 0) return;
    if (fault == FAULT_RESTORE_HANG) hang();
    if (fault == FAULT_RESTORE_DRIFT && step_size > 0.0 && floor(m->time / step_size + 0.5) >= m->i[VRI_fault_step])
        m->r[VR_v] *= 1.0 + 1e-4;
}

int model_initialize(ModelData *m, char *msg, size_t n) {
    if (m->i[VRI_fault] < FAULT_NONE || m->i[VRI_fault] > FAULT_LAST) {
        snprintf(msg, n, "fault must be 0..%d, got %d", FAULT_LAST, m->i[VRI_fault]);
        return 1;
    }
    if (!(m->r[VR_mass] > 0.0) || !(m->r[VR_damping] >= 0.0)) {
        snprintf(msg, n, "mass must be > 0 and damping >= 0, got %g and %g", m->r[VR_mass], m->r[VR_damping]);
        return 1;
    }
    if (m->i[VRI_log_bytes] < 0 || m->i[VRI_log_bytes] > 250) {
        snprintf(msg, n, "log_bytes must be 0..250, got %d", m->i[VRI_log_bytes]);
        return 1;
    }
    return 0;
}

double model_energy(const ModelData *m) {
    return 0.5 * m->r[VR_mass] * m->r[VR_v] * m->r[VR_v];
}

/* The faults that strike in doStep that need more than a line. */
static void strike_more(int fault) {
    sigset_t all;
    pthread_t thread;
    switch (fault) {
    case FAULT_BLIND_HANG:
        sigfillset(&all);
        pthread_sigmask(SIG_BLOCK, &all, NULL);
        hang();
        break;
    case FAULT_OWN_HANDLERS: own_handlers(); hang(); break;
    case FAULT_THREAD_CRASH:
        if (pthread_create(&thread, NULL, crash_thread, NULL) == 0) pthread_join(thread, NULL);
        break;
    case FAULT_FORK_CRASH:
        if (fork() == 0) {
            sleep(600);
            _exit(0);
        }
        *nowhere = 1;
        break;
    case FAULT_CLOSE_FDS:
        for (int fd = 0; fd < 65536; fd++) close(fd);
        *nowhere = 1;
        break;
    default: break;
    }
}

/* The fault of this instance, when the step from m->time is fault_step: the ones that end, stop or
 * hang the process strike here; the step's fault is returned (FAULT_NONE at other steps). */
static int strike(const ModelData *m, double h) {
    step_size = h;
    if (floor(m->time / h + 0.5) != (double)m->i[VRI_fault_step]) return FAULT_NONE;
    switch (m->i[VRI_fault]) {
    case FAULT_SEGFAULT: *nowhere = 1; break;
    case FAULT_EXIT: exit(0);
    case FAULT_UNDERSCORE_EXIT: _exit(3);
    case FAULT_HANG: hang(); break;
    case FAULT_ABORT: abort();
    case FAULT_STOP_SELF: for (;;) raise(SIGSTOP);
    case FAULT_KILL_SELF: raise(SIGKILL); break;
    case FAULT_CHDIR: if (chdir("/") != 0) abort(); break;
    default: strike_more(m->i[VRI_fault]); break;
    }
    return m->i[VRI_fault];
}

/* The doSteps an instance has made, kept outside ModelData so that fmi2SetFMUstate does not restore
 * it: the broken restore of FAULT_RESTORE (one slot per instance, found by its ModelData's address). */
static double hidden_steps(const ModelData *m) {
    static struct { const ModelData *m; double steps; } slots[64];
    for (int k = 0; k < 64; k++) {
        if (slots[k].m == m || !slots[k].m) {
            slots[k].m = m;
            return slots[k].steps += 1.0;
        }
    }
    return 0.0;
}

/* A warning note of log_bytes characters for the layer to log after the step. */
static void note(const ModelData *m, double h, char *msg, size_t n) {
    size_t want = (size_t)m->i[VRI_log_bytes];
    if (!want || n < 2) return;
    if (want > n - 1) want = n - 1;
    int head = snprintf(msg, n, "step %.0f of FaultySide: ", floor(m->time / h + 0.5));
    size_t at = head > 0 && (size_t)head < want ? (size_t)head : want;
    memset(msg + at, '.', want - at);
    msg[want] = '\0';
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    int fault = strike(m, h);
    if (fault == FAULT_ERROR) {
        snprintf(msg, n, "the spring broke");
        return 1;
    }
    double *r = m->r;
    /* mass (v' - v)/h = -F - damping vbar with F = c + s vbar held over the step, v' = 2 vbar - v */
    double vbar = (2.0 * r[VR_mass] * r[VR_v] / h - p->c[0]) / (2.0 * r[VR_mass] / h + r[VR_damping] + p->s[0]);
    r[VR_x] += h * vbar;
    r[VR_v] = 2.0 * vbar - r[VR_v];
    if (fault == FAULT_NAN) vbar = NAN;
    if (m->i[VRI_fault] == FAULT_RESTORE && m->i[VRI_fault_step] >= 0 &&
        floor(m->time / h + 0.5) >= (double)m->i[VRI_fault_step])
        vbar *= 1.0 + 1e-3 * hidden_steps(m);             /* from fault_step on, a step depends on the calls made */
    e[0] = p->c[0] + p->s[0] * vbar;
    f[0] = -vbar;
    note(m, h, msg, n);
    return 0;
}
