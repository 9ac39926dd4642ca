/* Containment of a supervised run (wavecosim/run/containment.py): what the process does when an FMU
 * crashes it (SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT), ends it with exit(), or is asked to stop a
 * call that does not return (the freeze signal, sent by the step-timeout watchdog or the parent).
 *
 * The thread that faults records what happened in the caller's GuardFault (the signal or exit
 * status and the code addresses of its stack), writes one byte to the rescue pipe and is parked for
 * good, every signal blocked. An FMU call runs without the GIL, so the interpreter's other threads
 * go on: a rescue thread writes the rows computed so far and the summary, then ends the process.
 * A thread that holds the GIL when it faults could never let the rescue run: it records the fault
 * and dies of it (the parent then writes what the record says). Only stores and write(2) happen in
 * the handlers; backtrace(3) is called once when arming, so it has loaded what it needs. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <execinfo.h>
#include <pthread.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/syscall.h>
#include <ucontext.h>
#include <unistd.h>

#include "abi.h"
#include "fmicall.h"
#include "guard.h"

#define GUARD_FRAMES 48
#define FREEZE_SIGNAL SIGUSR2

enum { FAULT_NONE, FAULT_SIGNAL, FAULT_EXIT, FAULT_FROZEN };

typedef struct GuardFault {
    int kind;                  /* FAULT_* */
    int signal;                /* the signal (FAULT_SIGNAL, FAULT_FROZEN) */
    int code;                  /* si_code, or the status given to exit(); -1: a freeze the watchdog took */
    int thread;                /* the faulting thread's id */
    int main_thread;           /* 1 if that is the thread that armed the guard */
    int rescuable;             /* 1 if the thread parked (the GIL is free for the rescue) */
    int frames;                /* entries of pc */
    int declined;              /* freeze requests that found the main thread holding the GIL */
    void *address;             /* si_addr: the memory address of a SIGSEGV or SIGBUS */
    void *pc[GUARD_FRAMES];    /* pc[0]: the interrupted instruction; then return addresses */
} GuardFault;

/* The page a supervised run's parent and child share (wavecosim/run/channel.py): the child's state
 * and exit code, what the parent or the watchdog asks, the watchdog's heartbeat, the FMU call in
 * progress and the subsystem whose FMU the set-up opens (named when a stuck process gives no stack),
 * and the fault. */
typedef struct {
    unsigned magic;
    int state, exit_code, request, pid, spare;
    double heartbeat;
    FmiCallNow call;
    char opening[64];
    GuardFault fault;
} RunStatus;

MIRRORED(GuardFault)
MIRRORED(FmiCallNow)
MIRRORED(RunStatus)

static GuardFault *volatile record = NULL;
static volatile int armed = 0, claimed = 0, notify_fd = -1;
static volatile pid_t main_tid = 0;
static int (*gil_held)(void) = NULL;
static int exit_handler_added = 0;
static const int fatal[] = {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT};

static pid_t thread_id(void) { return (pid_t)syscall(SYS_gettid); }

static void park(void) {
    sigset_t all;
    sigfillset(&all);
    pthread_sigmask(SIG_SETMASK, &all, NULL);
    for (;;) pause();
}

/* The interrupted instruction of a signal's context (0 where this platform is not known). */
static void *interrupted_pc(void *context) {
#if defined(__x86_64__)
    return context ? (void *)((ucontext_t *)context)->uc_mcontext.gregs[REG_RIP] : NULL;
#elif defined(__aarch64__)
    return context ? (void *)((ucontext_t *)context)->uc_mcontext.pc : NULL;
#else
    (void)context;
    return NULL;
#endif
}

/* Fills the record once (the first fault wins); returns 1 for the thread that filled it. */
static int claim(int kind, int sig, int code, void *address, void *context) {
    if (!record || __sync_lock_test_and_set(&claimed, 1)) return 0;
    GuardFault *f = record;
    f->signal = sig;
    f->code = code;
    f->thread = thread_id();
    f->main_thread = f->thread == main_tid;
    f->address = address;
    void *frames[GUARD_FRAMES], *pc0 = interrupted_pc(context);
    int n = backtrace(frames, GUARD_FRAMES), from = 0, out = 0;
    for (int j = 0; pc0 && j < n; j++)   /* the handler's own frames end where the fault is */
        if (frames[j] == pc0) {
            from = j + 1;
            break;
        }
    if (pc0) f->pc[out++] = pc0;
    for (int j = from; j < n && out < GUARD_FRAMES; j++) f->pc[out++] = frames[j];
    f->frames = out;
    f->rescuable = !(gil_held && gil_held());
    __sync_synchronize();
    f->kind = kind;                     /* last: a reader that sees the kind sees the rest */
    return 1;
}

