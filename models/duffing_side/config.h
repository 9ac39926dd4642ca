/* Subsystem A of the paper's benchmark: the Duffing oscillator holding the coupling spring k12
 * and dashpot c12. Port: flow in (u = v2, velocity of mass 2), effort out (the coupling force). */
#define MODEL_IDENTIFIER DuffingSide
#define MODEL_GUID "{5f0c2a8e-8d1b-4c55-9a6e-3d2f7a1b0001}"
#define MODEL_DESCRIPTION "Duffing oscillator with the coupling spring-damper; discrete-gradient step"

#define REAL_VARIABLES(X) \
    X(m1, PARAMETER, 8.0, "kg", "mass 1") \
    X(k1, PARAMETER, 100.0, "N/m", "linear spring of mass 1") \
    X(c1, PARAMETER, 0.0, "N.s/m", "damper of mass 1") \
    X(k12, PARAMETER, 120.0, "N/m", "coupling spring") \
    X(c12, PARAMETER, 0.05, "N.s/m", "coupling damper") \
    X(knl, PARAMETER, 8000.0, "N/m3", "hardening spring coefficient") \
    X(gamma, TUNABLE, 0.4, "N.s/m", "scattering impedance of the wave port") \
    X(newton_rtol, PARAMETER, 1e-12, "", "relative tolerance of the Newton step") \
    X(q1, STATE, 0.4, "m", "position of mass 1") \
    X(v1, STATE, 0.0, "m/s", "velocity of mass 1") \
    X(d, STATE, -0.4, "m", "coupling spring elongation q2 - q1") \
    X(a, INPUT, 0.0, "sqrt(J)", "incident wave (wave mode), scaled by sqrt(dt)") \
    X(u, INPUT, 0.0, "m/s", "port flow input v2 (physical mode)") \
    X(b, OUTPUT, 0.0, "sqrt(J)", "outgoing wave, scaled by sqrt(dt)") \
    X(e, OUTPUT, 0.0, "N", "port effort: coupling force (stage value)") \
    X(f, OUTPUT, 0.0, "m/s", "port flow: v2 held over the step") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave port (input a, output b), 1 = physical port (input u)") \
    X(newton_max_iter, 50, "iteration limit of the Newton step")

#define PORT_CHANNELS(X) X(a, b, e, f, u, FLOW_INPUT)
