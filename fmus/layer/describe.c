/* Prints the model's modelDescription.xml from the same X-macro tables the binary is built from,
 * so value references, start values and causalities can never drift apart. */
#include <stdio.h>

#include "model.h"

static const char *causality(int kind) {
    switch (kind) {
    case PARAMETER: case TUNABLE: return "parameter";
    case INPUT: return "input";
    default: return "output";
    }
}

/* Prints text with the XML special characters escaped. */
static void print_escaped(const char *text) {
    for (; *text; text++) {
        switch (*text) {
        case '<': fputs("&lt;", stdout); break;
        case '>': fputs("&gt;", stdout); break;
        case '&': fputs("&amp;", stdout); break;
        case '"': fputs("&quot;", stdout); break;
        default: putchar(*text);
        }
    }
}

#define PRINT_REAL(name, kind, start, unit, desc) print_real(#name, VR_##name, kind, start, unit, desc);
#define PRINT_INT(name, start, desc) print_int(#name, INTEGER_VR_BASE + VRI_##name, PARAMETER, start, desc);
#define PRINT_INT_IO(name, kind, start, desc) print_int(#name, INTEGER_VR_BASE + VRI_##name, kind, start, desc);
#define PRINT_BOOL(name, kind, start, desc) \
    print_typed("Boolean", #name, BOOLEAN_VR_BASE + VRB_##name, kind, (start) ? "true" : "false", desc);
#define PRINT_STRING(name, kind, start, desc) \
    print_typed("String", #name, STRING_VR_BASE + VRS_##name, kind, start, desc);
#define REAL_KIND(name, kind, start, unit, desc) kind,
#define INT_KIND(name, start, desc) PARAMETER,
#define TYPED_KIND(name, kind, start, desc) kind,
/* the kind of every variable in the order of ModelVariables: reals, integers, Booleans, strings */
static const int kinds[] = {REAL_VARIABLES(REAL_KIND) INTEGER_VARIABLES(INT_KIND) INTEGER_IO(TYPED_KIND)
                            BOOLEAN_VARIABLES(TYPED_KIND) STRING_VARIABLES(TYPED_KIND)};
enum { N_VARIABLES = N_REALS + N_INTEGERS + N_BOOLEANS + N_STRINGS };

/* Is a variable of this kind listed: among the outputs (states are exposed as outputs), or among
 * the initial unknowns (calculated outputs only)? */
static int is_output(int kind) { return kind == STATE || kind == OUTPUT; }
static int is_initial_unknown(int kind) { return kind == OUTPUT; }

#if HAS_FEEDTHROUGH
#define FEEDTHROUGH_PAIR(out, in) {VR_##out, VR_##in},
static const int feedthrough[][2] = {FEEDTHROUGH(FEEDTHROUGH_PAIR)};
enum { N_FEEDTHROUGH = sizeof feedthrough / sizeof feedthrough[0] };

/* The dependencies attribute of output k: the inputs it depends on directly (1-based indices). */
static void print_dependencies(int k) {
    const char *sep = "";
    printf(" dependencies=\"");
    for (int j = 0; j < N_FEEDTHROUGH; j++)
        if (feedthrough[j][0] == k) {
            printf("%s%d", sep, feedthrough[j][1] + 1);
            sep = " ";
        }
    printf("\"");
}
#else
static void print_dependencies(int k) { (void)k; }
#endif

/* Prints <element> with one Unknown per selected variable (1-based index), or nothing when none is
 * selected: the schema does not allow the element empty. */
static void print_unknowns(const char *element, int (*selected)(int kind)) {
    int any = 0;
    for (int k = 0; k < N_VARIABLES; k++) any |= selected(kinds[k]);
    if (!any) return;
    printf("    <%s>\n", element);
    for (int k = 0; k < N_VARIABLES; k++)
        if (selected(kinds[k])) {
            printf("      <Unknown index=\"%d\"", k + 1);
            print_dependencies(k);
            printf("/>\n");
        }
    printf("    </%s>\n", element);
}

static void print_real(const char *name, int vr, int kind, double start, const char *unit, const char *desc) {
    const char *variability = kind == PARAMETER ? "fixed" : kind == TUNABLE ? "tunable" : "continuous";
    printf("    <ScalarVariable name=\"%s\" valueReference=\"%d\" causality=\"%s\" variability=\"%s\"",
           name, vr, causality(kind), variability);
    if (kind == STATE) printf(" initial=\"exact\"");
    if (kind == OUTPUT) printf(" initial=\"calculated\"");
    printf(" description=\"");
    print_escaped(desc);
    printf("\">\n");
    if (kind == OUTPUT) printf("      <Real");
    else printf("      <Real start=\"%.17g\"", start);
    if (unit[0]) printf(" unit=\"%s\"", unit);
    printf("/>\n    </ScalarVariable>\n");
}

/* The opening of a ScalarVariable of a discrete type (Integer, Boolean, String): a parameter is
 * fixed, an input or output discrete, an output calculated (and has no start). */
static void print_head(const char *name, int vr, int kind, const char *desc) {
    const char *variability = kind == PARAMETER ? "fixed" : kind == TUNABLE ? "tunable" : "discrete";
    printf("    <ScalarVariable name=\"%s\" valueReference=\"%d\" causality=\"%s\" variability=\"%s\"%s "
           "description=\"", name, vr, causality(kind), variability, kind == OUTPUT ? " initial=\"calculated\"" : "");
    print_escaped(desc);
    printf("\">\n");
}

static void print_int(const char *name, int vr, int kind, int start, const char *desc) {
    print_head(name, vr, kind, desc);
    if (kind == OUTPUT) printf("      <Integer/>\n");
    else printf("      <Integer start=\"%d\"/>\n", start);
    printf("    </ScalarVariable>\n");
}

#if HAS_BOOLEANS || HAS_STRINGS
/* A Boolean or String variable, its start given as the XML text. */
static void print_typed(const char *type, const char *name, int vr, int kind, const char *start, const char *desc) {
    print_head(name, vr, kind, desc);
    if (kind == OUTPUT) {
        printf("      <%s/>\n", type);
    } else {
        printf("      <%s start=\"", type);
        print_escaped(start);
        printf("\"/>\n");
    }
    printf("    </ScalarVariable>\n");
}
#endif

/* The C files master/wavecosim/fmi/build.py compiles into the binary; sources/ in the FMU holds them and every
 * header they include, so `fmpy compile` can rebuild the binary on another platform. */
#ifndef FMI_LAYER_SOURCE
#define FMI_LAYER_SOURCE "fmi2_cosim.c"
#endif
#ifndef CAN_SERIALIZE_FMU_STATE
#define CAN_SERIALIZE_FMU_STATE "true"
#endif
#ifndef CAN_VARIABLE_STEP
#define CAN_VARIABLE_STEP "true"
#endif
static const char *source_files[] = {FMI_LAYER_SOURCE, "model.c"};

static void print_source_files(void) {
    printf("    <SourceFiles>\n");
    for (size_t k = 0; k < sizeof source_files / sizeof source_files[0]; k++)
        printf("      <File name=\"%s\"/>\n", source_files[k]);
    printf("    </SourceFiles>\n");
}

#define UNIT_DEF(name, kind, start, unit, desc) collect_unit(unit);
static const char *units[64];
static int n_units = 0;
static void collect_unit(const char *unit) {
    if (!unit[0]) return;
    for (int k = 0; k < n_units; k++) {
        const char *a = units[k], *b = unit;
        while (*a && *a == *b) { a++; b++; }
        if (*a == *b) return;
    }
    if (n_units < 64) units[n_units++] = unit;
}

int main(void) {
    printf("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    printf("<fmiModelDescription fmiVersion=\"2.0\" modelName=\"%s\" guid=\"%s\" description=\"%s\" "
           "generationTool=\"wavecosim fmus/layer\" variableNamingConvention=\"flat\" numberOfEventIndicators=\"0\">\n",
           MODEL_IDENTIFIER_STR, MODEL_GUID, MODEL_DESCRIPTION);
    printf("  <CoSimulation modelIdentifier=\"%s\" canHandleVariableCommunicationStepSize=\"%s\" "
           "canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"%s\" canNotUseMemoryManagementFunctions=\"true\">\n",
           MODEL_IDENTIFIER_STR, CAN_VARIABLE_STEP, CAN_SERIALIZE_FMU_STATE);
    print_source_files();
    printf("  </CoSimulation>\n");
    REAL_VARIABLES(UNIT_DEF)
    if (n_units) {
        printf("  <UnitDefinitions>\n");
        for (int k = 0; k < n_units; k++) printf("    <Unit name=\"%s\"/>\n", units[k]);
        printf("  </UnitDefinitions>\n");
    }
    printf("  <DefaultExperiment %s/>\n", DEFAULT_EXPERIMENT);
    printf("  <ModelVariables>\n");
    REAL_VARIABLES(PRINT_REAL)
    INTEGER_VARIABLES(PRINT_INT)
    INTEGER_IO(PRINT_INT_IO)
    BOOLEAN_VARIABLES(PRINT_BOOL)
    STRING_VARIABLES(PRINT_STRING)
    printf("  </ModelVariables>\n  <ModelStructure>\n");
    print_unknowns("Outputs", is_output);
    print_unknowns("InitialUnknowns", is_initial_unknown);
    printf("  </ModelStructure>\n</fmiModelDescription>\n");
    return 0;
}
