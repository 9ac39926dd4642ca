/* Physical ports on the kernel route (portview.c, in libdrkernel.so; wavecosim/kernel/portview.py
 * drives it through ctypes).
 *
 * A SignedPort is an fmi2 component wrapping an FMU whose physical port has signs: the master's
 * input u goes to the FMU as in_scale u and the FMU's output y comes back as out_scale y
 * (wavecosim/core/ports.py DirectPort); the DR kernel calls it through sp_functions' table.
 *
 * A PortView is what the runner reads of a physical port after each commit (readings.py
 * Sampler._physical_part): one getReal of [H,] effort, flow and the recorded outputs, returned as
 * [H or NaN, e, sign f, (a wave adapter's) b = k (e - gamma f), outputs]; dr_set_observed_view
 * makes the kernel read it through pv_getReal.
 */
#ifndef WAVECOSIM_PORTVIEW_H
#define WAVECOSIM_PORTVIEW_H

#include "drkernel.h"

typedef struct SignedPort SignedPort;
typedef struct PortView PortView;

/* Over the FMU's functions fn and instance comp, m channels, the scales copied. NULL on bad arguments
 * or no memory. */
SignedPort *sp_create(const DRFunctions *fn, fmi2Component comp, int m, const double *in_scale,
                      const double *out_scale);
/* The shim's functions (their component is the SignedPort). */
void sp_functions(DRFunctions *fn);
void sp_destroy(SignedPort *p);

/* vr: [H (if has_H),] m efforts, m flows, n_out outputs (copied). gamma and k: where the wave
 * adapter keeps its impedance (read at every call: it may be retuned), or NULL without an adapter. */
PortView *pv_create(fmi2GetRealTYPE *get, fmi2Component comp, const fmi2ValueReference *vr, int has_H, int m,
                    int n_out, const double *sign, const double *gamma, const double *k);
/* Values one read gives: 1 + 2 m (+ m with an adapter) + n_out. */
size_t pv_size(const PortView *v);
/* The view's getReal (vr is ignored; nvr must be pv_size). */
fmi2Status pv_getReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]);
void pv_destroy(PortView *v);

#endif
