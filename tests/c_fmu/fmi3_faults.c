/* A correct FMI 3.0 FMU (Co-Simulation and Model Exchange) written as a careful third-party tool
 * would, for the tests of `runner validate`: built as it is, validate must find nothing wrong;
 * built with one -DFAULT_... flag, it has exactly that fault and validate must name it.
 *
 * The model: x' = -k x, x(0) = x0 (= 1), with the event indicator z = x - 0.5; `crossings`
 * (a discrete output) counts how often z changed sign; `label`, a tunable String parameter, says what it
 * is. Co-Simulation (without Event Mode) steps
 * with the exact solution; Model Exchange leaves the integration to the importer. Every call
 * checks the FMI 3.0.2 state machine (each state's "Allowed Function Calls", sections 2.3, 3.2,
 * 4.2), its value references and its pointer arguments (NULL refused); a refused call returns fmi3Error.
 * It can get, set and serialize its FMU state. All 75 functions of fmi3Functions.h are exported; those
 * for capabilities it lacks return fmi3Error.
 *
 * The faults:
 *   FAULT_NO_EXPORT  fmi3GetClock is not exported
 *   FAULT_ILLEGAL    fmi3UpdateDiscreteStates is accepted in every state
 *   FAULT_SET_FIXED  fmi3SetFloat64 sets the fixed parameter k after initialization
 *   FAULT_RESET      fmi3Reset leaves the crossings counter of the run before
 *   FAULT_NAN        x becomes NaN from t = 1 on (Co-Simulation) / x' is NaN (Model Exchange)
 *   FAULT_SIZES      fmi3GetNumberOfContinuousStates reports 2 states, the description 1
 *   FAULT_STATE      fmi3SetFMUState brings back the start values, not the state it is given
 *   FAULT_NULL_VR    fmi3GetFloat64 does not check its arrays for NULL (and crashes on them)
 *   FAULT_STRING_NULL fmi3GetString returns fmi3OK with a NULL pointer for `label` */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))

typedef void *fmi3Instance;
typedef void *fmi3InstanceEnvironment;
typedef void *fmi3FMUState;
typedef uint32_t fmi3ValueReference;
typedef double fmi3Float64;
typedef float fmi3Float32;
typedef bool fmi3Boolean;
typedef const char *fmi3String;
typedef uint8_t fmi3Byte;
typedef const fmi3Byte *fmi3Binary;
typedef bool fmi3Clock;
typedef enum { fmi3OK, fmi3Warning, fmi3Discard, fmi3Error, fmi3Fatal } fmi3Status;
typedef void (*fmi3LogMessageCallback)(fmi3InstanceEnvironment, fmi3Status, fmi3String, fmi3String);
typedef void (*fmi3IntermediateUpdateCallback)(fmi3InstanceEnvironment, fmi3Float64, fmi3Boolean, fmi3Boolean, fmi3Boolean,
                                               fmi3Boolean, fmi3Boolean *, fmi3Float64 *);
typedef void (*fmi3ClockUpdateCallback)(fmi3InstanceEnvironment);
typedef void (*fmi3LockPreemptionCallback)(void);
typedef void (*fmi3UnlockPreemptionCallback)(void);

#define TOKEN "{7d1c2f40-5b8e-4c3a-9f61-0e2d4b6a8c13}"

enum { VR_TIME = 0, VR_X = 1, VR_DER_X = 2, VR_K = 3, VR_CROSSINGS = 4, VR_Z = 5, VR_LABEL = 6 };

/* The longest label (with its NUL) the FMU keeps; a longer one is refused. */
#define LABEL_SIZE 128
#define LABEL_START "exponential decay"

typedef enum {
    Instantiated = 1 << 0,
    InitializationMode = 1 << 1,
    EventMode = 1 << 2,
    ContinuousTimeMode = 1 << 3,
    StepMode = 1 << 4,
    Terminated = 1 << 5,
} State;

#define ANY (Instantiated | InitializationMode | EventMode | ContinuousTimeMode | StepMode | Terminated)
#define INITIALIZED (EventMode | ContinuousTimeMode | StepMode)

typedef struct {
    char *name;
    bool me;
    State state;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    double time, x, k, crossings;
    bool below; /* z <= 0 at the last event */
    char label[LABEL_SIZE];
} Model;

/* An FMU state: everything of the instance but its name and callbacks. */
typedef struct {
    State state;
    double time, x, k, crossings;
    bool below;
    char label[LABEL_SIZE];
} Snapshot;