/* 1 if the rescue was woken; 0 when the pipe is gone (an FMU closed every descriptor): the thread then
 * goes on to die, and the parent writes what the record says. */
static int wake_rescue(void) {
    return notify_fd >= 0 && write(notify_fd, "!", 1) == 1;
}

static void on_fatal(int sig, siginfo_t *info, void *context) {
    if (armed && claim(FAULT_SIGNAL, sig, info ? info->si_code : 0, info ? info->si_addr : NULL, context)) {
        if (wake_rescue() && record->rescuable) park();
    } else if (armed && claimed && !(gil_held && gil_held())) {
        park();                          /* a second fault while the first is rescued */
    }
    signal(sig, SIG_DFL);                /* die of it: the instruction faults again, or raise */
    if (sig == SIGABRT || (info && info->si_code <= 0)) raise(sig);
}

static void on_freeze(int sig, siginfo_t *info, void *context) {
    (void)info;
    if (!armed) return;
    if (thread_id() != main_tid) {       /* a process-directed signal: the main thread is meant */
        syscall(SYS_tgkill, getpid(), main_tid, sig);
        return;
    }
    if (gil_held && gil_held()) {        /* running Python, not stuck in a call: the watchdog decides */
        if (record) record->declined++;
        return;
    }
    if (claim(FAULT_FROZEN, sig, 0, NULL, context)) {
        wake_rescue();
        park();
    }
}

static void on_exit_call(int status, void *arg) {
    (void)arg;
    if (!armed) return;
    if (claim(FAULT_EXIT, 0, status, NULL, NULL)) {
        if (wake_rescue() && record->rescuable) park();
    } else if (claimed) {
        park();
    }
}

#if !defined(__GLIBC__)
static void on_exit_without_status(void) { on_exit_call(-1, NULL); }
#endif

/* Arms the guard in the calling (main) thread: faults go into *fault, the rescue pipe is fd.
 * Returns 0, or -1 if a handler could not be installed. */
int guard_arm(GuardFault *fault, int fd) {
    void *warm[2];
    backtrace(warm, 2);                  /* loads the unwinder now, not inside a handler */
    gil_held = (int (*)(void))dlsym(RTLD_DEFAULT, "PyGILState_Check");
    memset(fault, 0, sizeof *fault);
    record = fault;
    notify_fd = fd;
    main_tid = thread_id();
    claimed = 0;
    static char stack[1 << 16];          /* handlers run here when a thread overflowed its stack */
    stack_t alt = {.ss_sp = stack, .ss_size = sizeof stack, .ss_flags = 0};
    sigaltstack(&alt, NULL);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_flags = SA_SIGINFO | SA_ONSTACK;
    sigemptyset(&sa.sa_mask);
    sa.sa_sigaction = on_fatal;
    for (size_t k = 0; k < sizeof fatal / sizeof fatal[0]; k++)
        if (sigaction(fatal[k], &sa, NULL)) return -1;
    sa.sa_sigaction = on_freeze;
    sa.sa_flags = SA_SIGINFO | SA_RESTART;
    if (sigaction(FREEZE_SIGNAL, &sa, NULL)) return -1;
    if (!exit_handler_added) {
#if defined(__GLIBC__)
        if (on_exit(on_exit_call, NULL)) return -1;   /* glibc passes the exit status */
#else
        if (atexit(on_exit_without_status)) return -1;
#endif
        exit_handler_added = 1;
    }
    armed = 1;
    return 0;
}

/* Faults are the process's own again (the default actions); exit() is no longer held. */
void guard_disarm(void) {
    armed = 0;
    for (size_t k = 0; k < sizeof fatal / sizeof fatal[0]; k++) signal(fatal[k], SIG_DFL);
    signal(FREEZE_SIGNAL, SIG_IGN);
}

/* Asks the main thread to park if it is inside a call (it declines while it holds the GIL). */
int guard_freeze_main(void) {
    return main_tid ? (int)syscall(SYS_tgkill, getpid(), main_tid, FREEZE_SIGNAL) : -1;
}

int guard_freeze_signal(void) { return FREEZE_SIGNAL; }

/* Records a freeze the main thread never took (the FMU blocks, ignores or handles the freeze signal
 * itself) and wakes the rescue, which then runs while the main thread stays inside its call.
 * Returns 1 if this filled the record. */
int guard_claim_frozen(void) {
    if (!armed || !claim(FAULT_FROZEN, FREEZE_SIGNAL, -1, NULL, NULL)) return 0;
    record->frames = 0;                  /* the stack recorded is the caller's, not the main thread's */
    record->main_thread = 1;
    record->rescuable = 1;
    wake_rescue();
    return 1;
}

int guard_frames(void) { return GUARD_FRAMES; }
