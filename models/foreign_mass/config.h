/* A point mass as another tool (Dymola, OpenModelica) would export it: physical causality only,
 * its own fixed-step solver (`substeps` classical Runge-Kutta steps per doStep), no stored-energy
 * output, no wave port, no gamma or port_mode.
 *
 * Orientation: the input F is the force applied TO the mass and the output v its velocity, so
 * F v is the power flowing INTO the mass: a power-in port, whose step map has dv/dF > 0
 * (h/m when undamped). Pair it with ForeignSpring, whose output is the force it exerts on the mass. */
#define MODEL_IDENTIFIER ForeignMass
#define MODEL_GUID "{351bc20f-dee2-425d-b6ad-7b7f67d5ec98}"
#define MODEL_DESCRIPTION "Mass with viscous damping; input: force on the mass, output: its velocity (power in); RK4 substeps"

#define HAS_WAVE_PORT 0
#define HAS_ENERGY_OUTPUT 0

#define REAL_VARIABLES(X) \
    X(m, PARAMETER, 1.0, "kg", "mass") \
    X(c, PARAMETER, 0.0, "N.s/m", "viscous damping to ground") \
    X(x, STATE, 0.0, "m", "position") \
    X(v, STATE, 0.0, "m/s", "velocity: the output; F v is the power into the mass") \
    X(F, INPUT, 0.0, "N", "force applied to the mass, held over the step")

#define INTEGER_VARIABLES(X) \
    X(substeps, 10, "classical Runge-Kutta steps per communication step, >= 1")
