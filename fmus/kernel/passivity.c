/* Condition 2 over a block of macro-steps made in one kernel call (wavecosim/observers/passivity.py,
 * Passivity.after_block), in one pass over the kernel's log: per step the energy into each port and
 * into all of them, r_i = (H_i - H_i before) - supplied_i (eq. 27) and H_total, and the running
 * figures, each with the operation order of the step-by-step Python (Passivity.after_step; builtin
 * sum() from 0, left to right), so that every number is the same to the last bit. */
#include <stddef.h>

/* Python's grow_max_pos: the running max(0, x), NaN ignored (NaN until a number arrives). */
static double grow_max_pos(double current, double x) {
    if (x != x) return current;
    x = x > 0.0 ? x : 0.0;
    return current >= x ? current : x;
}

/* Energy into port i over step s: 1/2 (|a|^2 - |b|^2) (wave) or dt e.f; `all` gathers the sums of
 * squares over every channel so far (wave). v(r) is the value of log row r at step s. */
#define V(r) log[(size_t)(r) * ld + s]

static double port_supply(const double *log, size_t ld, size_t s, int first, int last, const int *a,
                          const int *b, const int *e, const int *f, int wave, double dt, double all[2]) {
    double in = 0.0, out = 0.0;
    for (int j = first; j < last; j++) {
        if (wave) {
            in += V(a[j]) * V(a[j]);
            all[0] += V(a[j]) * V(a[j]);
        } else {
            in += V(e[j]) * V(f[j]);
        }
    }
    if (!wave) return dt * in;
    for (int j = first; j < last; j++) {
        out += V(b[j]) * V(b[j]);
        all[1] += V(b[j]) * V(b[j]);
    }
    return 0.5 * (in - out);
}

/* Steps 0 .. count - 1. The values are rows of `log`, ld doubles apart, one value per step: a_hat,
 * b, e, f (channel j: row a[j] ...; port i holds channels port[i] .. port[i + 1] - 1) and the k
 * subsystems' H_i (rows h[i]). Writes the columns r_0 .. r_{k-1}, supply, H_total of `out` (ldo
 * doubles apart). prev[k]: the H_i before the block, left at the last step's. fig[k + 4]: the running
 * max_r_i, max_supply, drift, H_max, carried on; H_final goes to fig[k + 4]. */
void passivity_block(int count, int k, const int *port, int wave, double dt, const double *log, long ld_,
                     const int *a, const int *b, const int *e, const int *f, const int *h, double *prev,
                     double *out, long ldo_, double *fig) {
    size_t ld = (size_t)ld_, ldo = (size_t)ldo_;
    for (size_t s = 0; s < (size_t)count; s++) {
        double all[2] = {0.0, 0.0}, physical = 0.0, total = 0.0;
        for (int i = 0; i < k; i++) {
            double supplied = port_supply(log, ld, s, port[i], port[i + 1], a, b, e, f, wave, dt, all);
            double H = V(h[i]), r = (H - prev[i]) - supplied;
            physical += supplied;
            total += H;
            prev[i] = H;
            out[(size_t)i * ldo + s] = r;
            fig[i] = grow_max_pos(fig[i], r);
        }
        double supply = wave ? 0.5 * (all[0] - all[1]) : physical;
        out[(size_t)k * ldo + s] = supply;
        out[(size_t)(k + 1) * ldo + s] = total;
        fig[k] = grow_max_pos(fig[k], supply);
        fig[k + 1] += supply;
        fig[k + 2] = total == total ? (total > fig[k + 2] ? total : fig[k + 2]) : total;
        fig[k + 3] = total;
    }
}
