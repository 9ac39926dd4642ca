/* Many queries of one frozen port map S_i^n in one call (wavecosim/core/frozen_port_map.py,
 * Subsystem.raw_queries): each restores x_i^n, sets the inputs, makes one doStep and reads the
 * outputs, the same FMU calls in the same order as that many Subsystem.raw_query calls. */
#include "queries.h"
#include "abi.h"

int fq_queries(const DRFunctions *fn, fmi2Component comp, fmi2FMUstate *state, const fmi2ValueReference *in_vr,
               const fmi2ValueReference *out_vr, int m, double t, double dt, const double *inputs, int count,
               double *outputs, int dirty, int no_prior, int *failed)
{
    size_t n = (size_t)m;
    for (int q = 0; q < count; q++) {
        int status;
        if ((dirty || q > 0) && (status = fn->setFMUstate(comp, *state)) > fmi2Warning) {
            failed[0] = DR_FN_SET_STATE, failed[1] = status;
            return q;
        }
        if ((status = fn->setReal(comp, in_vr, n, inputs + (size_t)q * n)) > fmi2Warning) {
            failed[0] = DR_FN_SET_REAL, failed[1] = status;
            return q;
        }
        if ((status = fn->doStep(comp, t, dt, no_prior ? fmi2True : fmi2False)) > fmi2Warning) {
            failed[0] = DR_FN_DO_STEP, failed[1] = status;
            return q;
        }
        if ((status = fn->getReal(comp, out_vr, n, outputs + (size_t)q * n)) > fmi2Warning) {
            failed[0] = DR_FN_GET_REAL, failed[1] = status;
            return q;
        }
    }
    return count;
}

MIRRORED(DRFunctions)
