/* The discrete-gradient step shared by every model generated from a port-Hamiltonian spec
 * (fmus/codegen/ph.py). The generated model.c defines NX states, NU port channels, LINEAR,
 * CONST_STRUCTURE (J, R, G, P, S, N free of the states), the tables state_vr[] and effort_in[],
 * and the functions energy, dgrad, structure, jacobian_terms and extra_outputs, then includes this
 * file; its config.h defines PhStructure and, when LINEAR, the PhCache kept in ModelData.
 *
 * Unknowns w = (x', u): the new state and the held port inputs. With z the discrete gradient of H
 * between x and x', A = J - R, B = G - P, C = (G + P)^T, D = S + N at the midpoint:
 *   x' = x + h (A z + B u),   y = C z + D u,   u = c - s y   (the layer's port closure),
 * so H(x') - H(x) = h u.y - h [z; u]^T [[R, P], [P^T, S]] [z; u]. Newton with the generated
 * Jacobian; when LINEAR (quadratic H, constant structure) the step is an affine map of (x, c),
 * built once per (h, s) and kept in ModelData. */
#ifndef WAVECOSIM_PH_STEP_H
#define WAVECOSIM_PH_STEP_H

#include <math.h>
#include <stdio.h>

#define NW (NX + NU)

/* Everything evaluated at one iterate w, with the structure matrices S (PhStructure, config.h). */
typedef struct {
    double xm[NX], z[NX], y[NU], F[NW];
} Stage;

/* Midpoint, discrete gradient, port outputs and the residual at w. */
static void stage(const double *r, const double *x, const double *w, const PortClosure *p, double h,
                  const PhStructure *S, Stage *st) {
    const double *u = w + NX;
    for (int i = 0; i < NX; i++) st->xm[i] = 0.5 * (x[i] + w[i]);
    dgrad(r, x, w, st->xm, st->z);
    for (int i = 0; i < NX; i++) {
        double acc = 0.0;
        for (int k = 0; k < NX; k++) acc += S->A[i * NX + k] * st->z[k];
        for (int j = 0; j < NU; j++) acc += S->B[i * NU + j] * u[j];
        st->F[i] = w[i] - x[i] - h * acc;
    }
    for (int j = 0; j < NU; j++) {
        double acc = 0.0;
        for (int k = 0; k < NX; k++) acc += S->C[j * NX + k] * st->z[k];
        for (int l = 0; l < NU; l++) acc += S->D[j * NU + l] * u[l];
        st->y[j] = acc;
        st->F[NX + j] = u[j] - p->c[j] + p->s[j] * acc;
    }
}

/* Newton matrix dF/dw at the stage (row-major NW x NW). */
static void newton_matrix(const double *r, const double *x, const double *w, const PortClosure *p,
                          double h, const PhStructure *S, const Stage *st, double *M) {
    double Hz[NX * NX], dA[NX * NX], dC[NU * NX];
    jacobian_terms(r, x, w, st->xm, st->z, Hz, dA, dC);
    for (int i = 0; i < NX; i++) {
        for (int k = 0; k < NX; k++) {
            double acc = dA[i * NX + k];
            for (int l = 0; l < NX; l++) acc += S->A[i * NX + l] * Hz[l * NX + k];
            M[i * NW + k] = (i == k ? 1.0 : 0.0) - h * acc;
        }
        for (int j = 0; j < NU; j++) M[i * NW + NX + j] = -h * S->B[i * NU + j];
    }
    for (int j = 0; j < NU; j++) {
        for (int k = 0; k < NX; k++) {
            double acc = dC[j * NX + k];
            for (int l = 0; l < NX; l++) acc += S->C[j * NX + l] * Hz[l * NX + k];
            M[(NX + j) * NW + k] = p->s[j] * acc;
        }
        for (int l = 0; l < NU; l++)
            M[(NX + j) * NW + NX + l] = (j == l ? 1.0 : 0.0) + p->s[j] * S->D[j * NU + l];
    }
}

/* LU factorization with partial pivoting in place, the diagonal of U stored inverted;
 * returns non-zero when M is singular. */
static int lu_factor(double *M, int *piv) {
    for (int c = 0; c < NW; c++) {
        int best = c;
        for (int i = c + 1; i < NW; i++)
            if (fabs(M[i * NW + c]) > fabs(M[best * NW + c])) best = i;
        piv[c] = best;
        if (!(M[best * NW + c] != 0.0)) return 1;
        for (int k = 0; best != c && k < NW; k++) {
            double t = M[c * NW + k]; M[c * NW + k] = M[best * NW + k]; M[best * NW + k] = t;
        }
        double inv = 1.0 / M[c * NW + c];
        M[c * NW + c] = inv;
        for (int i = c + 1; i < NW; i++) {
            double l = M[i * NW + c] *= inv;
            for (int k = c + 1; k < NW; k++) M[i * NW + k] -= l * M[c * NW + k];
        }
    }
    return 0;
}