static void say(Model *m, fmi3Status status, const char *text) {
    if (m->log) m->log(m->env, status, status == fmi3OK ? "logEvents" : "logStatusError", text);
}

/* The state machine: `call` is allowed in `mask` (and for `me_only`/`cs_only`, in that interface). */
static bool allowed(Model *m, int mask, const char *call) {
    if (!m) return false;
    if (m->state & mask) return true;
    char text[200];
    snprintf(text, sizeof text, "%s is not allowed in this state", call);
    say(m, fmi3Error, text);
    return false;
}

/* A get or set of values: allowed in `mask`, its arrays not NULL where nvr > 0, one value a reference. */
static bool values_call(Model *m, int mask, const char *call, const void *vr, const void *values, size_t nvr, size_t n) {
    if (!allowed(m, mask, call)) return false;
    if ((nvr > 0 && (!vr || !values)) || n != nvr) {
        say(m, fmi3Error, "NULL arrays, or not one value a value reference");
        return false;
    }
    return true;
}

#define ME_ONLY(m, call) \
    if (!(m)) return fmi3Error; \
    if (!(m)->me) { say((m), fmi3Error, call " is a Model Exchange function"); return fmi3Error; }
#define CS_ONLY(m, call) \
    if (!(m)) return fmi3Error; \
    if ((m)->me) { say((m), fmi3Error, call " is a Co-Simulation function"); return fmi3Error; }

static double der_x(Model *m) {
#ifdef FAULT_NAN
    return NAN;
#endif
    return -m->k * m->x;
}

static void start_values(Model *m) {
    m->time = 0;
    m->x = 1;
    m->k = 1;
#ifndef FAULT_RESET
    m->crossings = 0;
#endif
    m->below = false;
    strcpy(m->label, LABEL_START);
}

static fmi3Instance instantiate(fmi3String name, fmi3String token, bool me, fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    if (!name || !token || strcmp(token, TOKEN) != 0) {
        if (log) log(env, fmi3Error, "logStatusError", "the instantiationToken does not fit this binary");
        return NULL;
    }
    Model *m = calloc(1, sizeof(Model));
    if (!m) return NULL;
    m->name = strdup(name);
    m->me = me;
    m->env = env;
    m->log = log;
    m->state = Instantiated;
    m->crossings = 0;
    start_values(m);
    return m;
}

EXPORT const char *fmi3GetVersion(void) { return "3.0"; }

EXPORT fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean on, size_t n, const fmi3String categories[]) {
    (void)on; (void)n; (void)categories;
    return instance ? fmi3OK : fmi3Error;
}

EXPORT fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
                                                 fmi3Boolean logging, fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    (void)resources; (void)visible; (void)logging;
    return instantiate(name, token, true, env, log);
}

EXPORT fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
                                                fmi3Boolean logging, fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                                const fmi3ValueReference required[], size_t nRequired,
                                                fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                                fmi3IntermediateUpdateCallback update) {
    (void)resources; (void)visible; (void)logging; (void)earlyReturnAllowed; (void)required; (void)nRequired; (void)update;
    if (eventModeUsed) {
        if (log) log(env, fmi3Error, "logStatusError", "this FMU has no Event Mode (hasEventMode is false)");
        return NULL;
    }
    return instantiate(name, token, false, env, log);
}

EXPORT fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
                                                      fmi3Boolean logging, fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                                      fmi3ClockUpdateCallback clock, fmi3LockPreemptionCallback lock,
                                                      fmi3UnlockPreemptionCallback unlock) {
    (void)name; (void)token; (void)resources; (void)visible; (void)logging; (void)clock; (void)lock; (void)unlock;
    if (log) log(env, fmi3Error, "logStatusError", "Scheduled Execution is not supported");
    return NULL;
}

EXPORT void fmi3FreeInstance(fmi3Instance instance) {
    Model *m = instance;
    if (!m) return;
    free(m->name);
    free(m);
}

EXPORT fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                              fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Model *m = instance;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (!allowed(m, Instantiated, "fmi3EnterInitializationMode")) return fmi3Error;
    m->time = startTime;
    m->state = InitializationMode;
    return fmi3OK;
}

EXPORT fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Model *m = instance;
    if (!allowed(m, InitializationMode, "fmi3ExitInitializationMode")) return fmi3Error;
    m->below = m->x - 0.5 <= 0;
    m->state = m->me ? EventMode : StepMode;
    return fmi3OK;
}

