/* A series loop of inductor L, resistor R and capacitor C, started from a charged capacitor,
 * with no sources: one electrical port in the loop (effort = voltage u across the port terminals,
 * flow = current i_L into the + terminal; u i is the power into the circuit).
 *   L di/dt = u - R i - q/C,  dq/dt = i.
 * Causality: effort in (voltage), flow out (current), like an inductor; DCMotorLoad is effort in
 * too (torque in, speed out). The two are joined through the motor constant Km, an ideal gyrator
 * that maps each side's flow to the other side's effort:
 *   u = Km omega,  tau = -Km i     (u i + tau omega = 0, lossless),
 * so a gyrator needs both sides effort-in (or both flow-in), never one of each. In waves the
 * gyrator is orthogonal (a_rlc = -b_motor, a_motor = b_rlc) when gamma_motor = Km^2 / gamma_rlc;
 * the default gammas (1 Ohm here, 0.01 N.m.s/rad there) match Km = 0.1 N.m/A. */
#define MODEL_IDENTIFIER RLCCircuit
#define MODEL_GUID "{c5d72f87-265f-499a-a25e-8785e9693085}"
#define MODEL_DESCRIPTION "Series RLC loop with a voltage/current port, no sources; implicit midpoint step"

#define REAL_VARIABLES(X) \
    X(L, PARAMETER, 0.1, "H", "inductance") \
    X(R, PARAMETER, 1.0, "Ohm", "resistance") \
    X(C, PARAMETER, 0.01, "F", "capacitance") \
    X(gamma, TUNABLE, 1.0, "Ohm", "scattering impedance of the wave port") \
    X(q_C, STATE, 0.1, "C", "capacitor charge (0.1 C on 10 mF is 10 V)") \
    X(i_L, STATE, 0.0, "A", "loop current (inductor current)") \
    X(a, INPUT, 0.0, "sqrt(J)", "incident wave (wave mode), scaled by sqrt(dt)") \
    X(u, INPUT, 0.0, "V", "port effort input: voltage across the port (physical mode)") \
    X(b, OUTPUT, 0.0, "sqrt(J)", "outgoing wave, scaled by sqrt(dt)") \
    X(e, OUTPUT, 0.0, "V", "port effort: voltage held over the step") \
    X(f, OUTPUT, 0.0, "A", "port flow: loop current at the stage") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave port (input a, output b), 1 = physical port (input u)")

#define PORT_CHANNELS(X) X(a, b, e, f, u, EFFORT_INPUT)
