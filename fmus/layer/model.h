/* The contract between one model (models/<name>/) and the shared FMI 2.0 layer (fmus/layer/).
 *
 * A model's config.h declares its variables with X-macros; this header turns them into value
 * references (VR_<name>, VRI_<name>) and one plain ModelData struct, so the layer can save,
 * restore and serialize state as a byte copy. model.c implements the functions at the bottom.
 *
 * config.h must declare:
 *   MODEL_IDENTIFIER, MODEL_GUID, MODEL_DESCRIPTION
 *   REAL_VARIABLES(X)    X(name, kind, start, unit, description); value reference = position
 *                        kind: PARAMETER (fixed), TUNABLE, STATE (exposed as an output with an
 *                        exact start), INPUT, OUTPUT (calculated)
 *   INTEGER_VARIABLES(X) X(name, start, description): fixed parameters with value reference
 *                        INTEGER_VR_BASE + position (at least one integer, here or in INTEGER_IO)
 *
 * config.h may declare further variables (all optional):
 *   INTEGER_IO(X)        X(name, kind, start, description), kind PARAMETER, INPUT or OUTPUT: integers
 *                        after INTEGER_VARIABLES in the same array (value reference INTEGER_VR_BASE +
 *                        position in both lists together)
 *   BOOLEAN_VARIABLES(X) X(name, kind, start, description), start 0 or 1: value reference
 *                        BOOLEAN_VR_BASE + position
 *   STRING_VARIABLES(X)  X(name, kind, start, description), start a string literal shorter than
 *                        STRING_SIZE bytes: value reference STRING_VR_BASE + position
 *   DEFAULT_EXPERIMENT   the attributes of <DefaultExperiment> as a string literal (default: start at
 *                        0, stop at 10, step 0.01)
 *
 * config.h may declare (compile-time flags, each 0 or 1, default 1):
 *   HAS_WAVE_PORT        1: the layer closes the port itself, in wave or physical mode. Then
 *                        config.h must also declare the real TUNABLE `gamma` (scattering
 *                        impedance, > 0), the integer `port_mode` (0 = wave, 1 = physical) and
 *                        PORT_CHANNELS(X) X(wave_in, wave_out, effort, flow, physical_in, input_kind)
 *                        with input_kind FLOW_INPUT or EFFORT_INPUT; model.c implements model_step.
 *                        0: a plain physical-causality FMU (as other tools export them): the
 *                        layer declares no port of its own and model.c implements model_step_io.
 *   HAS_ENERGY_OUTPUT    1: config.h declares the real OUTPUT `H`; model.c implements
 *                        model_energy, and the layer writes H = model_energy after the
 *                        initialization and after every step.
 *   HAS_FEEDTHROUGH      (default 0) 1: outputs depend directly on inputs. config.h declares
 *                        FEEDTHROUGH(X) X(output, input), the real pairs the modelDescription
 *                        lists as dependencies (every other output depends on no input);
 *                        model.c implements model_outputs, which the layer calls on entering
 *                        initialization mode and after every set in initialization or step mode.
 *   MODEL_EXTRA_FIELDS   optional: more state kept in ModelData (arrays of internal DOFs)
 *   FAULTY_LAYER         optional, for test models that misbehave on purpose: 1 keeps a step that
 *                        leaves a non-finite real (its outputs are then NaN with status OK), and a
 *                        failed step is logged as many FMUs log, the format and its printf arguments
 *                        handed to the master's logger to format
 *   MODEL_HOOKS          optional: model.c implements model_hook, which the layer calls at the end
 *                        of fmi2Instantiate, fmi2ExitInitializationMode and fmi2SetFMUstate (the
 *                        test FMUs misbehave there on purpose)
 *
 * Integer, Boolean and String outputs are written by the model (model_initialize, model_step_io);
 * inputs of every type are held over the step. The layer reads and writes only: every variable by
 * value reference through get/set, `gamma`,
 * `port_mode` and the PORT_CHANNELS variables when HAS_WAVE_PORT, `H` when HAS_ENERGY_OUTPUT.
 * After every call below it rejects a state with a non-finite real and restores the old one.
 * A step that succeeds may leave a note in msg: the layer logs it as a warning.
 */
#ifndef WAVECOSIM_MODEL_H
#define WAVECOSIM_MODEL_H

#include <stddef.h>
#include "config.h"

#ifndef HAS_WAVE_PORT
#define HAS_WAVE_PORT 1
#endif
#ifndef HAS_ENERGY_OUTPUT
#define HAS_ENERGY_OUTPUT 1
#endif
#ifndef HAS_FEEDTHROUGH
#define HAS_FEEDTHROUGH 0
#endif
#ifndef FAULTY_LAYER
#define FAULTY_LAYER 0
#endif

#if HAS_WAVE_PORT && !defined(PORT_CHANNELS)
#error "config.h: a model with a wave port declares PORT_CHANNELS, gamma and port_mode (or sets HAS_WAVE_PORT 0)"
#endif

#define PARAMETER 0
#define TUNABLE 1
#define STATE 2
#define INPUT 3
#define OUTPUT 4

#define FLOW_INPUT 0
#define EFFORT_INPUT 1

/* Value references of each type start at their own base, so that they never collide. */
#define INTEGER_VR_BASE 1000
#define BOOLEAN_VR_BASE 2000
#define STRING_VR_BASE 3000
#define STRING_SIZE 128      /* bytes of a String variable, its terminating zero included */