/* Solves M d = b with the factors of lu_factor; b becomes d. */
static void lu_solve(const double *M, const int *piv, double *b) {
    for (int c = 0; c < NW; c++) {
        double t = b[c]; b[c] = b[piv[c]]; b[piv[c]] = t;
    }
    for (int c = 0; c < NW; c++)
        for (int i = c + 1; i < NW; i++) b[i] -= M[i * NW + c] * b[c];
    for (int i = NW - 1; i >= 0; i--) {
        double acc = b[i];
        for (int k = i + 1; k < NW; k++) acc -= M[i * NW + k] * b[k];
        b[i] = acc * M[i * NW + i];
    }
}

#if LINEAR
#define NV (NX + NU + 1)

/* One solve of the affine step for state x and closure offsets c; writes (x', u) to w, y to y. */
static void affine_solve(const double *r, const double *x, const double *c, const double *s, double h,
                         const PhStructure *S, const double *lu, const int *piv, double *w, double *y) {
    PortClosure q;
    Stage st;
    for (int j = 0; j < NU; j++) { q.c[j] = c[j]; q.s[j] = s[j]; }
    for (int i = 0; i < NX; i++) w[i] = x[i];
    for (int j = 0; j < NU; j++) w[NX + j] = c[j];
    stage(r, x, w, &q, h, S, &st);
    double dw[NW];
    for (int k = 0; k < NW; k++) dw[k] = -st.F[k];
    lu_solve(lu, piv, dw);
    for (int k = 0; k < NW; k++) w[k] += dw[k];
    stage(r, x, w, &q, h, S, &st);
    for (int j = 0; j < NU; j++) y[j] = st.y[j];
}

/* The linear step is an affine map (x, c) -> (x', u, y) fixed by h and s: its columns T[.][k]
 * (k < NX + NU: response to a unit x or c, k = NX + NU: the constant) are found by NV solves. */
static int affine_map(ModelData *m, const PortClosure *p, double h) {
    PhCache *cache = &m->ph;
    PhStructure S;
    Stage st;
    double M[NW * NW], v[NX + NU], out[NW + NU], zero[NX + NU] = {0.0};
    int piv[NW];
    structure(m->r, zero, S.A, S.B, S.C, S.D);
    stage(m->r, zero, zero, p, h, &S, &st);
    newton_matrix(m->r, zero, zero, p, h, &S, &st, M);
    if (lu_factor(M, piv)) return -1;
    affine_solve(m->r, zero, zero + NX, p->s, h, &S, M, piv, out, out + NW);
    for (int i = 0; i < NW + NU; i++) cache->T[i * NV + NX + NU] = out[i];
    for (int k = 0; k < NX + NU; k++) {
        for (int l = 0; l < NX + NU; l++) v[l] = (l == k) ? 1.0 : 0.0;
        affine_solve(m->r, v, v + NX, p->s, h, &S, M, piv, out, out + NW);
        for (int i = 0; i < NW + NU; i++) cache->T[i * NV + k] = out[i] - cache->T[i * NV + NX + NU];
    }
    cache->h = h;
    for (int j = 0; j < NU; j++) cache->s[j] = p->s[j];
    return 0;
}

/* One row of the affine map at (x, c). */
static double affine_row(const double *T, const double *x, const double *c) {
    double acc = T[NX + NU];
    for (int k = 0; k < NX; k++) acc += T[k] * x[k];
    for (int j = 0; j < NU; j++) acc += T[NX + j] * c[j];
    return acc;
}

/* Linear step: the affine map, rebuilt when h or s changed (kept in ModelData). */
static int ph_solve(ModelData *m, const double *x, double *w, const PortClosure *p, double h, double *y) {
    PhCache *cache = &m->ph;
    int fresh = cache->h == h;
    for (int j = 0; j < NU; j++) fresh = fresh && cache->s[j] == p->s[j];
    if (!fresh && affine_map(m, p, h)) return -1;
    for (int i = 0; i < NW; i++) w[i] = affine_row(cache->T + i * NV, x, p->c);
    for (int j = 0; j < NU; j++) y[j] = affine_row(cache->T + (NW + j) * NV, x, p->c);
    return 1;
}
#else
/* Structure at the midpoint of w (unless it is constant and already in S), then the stage. */
static void stage_at(const double *r, const double *x, const double *w, const PortClosure *p, double h,
                     PhStructure *S, Stage *st) {
    if (!CONST_STRUCTURE) {
        double xm[NX];
        for (int i = 0; i < NX; i++) xm[i] = 0.5 * (x[i] + w[i]);
        structure(r, xm, S->A, S->B, S->C, S->D);
    }
    stage(r, x, w, p, h, S, st);
}

