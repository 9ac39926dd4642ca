/* FMI 3.0 co-simulation instances behind the fmi2 signatures the kernel calls (drkernel.h, DRFunctions).
 *
 * The fmi2Component each function takes is a Fmi3Shim: the fmi3 instance, the FMU's own fmi3
 * function pointers and the out-arguments of its last fmi3DoStep. The Python side
 * (wavecosim/fmi/fmi3.py, Shim) fills the struct and mirrors its layout. Statuses pass through
 * unchanged (fmi3 OK..Fatal have fmi2's values); a doStep that returns OK or Warning but asks to
 * terminate the simulation or returned early becomes fmi2Error, with the flags kept in the
 * struct for the error message. Any code written against the fmi2 contract (the DR kernel, a
 * wrapper of fmi2-signature calls) runs an FMI 3 FMU through these functions unchanged.
 */
#include "fmi3shim.h"
#include "fmi3FunctionTypes.h"
#include "abi.h"

typedef struct {
    fmi3Instance instance;
    fmi3GetFMUStateTYPE *getFMUState;
    fmi3SetFMUStateTYPE *setFMUState;
    fmi3FreeFMUStateTYPE *freeFMUState;
    fmi3SetFloat64TYPE *setFloat64;
    fmi3DoStepTYPE *doStep;
    fmi3GetFloat64TYPE *getFloat64;
    fmi3Boolean eventHandlingNeeded;   /* out-arguments of the last doStep */
    fmi3Boolean terminateSimulation;
    fmi3Boolean earlyReturn;
    fmi3Float64 lastSuccessfulTime;
} Fmi3Shim;

fmi2Status fmi3shim_getFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Fmi3Shim *s = (Fmi3Shim *)c;
    return (fmi2Status)s->getFMUState(s->instance, (fmi3FMUState *)state);
}

fmi2Status fmi3shim_setFMUstate(fmi2Component c, fmi2FMUstate state) {
    Fmi3Shim *s = (Fmi3Shim *)c;
    return (fmi2Status)s->setFMUState(s->instance, (fmi3FMUState)state);
}

fmi2Status fmi3shim_freeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Fmi3Shim *s = (Fmi3Shim *)c;
    return (fmi2Status)s->freeFMUState(s->instance, (fmi3FMUState *)state);
}

fmi2Status fmi3shim_setReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Fmi3Shim *s = (Fmi3Shim *)c;
    return (fmi2Status)s->setFloat64(s->instance, (const fmi3ValueReference *)vr, nvr, value, nvr);
}

fmi2Status fmi3shim_getReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Fmi3Shim *s = (Fmi3Shim *)c;
    return (fmi2Status)s->getFloat64(s->instance, (const fmi3ValueReference *)vr, nvr, value, nvr);
}

fmi2Status fmi3shim_doStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Fmi3Shim *s = (Fmi3Shim *)c;
    fmi3Status status = s->doStep(s->instance, t, h, noSetFMUStatePriorToCurrentPoint != fmi2False,
                                  &s->eventHandlingNeeded, &s->terminateSimulation, &s->earlyReturn,
                                  &s->lastSuccessfulTime);
    if (status <= fmi3Warning && (s->terminateSimulation || s->earlyReturn)) return fmi2Error;
    return (fmi2Status)status;
}

MIRRORED(Fmi3Shim)