#define WAVECOSIM_STR_(x) #x
#define WAVECOSIM_STR(x) WAVECOSIM_STR_(x)
#define MODEL_IDENTIFIER_STR WAVECOSIM_STR(MODEL_IDENTIFIER)

#ifndef INTEGER_VARIABLES
#define INTEGER_VARIABLES(X)
#endif
#ifndef INTEGER_IO
#define INTEGER_IO(X)
#endif
#ifdef BOOLEAN_VARIABLES
#define HAS_BOOLEANS 1
#else
#define HAS_BOOLEANS 0
#define BOOLEAN_VARIABLES(X)
#endif
#ifdef STRING_VARIABLES
#define HAS_STRINGS 1
#else
#define HAS_STRINGS 0
#define STRING_VARIABLES(X)
#endif
#ifndef DEFAULT_EXPERIMENT
#define DEFAULT_EXPERIMENT "startTime=\"0\" stopTime=\"10\" stepSize=\"0.01\""
#endif

#define VR_REAL_ENUM(name, kind, start, unit, desc) VR_##name,
#define VR_INT_ENUM(name, start, desc) VRI_##name,
#define VR_TYPED_ENUM(name, kind, start, desc) VRI_##name,
#define VR_BOOL_ENUM(name, kind, start, desc) VRB_##name,
#define VR_STRING_ENUM(name, kind, start, desc) VRS_##name,
enum { REAL_VARIABLES(VR_REAL_ENUM) N_REALS };
enum { INTEGER_VARIABLES(VR_INT_ENUM) INTEGER_IO(VR_TYPED_ENUM) N_INTEGERS };
enum { BOOLEAN_VARIABLES(VR_BOOL_ENUM) N_BOOLEANS };
enum { STRING_VARIABLES(VR_STRING_ENUM) N_STRINGS };

#ifndef MODEL_EXTRA_FIELDS
#define MODEL_EXTRA_FIELDS
#endif

#if HAS_BOOLEANS
#define BOOLEAN_FIELDS int b[N_BOOLEANS];
#else
#define BOOLEAN_FIELDS
#endif
#if HAS_STRINGS
#define STRING_FIELDS char s[N_STRINGS][STRING_SIZE];
#else
#define STRING_FIELDS
#endif

/* Every simulation variable of an instance; a saved FMU state is a copy of this struct. `time` is
 * the start of the step being made (the communication point doStep got), then its end; `tolerance`
 * what fmi2SetupExperiment passed (0 when it passed none). */
typedef struct {
    double time;
    double tolerance;
    double r[N_REALS];
    int i[N_INTEGERS];
    BOOLEAN_FIELDS
    STRING_FIELDS
    MODEL_EXTRA_FIELDS
} ModelData;

/* Called after start values and parameters are final (exit of initialization mode). Returns 0, or
 * non-zero with a message naming the bad parameter. A model without a wave port also writes its
 * initial OUTPUT variables here. */
int model_initialize(ModelData *m, char *msg, size_t msg_size);

#if HAS_FEEDTHROUGH
/* The outputs that depend directly on inputs, from the current inputs and parameters. */
void model_outputs(ModelData *m);
#endif

#if HAS_ENERGY_OUTPUT
/* Stored energy H(x) of the current state. */
double model_energy(const ModelData *m);
#endif

/* The layers' update of the output H = model_energy of the current state (nothing for a model
 * that does not expose its stored energy). */
static inline void write_energy(ModelData *m) {
#if HAS_ENERGY_OUTPUT
    m->r[VR_H] = model_energy(m);
#else
    (void)m;
#endif
}

#ifdef MODEL_HOOKS
/* Called with the instance's data at the end of the FMI call `call` (its name) that succeeded. */
void model_hook(ModelData *m, const char *call);
#define MODEL_HOOK(m, call) model_hook(m, call)
#else
#define MODEL_HOOK(m, call) ((void)0)
#endif

#if HAS_WAVE_PORT
#define COUNT_CHANNEL(ain, bout, eff, flo, phys, kind) +1
enum { N_CHANNELS = 0 PORT_CHANNELS(COUNT_CHANNEL) };

/* Port closure for one step: on each channel the held port input is `c - s * output`.
 * Physical mode: c = the given input, s = 0. Wave mode: the layer picks c, s so that
 * e + gamma f = sqrt(2 gamma / h) a holds together with the step. */
typedef struct {
    double c[N_CHANNELS];
    double s[N_CHANNELS];
} PortClosure;

/* One discrete-gradient step of size h with the port closure p. On success writes the new state,
 * and the stage port values e[j], f[j] of each channel, and returns 0; the step must satisfy
 * H(x1) - H(x0) = h sum_j e[j] f[j] - (dissipation >= 0) to roundoff. On failure returns
 * non-zero with a message in msg and must leave m unchanged or the layer restores it. */
int model_step(ModelData *m, double h, const PortClosure *p, double *e, double *f,
               char *msg, size_t msg_size);
#else
/* One step of size h of a plain physical-causality model: reads its INPUT variables (held over
 * the step, finite), writes its new state and OUTPUT variables, and returns 0. On failure returns
 * non-zero with a message in msg; the layer restores m. */
int model_step_io(ModelData *m, double h, char *msg, size_t msg_size);
#endif

#endif
