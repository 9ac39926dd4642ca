/* The mechanical side of a DC motor drive: rotor and load inertia J with viscous friction and a
 * torsional spring to ground (a compliant shaft). Port: effort in = torque tau applied to the
 * shaft, flow out = angular velocity omega at the stage; tau omega is the power into the load.
 *   J domega/dt = tau - friction omega - stiffness theta.
 * The electro-mechanical conversion is not in here: the master couples this port to RLCCircuit
 * (also effort in) through the motor constant Km as an ideal gyrator, u = Km omega, tau = -Km i.
 * A gyrator maps flow to effort, so both of its sides are effort-in; see rlc_circuit/config.h. */
#define MODEL_IDENTIFIER DCMotorLoad
#define MODEL_GUID "{13346649-b004-4c3a-8392-1e19b6d95856}"
#define MODEL_DESCRIPTION "Inertia with viscous friction and torsional spring, torque/speed port; implicit midpoint step"

#define REAL_VARIABLES(X) \
    X(J, PARAMETER, 0.01, "kg.m2", "moment of inertia of rotor and load") \
    X(friction, PARAMETER, 0.01, "N.m.s/rad", "viscous friction") \
    X(stiffness, PARAMETER, 1.0, "N.m/rad", "torsional spring to ground") \
    X(gamma, TUNABLE, 0.01, "N.m.s/rad", "scattering impedance of the wave port") \
    X(theta, STATE, 0.0, "rad", "shaft angle") \
    X(omega, STATE, 0.0, "rad/s", "shaft angular velocity") \
    X(a, INPUT, 0.0, "sqrt(J)", "incident wave (wave mode), scaled by sqrt(dt)") \
    X(tau, INPUT, 0.0, "N.m", "port effort input: torque on the shaft (physical mode)") \
    X(b, OUTPUT, 0.0, "sqrt(J)", "outgoing wave, scaled by sqrt(dt)") \
    X(e, OUTPUT, 0.0, "N.m", "port effort: torque held over the step") \
    X(f, OUTPUT, 0.0, "rad/s", "port flow: omega at the stage") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave port (input a, output b), 1 = physical port (input tau)")

#define PORT_CHANNELS(X) X(a, b, e, f, tau, EFFORT_INPUT)
