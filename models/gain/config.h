/* A gain with direct feed-through, as block-diagram FMUs are exported: y = k u + c at every moment,
 * in initialization mode too (the output follows the input as soon as it is set), and x the
 * integral of y. A chain of them (A.y -> B.u -> B.y -> C.u) or a loop makes the initialization
 * depend on the order the inputs are set in, which a master settles before the first step. */
#define MODEL_IDENTIFIER Gain
#define MODEL_GUID "{3c1f6d2a-8e47-4b95-a0d3-5f9e2b7c1a64}"
#define MODEL_DESCRIPTION "Direct feed-through: y = k u + c, and x the integral of y"

#define HAS_WAVE_PORT 0
#define HAS_ENERGY_OUTPUT 0
#define HAS_FEEDTHROUGH 1
#define FEEDTHROUGH(X) X(y, u)
#define DEFAULT_EXPERIMENT "startTime=\"0\" stopTime=\"1\" stepSize=\"0.1\""

#define REAL_VARIABLES(X) \
    X(k, PARAMETER, 1.0, "", "gain") \
    X(c, PARAMETER, 0.0, "", "offset") \
    X(u, INPUT, 0.0, "", "input") \
    X(x, STATE, 0.0, "", "integral of y") \
    X(y, OUTPUT, 0.0, "", "k u + c, following u at once")

#define INTEGER_IO(X) \
    X(steps, OUTPUT, 0, "doSteps made")
