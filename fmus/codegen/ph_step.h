/* The discrete-gradient step shared by every model generated from a port-Hamiltonian spec
 * (fmus/codegen/ph.py). The generated model.c defines NX states, NU port channels, LINEAR, the
 * tables state_vr[] and effort_in[], and the functions dgrad, structure, jacobian_terms and
 * extra_outputs, then includes this file.
 *
 * Unknowns w = (x', u): the new state and the held port inputs. With z the discrete gradient of H
 * between x and x', A = J - R, B = G - P, C = (G + P)^T, D = S + N at the midpoint:
 *   x' = x + h (A z + B u),   y = C z + D u,   u = c - s y   (the layer's port closure),
 * so H(x') - H(x) = h u.y - h [z; u]^T [[R, P], [P^T, S]] [z; u]. Newton with the generated
 * Jacobian; one solve when LINEAR (quadratic H, constant structure). */
#ifndef WAVECOSIM_PH_STEP_H
#define WAVECOSIM_PH_STEP_H

#include <math.h>
#include <stdio.h>

#define NW (NX + NU)

/* Everything evaluated at one iterate w. */
typedef struct {
    double xm[NX], z[NX], y[NU], F[NW];
    double A[NX * NX], B[NX * NU], C[NU * NX], D[NU * NU];
} Stage;

/* Midpoint, discrete gradient, structure matrices, port outputs and the residual at w. */
static void stage(const double *r, const double *x, const double *w, const PortClosure *p, double h,
                  Stage *st) {
    const double *u = w + NX;
    for (int i = 0; i < NX; i++) st->xm[i] = 0.5 * (x[i] + w[i]);
    dgrad(r, x, w, st->xm, st->z);
    structure(r, st->xm, st->A, st->B, st->C, st->D);
    for (int i = 0; i < NX; i++) {
        double acc = 0.0;
        for (int k = 0; k < NX; k++) acc += st->A[i * NX + k] * st->z[k];
        for (int j = 0; j < NU; j++) acc += st->B[i * NU + j] * u[j];
        st->F[i] = w[i] - x[i] - h * acc;
    }
    for (int j = 0; j < NU; j++) {
        double acc = 0.0;
        for (int k = 0; k < NX; k++) acc += st->C[j * NX + k] * st->z[k];
        for (int l = 0; l < NU; l++) acc += st->D[j * NU + l] * u[l];
        st->y[j] = acc;
        st->F[NX + j] = u[j] - p->c[j] + p->s[j] * acc;
    }
}

/* Newton matrix dF/dw at the stage (row-major NW x NW). */
static void newton_matrix(const double *r, const double *x, const double *w, const PortClosure *p,
                          double h, const Stage *st, double *M) {
    double Hz[NX * NX], dA[NX * NX], dC[NU * NX];
    jacobian_terms(r, x, w, st->xm, st->z, Hz, dA, dC);
    for (int i = 0; i < NX; i++) {
        for (int k = 0; k < NX; k++) {
            double acc = dA[i * NX + k];
            for (int l = 0; l < NX; l++) acc += st->A[i * NX + l] * Hz[l * NX + k];
            M[i * NW + k] = (i == k ? 1.0 : 0.0) - h * acc;
        }
        for (int j = 0; j < NU; j++) M[i * NW + NX + j] = -h * st->B[i * NU + j];
    }
    for (int j = 0; j < NU; j++) {
        for (int k = 0; k < NX; k++) {
            double acc = dC[j * NX + k];
            for (int l = 0; l < NX; l++) acc += st->C[j * NX + l] * Hz[l * NX + k];
            M[(NX + j) * NW + k] = p->s[j] * acc;
        }
        for (int l = 0; l < NU; l++)
            M[(NX + j) * NW + NX + l] = (j == l ? 1.0 : 0.0) + p->s[j] * st->D[j * NU + l];
    }
}

/* Solves M d = b in place (b becomes d) by Gaussian elimination with partial pivoting;
 * returns non-zero when M is singular. */
