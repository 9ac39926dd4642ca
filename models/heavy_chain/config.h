/* The heavy subsystem of the parallel-speedup benchmark: n masses in a line joined by hardening
 * springs, the last one tied to a wall by the same spring, viscous damping c on every mass.
 *   [port] - m_0 - spring - m_1 - ... - m_{n-1} - spring - wall,  V(d) = k d^2/2 + kn d^4/4.
 * Port at the first mass, as in LinearSide: effort in F (the force the mass applies to its
 * neighbour; the force on it is -F), flow out f = -vbar_0. Pair it with DuffingSide or
 * SpringDamper (flow in, effort out).
 * The internal DOFs live in MODEL_EXTRA_FIELDS (so save/restore stays a byte copy); only q_first,
 * q_last and H are exposed. Initial state: a Gaussian bump of height `amplitude` and width n/20
 * in the middle of the chain, at rest.
 * Cost knob: each step runs at least `newton_sweeps` full Newton iterations (residual, tridiagonal
 * Jacobian, Thomas solve). Sweeps after convergence only move the solution by roundoff, so the
 * physics does not depend on the knob but the cost per doStep grows linearly with it. */
#define MODEL_IDENTIFIER HeavyChain
#define MODEL_GUID "{4c1d9130-cd8a-43c1-a552-ce15680ff900}"
#define MODEL_DESCRIPTION "Chain of n masses with hardening springs, port at the first mass; discrete-gradient step with full Newton"

#define HEAVY_CHAIN_MAX_N 1000
#define MODEL_EXTRA_FIELDS double q[HEAVY_CHAIN_MAX_N]; double v[HEAVY_CHAIN_MAX_N];

#define REAL_VARIABLES(X) \
    X(m, PARAMETER, 1.0, "kg", "mass of each body") \
    X(k, PARAMETER, 1000.0, "N/m", "linear stiffness of each spring") \
    X(kn, PARAMETER, 400000.0, "N/m3", "hardening coefficient of each spring (kn d^4/4)") \
    X(c, PARAMETER, 0.0, "N.s/m", "viscous damping of each mass to ground") \
    X(amplitude, PARAMETER, 0.5, "m", "height of the initial Gaussian displacement bump") \
    X(gamma, TUNABLE, 1.0, "N.s/m", "scattering impedance of the wave port") \
    X(newton_rtol, PARAMETER, 1e-12, "", "relative tolerance of the Newton step") \
    X(a, INPUT, 0.0, "sqrt(J)", "incident wave (wave mode), scaled by sqrt(dt)") \
    X(F, INPUT, 0.0, "N", "port effort input: force the first mass applies (physical mode)") \
    X(b, OUTPUT, 0.0, "sqrt(J)", "outgoing wave, scaled by sqrt(dt)") \
    X(e, OUTPUT, 0.0, "N", "port effort held over the step") \
    X(f, OUTPUT, 0.0, "m/s", "port flow: -v of the first mass at the stage") \
    X(q_first, OUTPUT, 0.0, "m", "displacement of the first mass") \
    X(q_last, OUTPUT, 0.0, "m", "displacement of the last mass") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave port (input a, output b), 1 = physical port (input F)") \
    X(newton_max_iter, 50, "iteration limit of the Newton step (beyond newton_sweeps)") \
    X(n, 200, "number of masses, 1..1000 (another value fails initialization)") \
    X(newton_sweeps, 100, "minimum Newton iterations per step: the cost knob of the benchmark")

#define PORT_CHANNELS(X) X(a, b, e, f, F, EFFORT_INPUT)
