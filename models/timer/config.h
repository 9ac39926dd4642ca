/* A clock whose experiment starts at t = 20 s (as some exported FMUs' do): it reports the time it
 * was set up at, the end of its last step, and the tolerance fmi2SetupExperiment gave it. A master
 * that starts it at 0, or does not pass the DefaultExperiment's tolerance, shows in its outputs. */
#define MODEL_IDENTIFIER Timer
#define MODEL_GUID "{c4d2a7e1-93f5-4b60-8e2a-5d71f0b9c6e4}"
#define MODEL_DESCRIPTION "Time since the start of its experiment (DefaultExperiment start 20 s, tolerance 1e-5)"

#define HAS_WAVE_PORT 0
#define HAS_ENERGY_OUTPUT 0
#define DEFAULT_EXPERIMENT "startTime=\"20\" stopTime=\"22\" stepSize=\"0.25\" tolerance=\"1e-05\""

#define REAL_VARIABLES(X) \
    X(start, OUTPUT, 0.0, "s", "the start time of the experiment") \
    X(clock, OUTPUT, 0.0, "s", "the end of the last step (the start time before any)") \
    X(elapsed, OUTPUT, 0.0, "s", "clock - start") \
    X(tolerance, OUTPUT, 0.0, "", "the relative tolerance set up (0: none)")

#define INTEGER_IO(X) \
    X(steps, OUTPUT, 0, "steps made")
