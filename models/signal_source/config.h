/* A source of signals of every FMI 2 type, with no port (as most exported FMUs are): a sine, a
 * step counter, a flag that flips every `period` steps and a label that follows the flag. With
 * SignalSink it forms a signal-only pair: every type through a connection, with no power bond. */
#define MODEL_IDENTIFIER SignalSource
#define MODEL_GUID "{6b0e5f7a-2d41-4c1e-9a53-8f2c7d3e9b10}"
#define MODEL_DESCRIPTION "Signals of every type: y = amplitude sin(2 pi frequency t), a step count, a flag and its label"

#define HAS_WAVE_PORT 0
#define HAS_ENERGY_OUTPUT 0
#define DEFAULT_EXPERIMENT "startTime=\"0\" stopTime=\"2\" stepSize=\"0.05\""

#define REAL_VARIABLES(X) \
    X(amplitude, PARAMETER, 1.0, "", "amplitude of y") \
    X(frequency, PARAMETER, 1.0, "Hz", "frequency of y") \
    X(y, OUTPUT, 0.0, "", "amplitude sin(2 pi frequency t) at the end of the step")

#define INTEGER_VARIABLES(X) \
    X(period, 4, "steps between two flips of the flag, >= 1")

#define INTEGER_IO(X) \
    X(count, OUTPUT, 0, "steps made")

#define BOOLEAN_VARIABLES(X) \
    X(flag, OUTPUT, 0, "count / period is odd")

#define STRING_VARIABLES(X) \
    X(label, OUTPUT, "", "the flag in words: low, or high, \"on\" (a comma and quotes, as text may hold)")
