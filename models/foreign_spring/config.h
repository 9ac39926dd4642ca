/* A spring-damper between a wall and a mass, as another tool (Dymola, OpenModelica) would export
 * it: physical causality only, its own fixed-step solver (`substeps` steps per doStep), no
 * stored-energy output, no wave port, no gamma or port_mode.
 *
 * Orientation: the input v is the velocity of the mass (the elongation rate) and the output F is
 * the force the element exerts ON the mass, F = -(k x + d v). So F v is the power flowing OUT of
 * the element: a power-out port, whose step map has dF/dv = -(k h + d) < 0. Pair it with
 * ForeignMass, whose input is the force on the mass. */
#define MODEL_IDENTIFIER ForeignSpring
#define MODEL_GUID "{09912406-bfa5-41cf-b753-392e0db6e0c4}"
#define MODEL_DESCRIPTION "Spring-damper from a wall; input: velocity of the mass, output: force on the mass (power out)"

#define HAS_WAVE_PORT 0
#define HAS_ENERGY_OUTPUT 0

#define REAL_VARIABLES(X) \
    X(k, PARAMETER, 100.0, "N/m", "spring") \
    X(d, PARAMETER, 0.5, "N.s/m", "damper in parallel with the spring") \
    X(x, STATE, 0.1, "m", "elongation: position of the mass minus the rest length") \
    X(v, INPUT, 0.0, "m/s", "velocity of the mass, held over the step") \
    X(F, OUTPUT, 0.0, "N", "force on the mass, -(k x + d v): F v is the power out of the element")

#define INTEGER_VARIABLES(X) \
    X(substeps, 10, "solver steps per communication step, >= 1")