EXPORT fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    Model *m = instance;
    ME_ONLY(m, "fmi3EnterEventMode (without Event Mode in Co-Simulation)");
    if (!allowed(m, ContinuousTimeMode, "fmi3EnterEventMode")) return fmi3Error;
    m->state = EventMode;
    return fmi3OK;
}

EXPORT fmi3Status fmi3Terminate(fmi3Instance instance) {
    Model *m = instance;
    if (!allowed(m, INITIALIZED, "fmi3Terminate")) return fmi3Error;
    m->state = Terminated;
    return fmi3OK;
}

EXPORT fmi3Status fmi3Reset(fmi3Instance instance) {
    Model *m = instance;
    if (!allowed(m, ANY, "fmi3Reset")) return fmi3Error;
    start_values(m);
    m->state = Instantiated;
    return fmi3OK;
}

/* Float64: every variable; the others have no variables of their type. */
EXPORT fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[], size_t n) {
    Model *m = instance;
#ifdef FAULT_NULL_VR
    if (!allowed(m, ANY, "fmi3GetFloat64") || n != nvr) return fmi3Error;
#else
    if (!values_call(m, ANY, "fmi3GetFloat64", vr, values, nvr, n)) return fmi3Error;
#endif
    for (size_t i = 0; i < nvr; i++) {
        switch (vr[i]) {
        case VR_TIME: values[i] = m->time; break;
        case VR_X: values[i] = m->x; break;
        case VR_DER_X: values[i] = der_x(m); break;
        case VR_K: values[i] = m->k; break;
        case VR_CROSSINGS: values[i] = m->crossings; break;
        case VR_Z: values[i] = m->x - 0.5; break;
        default: say(m, fmi3Error, "unknown value reference"); return fmi3Error;
        }
    }
    return fmi3OK;
}

EXPORT fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 values[], size_t n) {
    Model *m = instance;
    if (!values_call(m, ANY & ~Terminated, "fmi3SetFloat64", vr, values, nvr, n)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        bool before = m->state & (Instantiated | InitializationMode);
        switch (vr[i]) {
        case VR_X:
            /* initial="exact": before initialization; a state: in Continuous-Time Mode (ME). */
            if (!(before || (m->me && m->state == ContinuousTimeMode))) goto refused;
            m->x = values[i];
            break;
        case VR_K:
#ifndef FAULT_SET_FIXED
            if (!before) goto refused;
#endif
            m->k = values[i];
            break;
        default:
            goto refused;
        }
    }
    return fmi3OK;
refused:
    say(m, fmi3Error, "this variable cannot be set in this state");
    return fmi3Error;
}

#define NO_VARIABLES_GET(Name, T)                                                                                         \
    EXPORT fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, T values[], size_t n) { \
        (void)vr; (void)values; (void)n;                                                                                  \
        if (!allowed(instance, ANY, "fmi3Get" #Name)) return fmi3Error;                                                   \
        return nvr == 0 ? fmi3OK : fmi3Error;                                                                             \
    }
#define NO_VARIABLES_SET(Name, T)                                                                                                \
    EXPORT fmi3Status fmi3Set##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const T values[], size_t n) { \
        (void)vr; (void)values; (void)n;                                                                                         \
        if (!allowed(instance, ANY & ~Terminated, "fmi3Set" #Name)) return fmi3Error;                                            \
        return nvr == 0 ? fmi3OK : fmi3Error;                                                                                    \
    }
#define NO_VARIABLES(Name, T) NO_VARIABLES_GET(Name, T) NO_VARIABLES_SET(Name, T)

NO_VARIABLES(Float32, fmi3Float32)
NO_VARIABLES(Int8, int8_t)
NO_VARIABLES(UInt8, uint8_t)
NO_VARIABLES(Int16, int16_t)
NO_VARIABLES(UInt16, uint16_t)
NO_VARIABLES(Int32, int32_t)
NO_VARIABLES(UInt32, uint32_t)
NO_VARIABLES(Int64, int64_t)
NO_VARIABLES(UInt64, uint64_t)
NO_VARIABLES(Boolean, fmi3Boolean)

/* String: `label` alone. The returned pointer is the instance's copy, valid until the label changes. */
EXPORT fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3String values[], size_t n) {
    Model *m = instance;
    if (!values_call(m, ANY, "fmi3GetString", vr, values, nvr, n)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_LABEL) {
            say(m, fmi3Error, "unknown String value reference");
            return fmi3Error;
        }
#ifdef FAULT_STRING_NULL
        values[i] = NULL;
#else
        values[i] = m->label;
#endif
    }
    return fmi3OK;
}

EXPORT fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3String values[], size_t n) {
    Model *m = instance;
    if (!values_call(m, ANY & ~Terminated, "fmi3SetString", vr, values, nvr, n)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_LABEL || !values[i] || strlen(values[i]) >= LABEL_SIZE) {
            say(m, fmi3Error, "not a String variable, or a NULL or too long text");
            return fmi3Error;
        }
    }
    /* Copied: the caller's texts are the caller's. */
    for (size_t i = 0; i < nvr; i++) strcpy(m->label, values[i]);
    return fmi3OK;
}

