/* A 2-D spring-damper anchored at the origin, its free end at (x, y): the partner of PlanarMass.
 * Potential V = kx x^2/2 + kxy x y + ky y^2/2 + kn (x^2 + y^2)^2/4 (anisotropic, with an isotropic
 * hardening term; convex when kx, ky > 0, kx ky >= kxy^2, kn >= 0), damper force damping * v.
 * Each channel takes a flow in (velocity of the free end) and gives an effort out (the force the
 * outside applies to the end, grad V + damping v), so e . f is the power into the spring. */
#define MODEL_IDENTIFIER PlanarSpring
#define MODEL_GUID "{a5c857a3-fb7d-4394-826c-470de50a353e}"
#define MODEL_DESCRIPTION "Anchored nonlinear 2-D spring-damper with a 2-channel velocity port; AVF discrete-gradient step"

#define REAL_VARIABLES(X) \
    X(kx, PARAMETER, 10.0, "N/m", "stiffness along x") \
    X(ky, PARAMETER, 20.0, "N/m", "stiffness along y") \
    X(kxy, PARAMETER, 4.0, "N/m", "cross stiffness, kxy^2 at most kx ky") \
    X(kn, PARAMETER, 50.0, "N/m3", "isotropic hardening coefficient of kn r^4/4") \
    X(damping, PARAMETER, 0.0, "N.s/m", "isotropic damper of the free end") \
    X(gamma, TUNABLE, 1.0, "N.s/m", "scattering impedance of both wave channels") \
    X(newton_rtol, PARAMETER, 1e-12, "", "relative tolerance of the Newton step") \
    X(x, STATE, 0.2, "m", "free end position x") \
    X(y, STATE, 0.1, "m", "free end position y") \
    X(a_x, INPUT, 0.0, "sqrt(J)", "incident wave, x channel (wave mode), scaled by sqrt(dt)") \
    X(u_x, INPUT, 0.0, "m/s", "flow input x: free end velocity (physical mode)") \
    X(a_y, INPUT, 0.0, "sqrt(J)", "incident wave, y channel (wave mode), scaled by sqrt(dt)") \
    X(u_y, INPUT, 0.0, "m/s", "flow input y: free end velocity (physical mode)") \
    X(b_x, OUTPUT, 0.0, "sqrt(J)", "outgoing wave, x channel, scaled by sqrt(dt)") \
    X(e_x, OUTPUT, 0.0, "N", "effort x: force on the free end at the stage") \
    X(f_x, OUTPUT, 0.0, "m/s", "flow x held over the step") \
    X(b_y, OUTPUT, 0.0, "sqrt(J)", "outgoing wave, y channel, scaled by sqrt(dt)") \
    X(e_y, OUTPUT, 0.0, "N", "effort y: force on the free end at the stage") \
    X(f_y, OUTPUT, 0.0, "m/s", "flow y held over the step") \
    X(H, OUTPUT, 0.0, "J", "stored energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave ports (inputs a_*, outputs b_*), 1 = physical ports (inputs u_*)") \
    X(newton_max_iter, 50, "iteration limit of the 2x2 Newton step")

#define PORT_CHANNELS(X) \
    X(a_x, b_x, e_x, f_x, u_x, FLOW_INPUT) \
    X(a_y, b_y, e_y, f_y, u_y, FLOW_INPUT)
