/* A point mass behind the strict FMI layer (fmus/layer/fmi2_strict.c): a twin of ForeignMass
 * (the same port: input F, the force on the mass; output v, its velocity; F v is the power into
 * the mass) that aborts the process on any misuse of an instance or a state handle, as the least
 * forgiving real exports crash on it. Its step is exact for the held force.
 *
 * Three parameters switch on behaviours of real FMUs (all off by default):
 *   freeze_without_flag  1: doStep with noSetFMUStatePriorToCurrentPoint = false freezes the state
 *                        after the first step (outputs constant, status OK); 2: every such doStep
 *                        after the first returns the state to its start point (outputs constant
 *                        from the second step on, status OK), as a real CVODE-based FMU does;
 *   shared_state         1: every instance in one copy of the binary keeps its variables in one
 *                        block (an FMU that is not reentrant); 2: one block for the whole process,
 *                        whichever copy of the binary an instance is in;
 *   restore_error        fmi2SetFMUstate leaves x and v off by this relative error.
 * Its integer outputs nDoStep, nGetFMUstate, nSetFMUstate, nGet and nSet are the calls the instance
 * took (value gets and sets of every type), counted by the FMU itself (the layer's COUNT_CALLS), to
 * check a master's own count against. */
#define MODEL_IDENTIFIER StrictMass
#define MODEL_GUID "{37ea3a43-9766-407f-813e-02e867337245}"
#define MODEL_DESCRIPTION "Mass with viscous damping behind a strict FMI layer; input: force on the mass, output: its velocity (power in)"
#define FMI_LAYER_SOURCE "fmi2_strict.c"
#define CAN_SERIALIZE_FMU_STATE "false"

#define HAS_WAVE_PORT 0
#define HAS_ENERGY_OUTPUT 1

#define REAL_VARIABLES(X) \
    X(m, PARAMETER, 1.0, "kg", "mass") \
    X(c, PARAMETER, 0.0, "N.s/m", "viscous damping to ground") \
    X(F_max, PARAMETER, 1e6, "N", "largest force accepted: a doStep beyond it returns fmi2Error") \
    X(restore_error, PARAMETER, 0.0, "", "relative error fmi2SetFMUstate leaves on x and v (0: exact)") \
    X(x, STATE, 0.0, "m", "position") \
    X(v, STATE, 0.0, "m/s", "velocity: the output; F v is the power into the mass") \
    X(F, INPUT, 0.0, "N", "force applied to the mass, held over the step") \
    X(H, OUTPUT, 0.0, "J", "kinetic energy m v^2 / 2")

#define INTEGER_VARIABLES(X) \
    X(freeze_without_flag, 0, "doStep with noSetFMUStatePriorToCurrentPoint = false after the first step: 1 stays, 2 returns to the start") \
    X(shared_state, 0, "1: one block of variables for every instance of this binary, 2: for the whole process")

#define INTEGER_IO(X) \
    X(nDoStep, OUTPUT, 0, "fmi2DoStep calls this instance took, its own count (no restore undoes it)") \
    X(nGetFMUstate, OUTPUT, 0, "fmi2GetFMUstate calls this instance took, its own count") \
    X(nSetFMUstate, OUTPUT, 0, "fmi2SetFMUstate calls this instance took, its own count") \
    X(nGet, OUTPUT, 0, "fmi2Get Real, Integer, Boolean and String calls this instance took (the one reading it included)") \
    X(nSet, OUTPUT, 0, "fmi2Set Real, Integer, Boolean and String calls this instance took, its own count")

#define QUIRK_FREEZE VRI_freeze_without_flag
#define QUIRK_SHARED VRI_shared_state
#define QUIRK_RESTORE VR_restore_error
#define COUNT_CALLS VRI_nDoStep
