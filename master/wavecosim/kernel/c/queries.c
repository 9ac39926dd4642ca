/* Many queries of one frozen port map S_i^n in one call (wavecosim/core/frozen_port_map.py,
 * Subsystem.raw_queries): each restores x_i^n, sets the inputs, makes one doStep and reads the
 * outputs, the same FMU calls in the same order as that many Subsystem.raw_query calls. */
#include "queries.h"
#include "abi.h"

int fq_queries(const DRFunctions *fn, fmi2Component comp, fmi2FMUstate *state, const fmi2ValueReference *in_vr,
               const fmi2ValueReference *out_vr, int m, double t, double dt, const double *inputs, int count,
               double *outputs, int *dirty, int no_prior, FmiFailure *failed)
{
    size_t n = (size_t)m;
    for (int q = 0; q < count; q++) {
        if (*dirty && fmi_set_state(fn->setFMUstate, fn->calls, comp, *state, failed)) return q;
        *dirty = 1;
        if (fmi_set_real(fn->setReal, fn->calls, comp, in_vr, n, inputs + (size_t)q * n, failed)) return q;
        if (fmi_do_step(fn->doStep, fn->calls, comp, t, dt, no_prior, failed)) return q;
        if (fmi_get_real(fn->getReal, fn->calls, comp, out_vr, n, outputs + (size_t)q * n, failed)) return q;
    }
    return count;
}

MIRRORED(DRFunctions)
MIRRORED(FmiFailure)