/* The larger of a and b (fmax is a libm call). */
static double max2(double a, double b) {
    return a > b ? a : b;
}

/* Largest Newton update relative to the largest magnitude in its block: states (old and new),
 * inputs (with the closure terms c and s y they balance). */
static double update_size(const double *x, const double *w, const double *dw, const PortClosure *p,
                          const Stage *st) {
    double big[2] = {0.0, 0.0}, step[2] = {0.0, 0.0};
    for (int i = 0; i < NX; i++) {
        big[0] = max2(big[0], max2(fabs(x[i]), fabs(w[i])));
        step[0] = max2(step[0], fabs(dw[i]));
    }
    for (int j = 0; j < NU; j++) {
        big[1] = max2(big[1], fabs(w[NX + j]) + fabs(p->c[j]) + fabs(p->s[j] * st->y[j]));
        step[1] = max2(step[1], fabs(dw[NX + j]));
    }
    return max2(step[0] / (big[0] + 1e-300), step[1] / (big[1] + 1e-300));
}

/* Newton converged after an update of relative size `size` following one of size `last`: the
 * update is at roundoff, or (from the second update on) the contraction theta = size / last
 * predicts a remaining error theta / (1 - theta) * size at roundoff, or the updates stopped
 * shrinking below 1e-10 (the roundoff floor of a difference quotient or an ill-conditioned step). */
static int converged(double size, double last) {
    double theta = size / last;
    if (size <= 1e-14) return 1;
    if (!isfinite(last)) return 0;
    return (theta < 0.5 && theta / (1.0 - theta) * size <= 1e-15) || (size <= 1e-10 && theta >= 0.5);
}

/* Newton on F(w) = 0 from w = (x, c), keeping the factored matrix of the first iterate while
 * each update shrinks at least fourfold; returns the iterations used, or -1. */
static int ph_solve(ModelData *m, const double *x, double *w, const PortClosure *p, double h, double *y) {
    double M[NW * NW], dw[NW], last = INFINITY;
    int piv[NW], slow = 0;
    PhStructure S;
    Stage st;
    if (CONST_STRUCTURE) structure(m->r, x, S.A, S.B, S.C, S.D);
    for (int it = 1; it <= m->i[VRI_newton_max_iter]; it++) {
        stage_at(m->r, x, w, p, h, &S, &st);
        if (it == 1 || slow) {
            newton_matrix(m->r, x, w, p, h, &S, &st, M);
            if (lu_factor(M, piv)) return -1;
        }
        for (int k = 0; k < NW; k++) dw[k] = -st.F[k];
        lu_solve(M, piv, dw);
        for (int k = 0; k < NW; k++) w[k] += dw[k];
        double size = update_size(x, w, dw, p, &st);
        if (!isfinite(size)) return -1;
        if (converged(size, last)) {
            stage_at(m->r, x, w, p, h, &S, &st);
            for (int j = 0; j < NU; j++) y[j] = st.y[j];
            return it;
        }
        slow = size > 0.25 * last;
        last = size;
    }
    return -1;
}
#endif

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
    double x[NX], w[NW], y[NU] = {0.0};
    for (int i = 0; i < NX; i++) w[i] = x[i] = r[state_vr[i]];
    for (int j = 0; j < NU; j++) w[NX + j] = p->c[j];
    if (ph_solve(m, x, w, p, h, y) < 0) {
        snprintf(msg, n, "the discrete-gradient step failed: %s (newton_max_iter = %d)",
                 LINEAR ? "singular step matrix" : "Newton did not converge", m->i[VRI_newton_max_iter]);
        return 1;
    }
    for (int i = 0; i < NX; i++) r[state_vr[i]] = w[i];
    for (int j = 0; j < NU; j++) {
        e[j] = effort_in[j] ? w[NX + j] : y[j];
        f[j] = effort_in[j] ? y[j] : w[NX + j];
    }
    extra_outputs(r);
    return 0;
}

#endif