EXPORT fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t sizes[], fmi3Binary values[], size_t n) {
    (void)vr; (void)sizes; (void)values; (void)n;
    if (!allowed(instance, ANY, "fmi3GetBinary")) return fmi3Error;
    return nvr == 0 ? fmi3OK : fmi3Error;
}

EXPORT fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t sizes[],
                                const fmi3Binary values[], size_t n) {
    (void)vr; (void)sizes; (void)values; (void)n;
    if (!allowed(instance, ANY & ~Terminated, "fmi3SetBinary")) return fmi3Error;
    return nvr == 0 ? fmi3OK : fmi3Error;
}

/* What this FMU does not offer (clocks, derivatives, configuration): fmi3Error. */
#define UNSUPPORTED(call)                                               \
    do {                                                                \
        if (instance) say(instance, fmi3Error, call " is not supported"); \
        return fmi3Error;                                               \
    } while (0)

#ifndef FAULT_NO_EXPORT
EXPORT fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    (void)vr; (void)nvr; (void)values;
    UNSUPPORTED("fmi3GetClock");
}
#endif
EXPORT fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    (void)vr; (void)nvr; (void)values;
    UNSUPPORTED("fmi3SetClock");
}
EXPORT fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr, size_t *n) {
    (void)vr; (void)n;
    UNSUPPORTED("fmi3GetNumberOfVariableDependencies");
}
EXPORT fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent, size_t elements[],
                                              fmi3ValueReference independents[], size_t independentElements[], int kinds[], size_t n) {
    (void)dependent; (void)elements; (void)independents; (void)independentElements; (void)kinds; (void)n;
    UNSUPPORTED("fmi3GetVariableDependencies");
}

/* FMU state: a Snapshot on the heap; serialized, its bytes. COPY_STATE copies what a Snapshot
 * holds from a Model to a Snapshot or back. */
#define COPY_STATE(to, from)                                 \
    do {                                                     \
        (to)->state = (from)->state;                         \
        (to)->time = (from)->time;                           \
        (to)->x = (from)->x;                                 \
        (to)->k = (from)->k;                                 \
        (to)->crossings = (from)->crossings;                 \
        (to)->below = (from)->below;                         \
        memcpy((to)->label, (from)->label, LABEL_SIZE);      \
    } while (0)

static void save(const Model *m, Snapshot *s) { COPY_STATE(s, m); }

static void restore(Model *m, const Snapshot *s) {
#ifdef FAULT_STATE
    start_values(m);
    m->crossings = 0;
    m->state = s->state;
#else
    COPY_STATE(m, s);
#endif
}

