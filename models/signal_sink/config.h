/* A sink of signals of every FMI 2 type, with no port: it integrates a Real input, shifts an
 * Integer, negates a Boolean and echoes a String (and counts its bytes). Its DefaultExperiment
 * gives no step size, so a system of it alone needs one. */
#define MODEL_IDENTIFIER SignalSink
#define MODEL_GUID "{0f3a9c2e-71b4-4d8a-b6e5-2c9d1e4f7a83}"
#define MODEL_DESCRIPTION "Inputs of every type: the integral of u, n + offset, not on, and the text echoed"

#define HAS_WAVE_PORT 0
#define HAS_ENERGY_OUTPUT 0
#define DEFAULT_EXPERIMENT "startTime=\"0\" stopTime=\"2\""

#define REAL_VARIABLES(X) \
    X(gain, PARAMETER, 2.0, "", "gain of scaled") \
    X(u, INPUT, 0.0, "", "Real input, held over the step") \
    X(integral, STATE, 0.0, "", "integral of u") \
    X(scaled, OUTPUT, 0.0, "", "gain u of the last step")

#define INTEGER_VARIABLES(X) \
    X(offset, 10, "added to n")

#define INTEGER_IO(X) \
    X(n, INPUT, 0, "Integer input") \
    X(shifted, OUTPUT, 0, "n + offset of the last step") \
    X(length, OUTPUT, 0, "bytes of text in the last step")

#define BOOLEAN_VARIABLES(X) \
    X(on, INPUT, 0, "Boolean input") \
    X(off, OUTPUT, 1, "not on, in the last step")

#define STRING_VARIABLES(X) \
    X(text, INPUT, "none", "String input") \
    X(echo, OUTPUT, "", "text, as it came in the last step")