static int solve_dense(double *M, double *b) {
    for (int c = 0; c < NW; c++) {
        int piv = c;
        for (int i = c + 1; i < NW; i++)
            if (fabs(M[i * NW + c]) > fabs(M[piv * NW + c])) piv = i;
        if (!(M[piv * NW + c] != 0.0)) return 1;
        if (piv != c) {
            for (int k = 0; k < NW; k++) {
                double t = M[c * NW + k]; M[c * NW + k] = M[piv * NW + k]; M[piv * NW + k] = t;
            }
            double t = b[c]; b[c] = b[piv]; b[piv] = t;
        }
        for (int i = c + 1; i < NW; i++) {
            double l = M[i * NW + c] / M[c * NW + c];
            for (int k = c + 1; k < NW; k++) M[i * NW + k] -= l * M[c * NW + k];
            b[i] -= l * b[c];
        }
    }
    for (int i = NW - 1; i >= 0; i--) {
        double acc = b[i];
        for (int k = i + 1; k < NW; k++) acc -= M[i * NW + k] * b[k];
        b[i] = acc / M[i * NW + i];
    }
    return 0;
}

/* Largest Newton update relative to the iterate, each block (states, inputs) with a floor of
 * 1e-3 of its largest entry so that components crossing zero do not stall convergence. */
static double update_size(const double *w, const double *dw) {
    double big[2] = {0.0, 0.0}, worst = 0.0;
    for (int k = 0; k < NW; k++) big[k >= NX] = fmax(big[k >= NX], fabs(w[k]));
    for (int k = 0; k < NW; k++)
        worst = fmax(worst, fabs(dw[k]) / (fabs(w[k]) + 1e-3 * big[k >= NX] + 1e-300));
    return worst;
}

/* Newton on F(w) = 0 from w = (x, c). Converged when the update is below 1e-14 relative, or when
 * it stops shrinking below 1e-9 (the roundoff floor of an ill-conditioned step). */
static int ph_solve(const double *r, const double *x, double *w, const PortClosure *p, double h,
                    int max_iter, Stage *st) {
    double M[NW * NW], dw[NW], last = INFINITY;
    for (int it = 1; it <= (LINEAR ? 1 : max_iter); it++) {
        stage(r, x, w, p, h, st);
        newton_matrix(r, x, w, p, h, st, M);
        for (int k = 0; k < NW; k++) dw[k] = -st->F[k];
        if (solve_dense(M, dw)) return -1;
        for (int k = 0; k < NW; k++) w[k] += dw[k];
        double size = update_size(w, dw);
        if (!isfinite(size)) return -1;
        if (LINEAR || size <= 1e-14 || (size <= 1e-9 && size >= 0.5 * last)) return it;
        last = size;
    }
    return -1;
}

int model_initialize(ModelData *m, char *msg, size_t n) {
    (void)msg; (void)n;
    extra_outputs(m->r);
    return 0;
}

double model_energy(const ModelData *m) {
    double x[NX];
    for (int i = 0; i < NX; i++) x[i] = m->r[state_vr[i]];
    return energy(m->r, x);
}

int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f, char *msg, size_t n) {
    double *r = m->r;
    double x[NX], w[NW];
    Stage st;
    for (int i = 0; i < NX; i++) w[i] = x[i] = r[state_vr[i]];
    for (int j = 0; j < NU; j++) w[NX + j] = p->c[j];
    int max_iter = m->i[VRI_newton_max_iter];
    if (ph_solve(r, x, w, p, h, max_iter, &st) < 0) {
        snprintf(msg, n, "the discrete-gradient Newton iteration did not converge in %d iterations", max_iter);
        return 1;
    }
    stage(r, x, w, p, h, &st);
    for (int i = 0; i < NX; i++) r[state_vr[i]] = w[i];
    for (int j = 0; j < NU; j++) {
        e[j] = effort_in[j] ? w[NX + j] : st.y[j];
        f[j] = effort_in[j] ? st.y[j] : w[NX + j];
    }
    extra_outputs(r);
    return 0;
}

#endif
