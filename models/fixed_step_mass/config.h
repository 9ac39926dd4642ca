/* ForeignMass (models/foreign_mass) declaring canHandleVariableCommunicationStepSize="false", as
 * exports with a solver tied to one step do: a master must keep its communication step. */
#define MODEL_SOURCE "foreign_mass"
#define MODEL_IDENTIFIER FixedStepMass
#define MODEL_GUID "{8c1f7a52-3b0e-4f43-9d55-0e6a1c2b7f31}"
#define CAN_VARIABLE_STEP "false"
#define MODEL_DESCRIPTION "Mass that keeps one step, with viscous damping; input: force on the mass, output: its velocity (power in); RK4 substeps"

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
