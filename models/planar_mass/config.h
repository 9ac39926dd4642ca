/* A point mass in the plane with optional linear drag: a vector port of two channels (x, y).
 * Each channel takes an effort in and gives a flow out, as in LinearSide: the effort F is the force
 * the mass applies to its neighbour (the force on the mass is -F) and f = -vbar, so F . f is the
 * power into the mass. Pair it with PlanarSpring (flow in, effort out) channel by channel. */
#define MODEL_IDENTIFIER PlanarMass
#define MODEL_GUID "{8295a91a-6e57-4485-9df5-863709a6dcf2}"
#define MODEL_DESCRIPTION "Point mass in the plane with linear drag and a 2-channel force port; implicit midpoint step"

#define REAL_VARIABLES(X) \
    X(m, PARAMETER, 1.0, "kg", "mass") \
    X(drag, PARAMETER, 0.0, "N.s/m", "linear drag coefficient (force -drag v)") \
    X(gamma, TUNABLE, 1.0, "N.s/m", "scattering impedance of both wave channels") \
    X(x, STATE, 0.0, "m", "position x") \
    X(y, STATE, 0.0, "m", "position y") \
    X(vx, STATE, 0.5, "m/s", "velocity x") \
    X(vy, STATE, 0.0, "m/s", "velocity y") \
    X(a_x, INPUT, 0.0, "sqrt(J)", "incident wave, x channel (wave mode), scaled by sqrt(dt)") \
    X(F_x, INPUT, 0.0, "N", "effort input x: force the mass applies (physical mode)") \
    X(a_y, INPUT, 0.0, "sqrt(J)", "incident wave, y channel (wave mode), scaled by sqrt(dt)") \
    X(F_y, INPUT, 0.0, "N", "effort input y: force the mass applies (physical mode)") \
    X(b_x, OUTPUT, 0.0, "sqrt(J)", "outgoing wave, x channel, scaled by sqrt(dt)") \
    X(e_x, OUTPUT, 0.0, "N", "effort x held over the step") \
    X(f_x, OUTPUT, 0.0, "m/s", "flow x: -vx at the stage") \
    X(b_y, OUTPUT, 0.0, "sqrt(J)", "outgoing wave, y channel, scaled by sqrt(dt)") \
    X(e_y, OUTPUT, 0.0, "N", "effort y held over the step") \
    X(f_y, OUTPUT, 0.0, "m/s", "flow y: -vy at the stage") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave ports (inputs a_*, outputs b_*), 1 = physical ports (inputs F_*)")

#define PORT_CHANNELS(X) \
    X(a_x, b_x, e_x, f_x, F_x, EFFORT_INPUT) \
    X(a_y, b_y, e_y, f_y, F_y, EFFORT_INPUT)
