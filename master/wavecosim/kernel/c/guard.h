/* The containment of a supervised run (guard.c, libguard.so; wavecosim/kernel/guard.py binds it):
 * the functions it exports, as guard.c defines them. */
#ifndef WAVECOSIM_GUARD_H
#define WAVECOSIM_GUARD_H

struct GuardFault;

/* Arms the guard in the calling (main) thread: faults go into *fault, the rescue pipe is fd.
 * Returns 0, or -1 if a handler could not be installed. */
int guard_arm(struct GuardFault *fault, int fd);

/* Faults are the process's own again (the default actions); exit() is no longer held. */
void guard_disarm(void);

/* Asks the main thread to park if it is inside a call (it declines while it holds the GIL). */
int guard_freeze_main(void);

/* The signal that asks a thread to park, and the code addresses a fault records. */
int guard_freeze_signal(void);
int guard_frames(void);

/* Records a freeze the main thread never took (the FMU blocks, ignores or handles the freeze signal
 * itself) and wakes the rescue; 1 if this filled the record. */
int guard_claim_frozen(void);

#endif