EXPORT fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *state) {
    Model *m = instance;
    if (!allowed(m, ANY, "fmi3GetFMUState")) return fmi3Error;
    if (!state) return fmi3Error;
    if (!*state) *state = malloc(sizeof(Snapshot));
    if (!*state) return fmi3Error;
    save(m, *state);
    return fmi3OK;
}
EXPORT fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState state) {
    Model *m = instance;
    if (!allowed(m, ANY, "fmi3SetFMUState")) return fmi3Error;
    if (!state) return fmi3Error;
    restore(m, state);
    return fmi3OK;
}
EXPORT fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *state) {
    if (!allowed(instance, ANY, "fmi3FreeFMUState")) return fmi3Error;
    if (!state) return fmi3Error;
    free(*state);
    *state = NULL;
    return fmi3OK;
}
EXPORT fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState state, size_t *size) {
    if (!allowed(instance, ANY, "fmi3SerializedFMUStateSize")) return fmi3Error;
    if (!state || !size) return fmi3Error;
    *size = sizeof(Snapshot);
    return fmi3OK;
}
EXPORT fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState state, fmi3Byte bytes[], size_t size) {
    if (!allowed(instance, ANY, "fmi3SerializeFMUState")) return fmi3Error;
    if (!state || !bytes || size != sizeof(Snapshot)) return fmi3Error;
    memcpy(bytes, state, sizeof(Snapshot));
    return fmi3OK;
}
EXPORT fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte bytes[], size_t size, fmi3FMUState *state) {
    if (!allowed(instance, ANY, "fmi3DeserializeFMUState")) return fmi3Error;
    if (!bytes || !state || size != sizeof(Snapshot)) return fmi3Error;
    Snapshot *s = malloc(sizeof(Snapshot));
    if (!s) return fmi3Error;
    memcpy(s, bytes, sizeof(Snapshot));
    *state = s;
    return fmi3OK;
}
EXPORT fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference u[], size_t nu, const fmi3ValueReference k[],
                                               size_t nk, const fmi3Float64 seed[], size_t ns, fmi3Float64 s[], size_t n) {
    (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)s; (void)n;
    UNSUPPORTED("fmi3GetDirectionalDerivative");
}
EXPORT fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference u[], size_t nu, const fmi3ValueReference k[],
                                           size_t nk, const fmi3Float64 seed[], size_t ns, fmi3Float64 s[], size_t n) {
    (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)s; (void)n;
    UNSUPPORTED("fmi3GetAdjointDerivative");
}
EXPORT fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { UNSUPPORTED("fmi3EnterConfigurationMode (no structural parameters)"); }
EXPORT fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { UNSUPPORTED("fmi3ExitConfigurationMode"); }
EXPORT fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Float64 i[], int q[]) {
    (void)vr; (void)n; (void)i; (void)q;
    UNSUPPORTED("fmi3GetIntervalDecimal");
}
EXPORT fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, uint64_t c[], uint64_t r[], int q[]) {
    (void)vr; (void)n; (void)c; (void)r; (void)q;
    UNSUPPORTED("fmi3GetIntervalFraction");
}
EXPORT fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Float64 s[]) {
    (void)vr; (void)n; (void)s;
    UNSUPPORTED("fmi3GetShiftDecimal");
}
EXPORT fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, uint64_t c[], uint64_t r[]) {
    (void)vr; (void)n; (void)c; (void)r;
    UNSUPPORTED("fmi3GetShiftFraction");
}
EXPORT fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Float64 i[]) {
    (void)vr; (void)n; (void)i;
    UNSUPPORTED("fmi3SetIntervalDecimal");
}
EXPORT fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const uint64_t c[], const uint64_t r[]) {
    (void)vr; (void)n; (void)c; (void)r;
    UNSUPPORTED("fmi3SetIntervalFraction");
}
EXPORT fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Float64 s[]) {
    (void)vr; (void)n; (void)s;
    UNSUPPORTED("fmi3SetShiftDecimal");
}
EXPORT fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const uint64_t c[], const uint64_t r[]) {
    (void)vr; (void)n; (void)c; (void)r;
    UNSUPPORTED("fmi3SetShiftFraction");
}
EXPORT fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { UNSUPPORTED("fmi3EvaluateDiscreteStates"); }

/* The discrete update: a crossing of z = x - 0.5 since the last event is counted. */
EXPORT fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *again, fmi3Boolean *terminate, fmi3Boolean *nominals,
                                           fmi3Boolean *values, fmi3Boolean *nextDefined, fmi3Float64 *next) {
    Model *m = instance;
#ifdef FAULT_ILLEGAL
    if (!allowed(m, ANY, "fmi3UpdateDiscreteStates")) return fmi3Error;
#else
    if (!allowed(m, EventMode, "fmi3UpdateDiscreteStates")) return fmi3Error;
#endif
    if (!again || !terminate || !nominals || !values || !nextDefined || !next) return fmi3Error;
    bool below = m->x - 0.5 <= 0;
    if (below != m->below) {
        m->crossings += 1;
        m->below = below;
    }
    *again = false;
    *terminate = false;
    *nominals = false;
    *values = false;
    *nextDefined = false;
    *next = 0;
    return fmi3OK;
}

EXPORT fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    Model *m = instance;
    ME_ONLY(m, "fmi3EnterContinuousTimeMode");
    if (!allowed(m, EventMode, "fmi3EnterContinuousTimeMode")) return fmi3Error;
    m->state = ContinuousTimeMode;
    return fmi3OK;
}

EXPORT fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *enterEventMode,
                                              fmi3Boolean *terminateSimulation) {
    Model *m = instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    ME_ONLY(m, "fmi3CompletedIntegratorStep");
    if (!allowed(m, ContinuousTimeMode, "fmi3CompletedIntegratorStep")) return fmi3Error;
    if (!enterEventMode || !terminateSimulation) return fmi3Error;
    *enterEventMode = false;
    *terminateSimulation = false;
    return fmi3OK;
}

