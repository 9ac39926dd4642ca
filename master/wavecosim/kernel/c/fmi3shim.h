/* FMI 3.0 co-simulation instances behind the fmi2 signatures the kernel calls (fmi3shim.c,
 * libfmi3shim.so): the fmi2Component each takes is a Fmi3Shim (wavecosim/fmi/fmi3.py, Shim). The
 * Python side passes their addresses, as an FMU's own functions, to the kernel. */
#ifndef WAVECOSIM_FMI3SHIM_H
#define WAVECOSIM_FMI3SHIM_H

#include "fmi2FunctionTypes.h"

fmi2Status fmi3shim_getFMUstate(fmi2Component c, fmi2FMUstate *state);
fmi2Status fmi3shim_setFMUstate(fmi2Component c, fmi2FMUstate state);
fmi2Status fmi3shim_freeFMUstate(fmi2Component c, fmi2FMUstate *state);
fmi2Status fmi3shim_setReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]);
fmi2Status fmi3shim_getReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]);
fmi2Status fmi3shim_doStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint);

#endif
