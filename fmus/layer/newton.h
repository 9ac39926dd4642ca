/* Safeguarded scalar Newton for the monotone residuals of discrete-gradient steps. */
#ifndef WAVECOSIM_NEWTON_H
#define WAVECOSIM_NEWTON_H

#include <math.h>

/* Residual g(x) and its derivative; returns g and writes g' to *dg. */
typedef double (*ScalarResidual)(double x, void *ctx, double *dg);

/* Solves g(x) = 0 for an increasing g, starting at x. Converged when the last Newton step is
 * below rtol * (scale + |x|) + atol, which with quadratic convergence leaves an error at
 * roundoff. Steps that leave the sign bracket seen so far are replaced by bisection.
 * Returns the number of iterations used, or -1 when max_iter is reached or a value is not finite. */
static int newton_increasing(ScalarResidual g, void *ctx, double *x, double scale,
                             double rtol, double atol, int max_iter) {
    double lo = -INFINITY, hi = INFINITY;
    double xk = *x;
    for (int k = 1; k <= max_iter; k++) {
        double dg;
        double gk = g(xk, ctx, &dg);
        if (!isfinite(gk) || !isfinite(dg)) return -1;
        if (gk == 0.0) { *x = xk; return k; }
        if (gk < 0.0) lo = xk; else hi = xk;
        double next = (dg > 0.0) ? xk - gk / dg : NAN;
        /* Closed bracket: xk is one of its ends, and near the root the Newton step rounds to
         * next == xk; bisecting there would throw the converged iterate away. */
        if (!(next >= lo && next <= hi)) {
            if (!isfinite(lo) || !isfinite(hi)) {
                next = xk - gk / (dg > 0.0 ? dg : 1.0);
            } else {
                next = 0.5 * (lo + hi);
            }
        }
        double step = next - xk;
        xk = next;
        if (!isfinite(xk)) return -1;
        if (fabs(step) <= rtol * (scale + fabs(xk)) + atol) { *x = xk; return k; }
    }
    return -1;
}

#endif