EXPORT fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    Model *m = instance;
    ME_ONLY(m, "fmi3SetTime");
    if (!allowed(m, ContinuousTimeMode, "fmi3SetTime")) return fmi3Error;
    m->time = time;
    return fmi3OK;
}

EXPORT fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t n) {
    Model *m = instance;
    ME_ONLY(m, "fmi3SetContinuousStates");
    if (!allowed(m, ContinuousTimeMode, "fmi3SetContinuousStates")) return fmi3Error;
    if (n != 1 || !x) return fmi3Error;
    m->x = x[0];
    return fmi3OK;
}

#define ME_READABLE (InitializationMode | EventMode | ContinuousTimeMode | Terminated)

EXPORT fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 dx[], size_t n) {
    Model *m = instance;
    ME_ONLY(m, "fmi3GetContinuousStateDerivatives");
    if (!allowed(m, ME_READABLE, "fmi3GetContinuousStateDerivatives")) return fmi3Error;
    if (n != 1 || !dx) return fmi3Error;
    dx[0] = der_x(m);
    return fmi3OK;
}

EXPORT fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 z[], size_t n) {
    Model *m = instance;
    ME_ONLY(m, "fmi3GetEventIndicators");
    if (!allowed(m, ME_READABLE, "fmi3GetEventIndicators")) return fmi3Error;
    if (n != 1 || !z) return fmi3Error;
    z[0] = m->x - 0.5;
    return fmi3OK;
}

EXPORT fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    Model *m = instance;
    ME_ONLY(m, "fmi3GetContinuousStates");
    if (!allowed(m, ME_READABLE, "fmi3GetContinuousStates")) return fmi3Error;
    if (n != 1 || !x) return fmi3Error;
    x[0] = m->x;
    return fmi3OK;
}

EXPORT fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t n) {
    Model *m = instance;
    ME_ONLY(m, "fmi3GetNominalsOfContinuousStates");
    if (!allowed(m, ME_READABLE, "fmi3GetNominalsOfContinuousStates")) return fmi3Error;
    if (n != 1 || !nominals) return fmi3Error;
    nominals[0] = 1;
    return fmi3OK;
}

EXPORT fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n) {
    Model *m = instance;
    ME_ONLY(m, "fmi3GetNumberOfEventIndicators");
    if (!allowed(m, ANY, "fmi3GetNumberOfEventIndicators") || !n) return fmi3Error;
    *n = 1;
    return fmi3OK;
}

EXPORT fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n) {
    Model *m = instance;
    ME_ONLY(m, "fmi3GetNumberOfContinuousStates");
    if (!allowed(m, ANY, "fmi3GetNumberOfContinuousStates") || !n) return fmi3Error;
#ifdef FAULT_SIZES
    *n = 2;
#else
    *n = 1;
#endif
    return fmi3OK;
}

EXPORT fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    Model *m = instance;
    CS_ONLY(m, "fmi3EnterStepMode");
    /* Only from Event Mode, which this FMU does not have. */
    if (!allowed(m, 0, "fmi3EnterStepMode")) return fmi3Error;
    return fmi3OK;
}

EXPORT fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const int32_t orders[],
                                           fmi3Float64 values[], size_t n) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)n;
    UNSUPPORTED("fmi3GetOutputDerivatives");
}

/* The exact solution over the step, the crossings counted at its end. */
EXPORT fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                             fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                             fmi3Float64 *lastSuccessfulTime) {
    Model *m = instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    CS_ONLY(m, "fmi3DoStep");
    if (!allowed(m, StepMode, "fmi3DoStep")) return fmi3Error;
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime || !(h > 0)) return fmi3Error;
    m->x *= exp(-m->k * h);
#ifdef FAULT_NAN
    if (t + h >= 1) m->x = NAN;
#endif
    m->time = t + h;
    bool below = m->x - 0.5 <= 0;
    if (below != m->below) {
        m->crossings += 1;
        m->below = below;
    }
    *eventHandlingNeeded = false;
    *terminateSimulation = false;
    *earlyReturn = false;
    *lastSuccessfulTime = m->time;
    return fmi3OK;
}

EXPORT fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clock, fmi3Float64 time) {
    (void)clock; (void)time;
    UNSUPPORTED("fmi3ActivateModelPartition");
}
