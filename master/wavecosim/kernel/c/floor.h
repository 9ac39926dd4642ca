/* The bench's floor of a run (floor.c, the kernel library libfloor.so; wavecosim/kernel/floor.py
 * drives it for bench/):
 * record every FMU call the kernel makes, in order, through shims with the fmi2 signatures, then
 * make the same calls with the same arguments from C alone on freshly instantiated FMUs and time
 * them. What a run costs beyond that replay is the master's, the observers' and the recorder's.
 *
 * fl_register(r, comp, fn) names an FMU instance and its own functions; the shims (fl_shims) look
 * the instance up by its component, record the call in the recorder started by fl_start, and make
 * it. State handles are recorded as slots (one per handle the FMU filled), so the replay saves and
 * restores its own. */
#ifndef WAVECOSIM_FLOOR_H
#define WAVECOSIM_FLOOR_H

#include <stddef.h>
#include "drkernel.h"

#define FL_MAX_FMUS 64
#define FL_MAX_SLOTS 256
#define FL_MAX_VALUES 4096

/* An FMU's functions: the table the DR kernel calls. */
typedef DRFunctions FLFunctions;

typedef struct FLRecorder FLRecorder;

FLRecorder *fl_create(void);
/* The FMU instance comp with its own functions; its index (the order of registration), or -1. */
int fl_register(FLRecorder *r, fmi2Component comp, const FLFunctions *fn);
/* The recording shims. */
void fl_shims(FLFunctions *fn);
/* Record into r from now on (one recorder at a time), or stop. */
void fl_start(FLRecorder *r);
void fl_stop(void);
/* Calls recorded, or 0 when the recording is spoilt (no memory, an unknown state handle). */
size_t fl_calls(const FLRecorder *r);
/* Make the recorded calls on comps[i] through fns[i] (FMU i as registered); seconds taken, or -1
 * for a spoilt recording; *failed: the call that failed (then the replay stopped), or -1. */
double fl_replay(const FLRecorder *r, const fmi2Component *comps, const FLFunctions *fns, int *failed);
void fl_destroy(FLRecorder *r);

#endif
