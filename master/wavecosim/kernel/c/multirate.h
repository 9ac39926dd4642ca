/* Multi-rate subsystems on the kernel route (multirate.c, in libdrkernel.so; wavecosim/kernel/multirate.py
 * drives it through ctypes).
 *
 * A MultiRate is an fmi2 component wrapping an FMU that makes n doSteps of h / n for each doStep of h
 * the kernel asks for, its inputs held (wavecosim/core/frozen_port_map.py Subsystem._substeps): the
 * inputs set are multiplied by scale; with stage value references (the FMU's own wave mode: m
 * efforts, m flows, m outgoing waves) each substep's are read and summed, and getReal gives, for
 * those value references, the efforts' and flows' means and the waves' sum times scale. The DR
 * kernel calls it through mr_functions' table; `mr_do_steps` counts the FMU's own doSteps.
 */
#ifndef WAVECOSIM_MULTIRATE_H
#define WAVECOSIM_MULTIRATE_H

#include "drkernel.h"

typedef struct MultiRate MultiRate;

/* Over the FMU's functions fn and instance comp: n substeps, inputs times scale, and stage_vr (3 m value
 * references, copied) with stage (the caller's 3 m + 1 doubles: the macro-step's values, then 1.0 once
 * one was made; shared with the Python route), or two NULLs for a physical port (the outputs as the
 * last substep leaves them). NULL on bad arguments or no memory. */
MultiRate *mr_create(const DRFunctions *fn, fmi2Component comp, int n, double scale, int m,
                     const fmi2ValueReference *stage_vr, double *stage);
/* The shim's functions (their component is the MultiRate). */
void mr_functions(DRFunctions *fn);
/* Where the count of the FMU's doSteps is kept (the DR kernel reads it: dr_set_adapter). */
const long *mr_do_steps(const MultiRate *p);
void mr_destroy(MultiRate *p);

#endif
