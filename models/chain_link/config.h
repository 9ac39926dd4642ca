/* One link of a mass chain: mass i and the spring-damper to its right neighbour, so that N links
 * make an N-mass chain with N FMUs and N - 1 two-port couplings (no separate spring FMUs).
 *   [free] left| m_0 ~k~ |right -- left| m_1 ~k~ |right -- ... -- left| m_{N-1} ~k~ |right [wall]
 * Left channel, as Oscillator's: effort in F_left (tension of the previous link's spring, pulling
 * the mass towards -x), flow out f_left = -vbar. Right channel, as DuffingSide's: flow in u_right
 * (velocity of the next mass), effort out e_right = the spring tension T = k d + c (u - v).
 * Both make e f the power into the link, so Link_i.right - Link_{i+1}.left joined by
 * equal_effort_opposite_flow is lossless: T = F_left of the next mass, u_right = its velocity.
 * Ends: first left channel free_end (F = 0); last right channel clamped_end (u = 0: the spring is
 * tied to a wall) or, with k = c = 0, either end type (nothing is attached).
 *   m dv/dt = -k0 q - c0 v - F_left + T,   dd/dt = u_right - v,   H = m v^2/2 + k0 q^2/2 + k d^2/2.
 * Incremental impedance at step h, e = (F_left, T) vs f = (-vbar, u): Z_d = [[M + kap, kap],
 * [kap, kap]] with M = 2m/h + k0 h/2 + c0, kap = k h/2 + c; symmetric, lambda_min ~ kap, so a
 * gamma at most k h/2 + c keeps the frozen port map firmly nonexpansive (paper Remark 3). */
#define MODEL_IDENTIFIER ChainLink
#define MODEL_GUID "{a07a2f23-9655-43f9-bdf6-f390a988f45a}"
#define MODEL_DESCRIPTION "Chain link: a mass with the spring-damper to its right neighbour; implicit midpoint step"

#define REAL_VARIABLES(X) \
    X(m, PARAMETER, 1.0, "kg", "mass") \
    X(k, PARAMETER, 100.0, "N/m", "spring to the right neighbour") \
    X(c, PARAMETER, 0.0, "N.s/m", "damper in parallel with that spring") \
    X(k0, PARAMETER, 0.0, "N/m", "spring to ground") \
    X(c0, PARAMETER, 0.0, "N.s/m", "damper to ground") \
    X(gamma, TUNABLE, 0.4, "N.s/m", "scattering impedance of both wave channels") \
    X(q, STATE, 0.0, "m", "position of the mass") \
    X(v, STATE, 0.0, "m/s", "velocity of the mass") \
    X(d, STATE, 0.0, "m", "elongation of the right spring: q_next - q, minus the rest length") \
    X(a_left, INPUT, 0.0, "sqrt(J)", "left incident wave (wave mode), scaled by sqrt(dt)") \
    X(F_left, INPUT, 0.0, "N", "left effort input: tension pulling the mass towards -x (physical mode)") \
    X(a_right, INPUT, 0.0, "sqrt(J)", "right incident wave (wave mode), scaled by sqrt(dt)") \
    X(u_right, INPUT, 0.0, "m/s", "right flow input: velocity of the next mass (physical mode)") \
    X(b_left, OUTPUT, 0.0, "sqrt(J)", "left outgoing wave, scaled by sqrt(dt)") \
    X(e_left, OUTPUT, 0.0, "N", "left effort held over the step") \
    X(f_left, OUTPUT, 0.0, "m/s", "left flow: -v at the stage") \
    X(b_right, OUTPUT, 0.0, "sqrt(J)", "right outgoing wave, scaled by sqrt(dt)") \
    X(e_right, OUTPUT, 0.0, "N", "right effort: spring tension at the stage") \
    X(f_right, OUTPUT, 0.0, "m/s", "right flow: next mass velocity held over the step") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave ports (inputs a_*, outputs b_*), 1 = physical ports (F_left, u_right)")

#define PORT_CHANNELS(X) \
    X(a_left, b_left, e_left, f_left, F_left, EFFORT_INPUT) \
    X(a_right, b_right, e_right, f_right, u_right, FLOW_INPUT)
