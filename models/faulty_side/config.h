/* A damped mass with an effort port (it can take LinearSide's place) that misbehaves on purpose, so the
 * tests can check that a run contains a crashing, exiting, hanging or chatty FMU. In doStep, in the
 * first one that starts at t = fault_step * h: fault 1 dereferences a null pointer (SIGSEGV), 2 calls
 * exit(0), 3 loops forever, 4 calls abort(), 5 loops forever with every signal blocked, 6 stops its
 * process (SIGSTOP) again and again, 7 loops forever under its own SIGUSR2, SIGTERM and SIGINT
 * handlers (as a JVM does), 8 segfaults in a thread it started, 9 forks a helper that sleeps and
 * then segfaults, 10 kills its process (SIGKILL), 11 changes the working directory to / and goes on.
 * Elsewhere: 12 fmi2SetFMUstate multiplies v by 1 + 1e-4 from t = fault_step * h on (a restore that
 * drifts), 13 the first fmi2SetFMUstate loops forever, 14 b and e are NaN after the initialization.
 * In doStep again: 15 fails the step with a message logged as a printf format and its arguments,
 * 16 returns NaN outputs with status OK, 17 restores its state only in part (from fault_step on,
 * every step depends on the doSteps the instance made before), 18 calls _exit(3) (no exit handler
 * sees it), 19 closes every file descriptor of its process, then segfaults.
 * The environment variable FAULTYSIDE_HANG = load or instantiate makes the binary loop forever
 * when it is loaded or in fmi2Instantiate. With log_bytes > 0 every successful step logs a warning
 * of that many characters. */
#define MODEL_HOOKS
#define FAULTY_LAYER 1
#define MODEL_IDENTIFIER FaultySide
#define MODEL_GUID "{3c0f4a52-8e1d-4d2b-9a6e-7f1b2c3d0f17}"
#define MODEL_DESCRIPTION "Damped mass that crashes, exits, hangs, stops, fails, gives NaN or lies at a chosen step (tests)"

#define REAL_VARIABLES(X) \
    X(mass, PARAMETER, 4.0, "kg", "the mass") \
    X(damping, PARAMETER, 0.5, "N.s/m", "viscous damping to ground") \
    X(gamma, TUNABLE, 0.4, "N.s/m", "scattering impedance of the wave port") \
    X(x, STATE, 0.0, "m", "position") \
    X(v, STATE, 0.0, "m/s", "velocity") \
    X(a, INPUT, 0.0, "", "incident wave (wave mode), scaled by sqrt(dt)") \
    X(F, INPUT, 0.0, "N", "port effort input: the force pulling the mass towards -x (physical mode)") \
    X(b, OUTPUT, 0.0, "", "outgoing wave, scaled by sqrt(dt)") \
    X(e, OUTPUT, 0.0, "N", "port effort held over the step") \
    X(f, OUTPUT, 0.0, "m/s", "port flow: -v at the stage") \
    X(H, OUTPUT, 0.0, "J", "kinetic energy")

#define INTEGER_VARIABLES(X) \
    X(port_mode, 0, "0 = wave port (input a, output b), 1 = physical port (input F)") \
    X(fault, 0, "0 none, 1..19: the fault of config.h's comment, at fault_step") \
    X(fault_step, -1, "the macro-step whose doStep faults (-1: none)") \
    X(log_bytes, 0, "characters of the warning logged after every step (0: none, at most 250)")

#define PORT_CHANNELS(X) X(a, b, e, f, F, EFFORT_INPUT)
