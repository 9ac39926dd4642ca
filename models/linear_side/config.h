/* Subsystem B of the paper's benchmark: the linear oscillator. Port: effort in (coupling force F),
 * flow out (f = -v2 at the stage). */
#define MODEL_IDENTIFIER LinearSide
#define MODEL_GUID "{9b3d6e10-22f4-4b8a-8c1e-5a4b3c2d0002}"
#define MODEL_DESCRIPTION "Linear oscillator; implicit midpoint (discrete-gradient) step"

#define REAL_VARIABLES(X) \
    X(m2, PARAMETER, 4.0, "kg", "mass 2") \
    X(k2, PARAMETER, 50.0, "N/m", "spring of mass 2") \
    X(c2, PARAMETER, 0.0, "N.s/m", "damper of mass 2") \
    X(gamma, TUNABLE, 0.4, "N.s/m", "scattering impedance of the wave port") \
    X(q2, STATE, 0.0, "m", "position of mass 2") \
    X(v2, STATE, 0.0, "m/s", "velocity of mass 2") \
    X(a, INPUT, 0.0, "sqrt(J)", "incident wave (wave mode), scaled by sqrt(dt)") \
    X(F, INPUT, 0.0, "N", "port effort input: coupling force (physical mode)") \
    X(b, OUTPUT, 0.0, "sqrt(J)", "outgoing wave, scaled by sqrt(dt)") \
    X(e, OUTPUT, 0.0, "N", "port effort: coupling force held over the step") \
    X(f, OUTPUT, 0.0, "m/s", "port flow: -v2 at the stage") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave port (input a, output b), 1 = physical port (input F)")

#define PORT_CHANNELS(X) X(a, b, e, f, F, EFFORT_INPUT)
