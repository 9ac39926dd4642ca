/* A mass m on a spring k and damper c to ground, with two force ports (left and right), for chains.
 *
 * Both channels take an effort in (the tension of the element attached on that side, pulling the
 * mass outward) and give a flow out, signed so that e f is the power into the oscillator:
 *   left:  e = F_left,  pulls towards -x, f_left  = -vbar
 *   right: e = F_right, pulls towards +x, f_right = +vbar
 *   m dv/dt = -k q - c v - F_left + F_right.
 * Oscillators are joined through SpringDamper FMUs (flow in, effort out) with the lossless pairing
 * e_A = e_B, f_A + f_B = 0: Oscillator.right - SpringDamper.left, SpringDamper.right -
 * Oscillator.left, and so on. With one channel only, this is the benchmark's LinearSide (F, f = -v2).
 * A common 0-junction (equal efforts, flows summing to zero) also works: it is orthogonal in waves.
 *
 * Why two fixed channels and no "n_ports" parameter: the channel list is compiled in, and the
 * master treats every channel generically. An unused channel at the end of a chain is closed by
 * the master: physical mode, input 0 (free end, F = 0); wave mode, a = -b (e = 0, the one-port
 * wave map P = -1, lossless). Feeding a = 0 instead is a matched load: it means e = -gamma f, a
 * damper of impedance gamma to ground, which dissipates. */
#define MODEL_IDENTIFIER Oscillator
#define MODEL_GUID "{10dc75b0-5e71-40e7-93f1-1cfde56b850d}"
#define MODEL_DESCRIPTION "Mass-spring-damper with left and right force ports; implicit midpoint step"

#define REAL_VARIABLES(X) \
    X(m, PARAMETER, 1.0, "kg", "mass") \
    X(k, PARAMETER, 10.0, "N/m", "spring to ground") \
    X(c, PARAMETER, 0.0, "N.s/m", "damper to ground") \
    X(gamma, TUNABLE, 1.0, "N.s/m", "scattering impedance of both wave channels") \
    X(q, STATE, 0.1, "m", "position") \
    X(v, STATE, 0.0, "m/s", "velocity") \
    X(a_left, INPUT, 0.0, "sqrt(J)", "left incident wave (wave mode), scaled by sqrt(dt)") \
    X(F_left, INPUT, 0.0, "N", "left effort input: tension pulling towards -x (physical mode)") \
    X(a_right, INPUT, 0.0, "sqrt(J)", "right incident wave (wave mode), scaled by sqrt(dt)") \
    X(F_right, INPUT, 0.0, "N", "right effort input: tension pulling towards +x (physical mode)") \
    X(b_left, OUTPUT, 0.0, "sqrt(J)", "left outgoing wave, scaled by sqrt(dt)") \
    X(e_left, OUTPUT, 0.0, "N", "left effort held over the step") \
    X(f_left, OUTPUT, 0.0, "m/s", "left flow: -v at the stage") \
    X(b_right, OUTPUT, 0.0, "sqrt(J)", "right outgoing wave, scaled by sqrt(dt)") \
    X(e_right, OUTPUT, 0.0, "N", "right effort held over the step") \
    X(f_right, OUTPUT, 0.0, "m/s", "right flow: +v at the stage") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave ports (inputs a_*, outputs b_*), 1 = physical ports (inputs F_*)")

#define PORT_CHANNELS(X) \
    X(a_left, b_left, e_left, f_left, F_left, EFFORT_INPUT) \
    X(a_right, b_right, e_right, f_right, F_right, EFFORT_INPUT)
