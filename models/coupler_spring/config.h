/* A massless spring k with a parallel damper c between two ends: the link between Oscillators.
 *
 * Both channels take a flow in and give an effort out (the tension, the same on both ends):
 *   left:  f_left  = -(velocity of the left end),  e_left  = tension
 *   right: f_right = +(velocity of the right end), e_right = tension
 * so e_left f_left + e_right f_right = tension * (v_right - v_left), the power into the element.
 * Pair the left channel with an Oscillator's right channel and the right channel with the next
 * Oscillator's left channel (e_A = e_B, f_A + f_B = 0). An end fixed to a wall is a channel held
 * at f = 0: physical mode, input 0; wave mode, a = b (the one-port wave map P = +1, lossless). */
#define MODEL_IDENTIFIER SpringDamper
#define MODEL_GUID "{49339cc1-48d8-47f8-a08a-1ae367768eb0}"
#define MODEL_DESCRIPTION "Spring-damper between two flow-input ends; implicit midpoint step"

#define REAL_VARIABLES(X) \
    X(k, PARAMETER, 20.0, "N/m", "spring") \
    X(c, PARAMETER, 0.0, "N.s/m", "damper in parallel with the spring") \
    X(gamma, TUNABLE, 1.0, "N.s/m", "scattering impedance of both wave channels") \
    X(delta, STATE, 0.0, "m", "elongation: right end minus left end, minus the rest length") \
    X(a_left, INPUT, 0.0, "sqrt(J)", "left incident wave (wave mode), scaled by sqrt(dt)") \
    X(u_left, INPUT, 0.0, "m/s", "left flow input: minus the velocity of the left end (physical mode)") \
    X(a_right, INPUT, 0.0, "sqrt(J)", "right incident wave (wave mode), scaled by sqrt(dt)") \
    X(u_right, INPUT, 0.0, "m/s", "right flow input: velocity of the right end (physical mode)") \
    X(b_left, OUTPUT, 0.0, "sqrt(J)", "left outgoing wave, scaled by sqrt(dt)") \
    X(e_left, OUTPUT, 0.0, "N", "left effort: tension at the stage") \
    X(f_left, OUTPUT, 0.0, "m/s", "left flow held over the step") \
    X(b_right, OUTPUT, 0.0, "sqrt(J)", "right outgoing wave, scaled by sqrt(dt)") \
    X(e_right, OUTPUT, 0.0, "N", "right effort: tension at the stage") \
    X(f_right, OUTPUT, 0.0, "m/s", "right flow held over the step") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave ports (inputs a_*, outputs b_*), 1 = physical ports (inputs u_*)")

#define PORT_CHANNELS(X) \
    X(a_left, b_left, e_left, f_left, u_left, FLOW_INPUT) \
    X(a_right, b_right, e_right, f_right, u_right, FLOW_INPUT)
