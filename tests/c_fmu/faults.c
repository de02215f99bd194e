/* A correct FMI 2.0 FMU (Co-Simulation and Model Exchange) written as a careful third-party tool
 * would, for the tests of `runner validate`: built as it is, validate must find nothing wrong;
 * built with one -DFAULT_... flag, it has exactly that fault and validate must name it.
 *
 * The model: x' = -k x + u, x(0) = x0, with the event indicator z = x - threshold; `below`
 * (z <= 0) and `crossings` (how often z changed domain) are discrete outputs. Co-Simulation
 * steps with the exact solution; Model Exchange leaves the integration to the importer. Every
 * call checks the state machine of FMI 2.0 (sections 3.2.3 and 4.2.4), its pointers and value
 * references, and a refused call changes nothing and puts the instance in the Error state.
 *
 * The faults:
 *   FAULT_CRASH_EARLY  fmi2Instantiate dereferences NULL
 *   FAULT_HANG         fmi2DoStep never returns
 *   FAULT_NO_EXPORT    fmi2GetRealStatus is not exported
 *   FAULT_WRONG_GUID   the binary expects another GUID than modelDescription.xml gives
 *   FAULT_ANY_GUID     fmi2Instantiate accepts any GUID
 *   FAULT_ROLLBACK     fmi2SetFMUstate returns fmi2OK but restores nothing
 *   FAULT_ILLEGAL      fmi2SetReal sets the fixed parameters k and x0 after initialization
 *   FAULT_NAN          x becomes NaN from t = 1 on
 *   FAULT_EVENT_LOOP   fmi2NewDiscreteStates always asks for another iteration
 *   FAULT_NO_EVENTS    fmi2EnterEventMode refuses to leave Continuous-Time Mode (a state event
 *                      cannot be handled)
 *   FAULT_EXIT         fmi2Terminate ends the process with exit(3)
 *   FAULT_NULL_COMPONENT  fmi2EnterInitializationMode reads through its component before
 *                      checking it for NULL
 *   FAULT_NULL_VR      fmi2GetReal reads its first value reference before checking the array
 *   FAULT_NULL_STATE   fmi2GetFMUstate writes through its FMUstate pointer unchecked
 *   FAULT_NULL_OUTPUT  fmi2GetDerivatives writes into its output array unchecked
 *   FAULT_STRING_COPY  fmi2SetString keeps the caller's pointer instead of a copy, and
 *                      fmi2GetString hands that pointer back
 *   FAULT_STRING_NULL_ELEMENT  fmi2SetString takes the length of its values unchecked (NULL)
 * and two variants that are not faults: NOISY, every fmi2DoStep prints to stdout and stderr, as
 * some FMUs do; FORKS, the first fmi2Instantiate of a process starts a helper process that
 * outlives it (holding every descriptor it inherited), as FMUs that talk to a tool server do. */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef struct {
    fmi2CallbackLogger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;
typedef struct {
    fmi2Boolean newDiscreteStatesNeeded;
    fmi2Boolean terminateSimulation;
    fmi2Boolean nominalsOfContinuousStatesChanged;
    fmi2Boolean valuesOfContinuousStatesChanged;
    fmi2Boolean nextEventTimeDefined;
    fmi2Real nextEventTime;
} fmi2EventInfo;

#define EXPORT __attribute__((visibility("default")))
#ifdef FAULT_WRONG_GUID
#define GUID "{5a0b6c1e-2f47-4d8e-9b3a-71c2d4e6f802}"
#else
#define GUID "{5a0b6c1e-2f47-4d8e-9b3a-71c2d4e6f801}"
#endif

/* Value references, one space per base type. */
enum { VR_TIME, VR_X, VR_DER_X, VR_K, VR_X0, VR_THRESHOLD, VR_U, VR_TAU, VR_LN2, N_REALS };
enum { VR_CROSSINGS };
enum { VR_BELOW };
enum { VR_LABEL };

/* States, as bits so that a function's allowed states are one mask. */
enum {
    INSTANTIATED = 1, INIT = 2, STEP_COMPLETE = 4, STEP_FAILED = 8, EVENT = 16, CONTINUOUS = 32, TERMINATED = 64, ERROR = 128
};
#define LIVE (INSTANTIATED | INIT | STEP_COMPLETE | STEP_FAILED | EVENT | CONTINUOUS | TERMINATED | ERROR)
#define READABLE_CS (INIT | STEP_COMPLETE | STEP_FAILED | TERMINATED | ERROR)
#define READABLE_ME (INIT | EVENT | CONTINUOUS | TERMINATED | ERROR)

/* Everything an FMU state holds. */
typedef struct {
    int state;
    /* Initialization Mode has been left: x holds the state (else x0 stands for it). */
    int initialized;
    double time, stop;
    int stop_defined;
    double k, x0, threshold, u, x;
    int crossings, below;
    char label[64];
} Values;

typedef struct {
    fmi2CallbackFunctions cb;
    char *name;
    int type;
    Values v;
#ifdef FAULT_STRING_COPY
    const char *label_pointer;
#endif
} Instance;

static const char *state_name(int s) {
    switch (s) {
    case INSTANTIATED: return "Instantiated";
    case INIT: return "InitializationMode";
    case STEP_COMPLETE: return "StepComplete";
    case STEP_FAILED: return "StepFailed";
    case EVENT: return "EventMode";
    case CONTINUOUS: return "ContinuousTimeMode";
    case TERMINATED: return "Terminated";
    default: return "Error";
    }
}

static void logv(Instance *inst, fmi2Status status, const char *fmt, va_list args) {
    char text[512];
    vsnprintf(text, sizeof text, fmt, args);
    if (inst->cb.logger) inst->cb.logger(inst->cb.componentEnvironment, inst->name, status, "logStatusError", "%s", text);
}

/* Logs why a call is refused, moves the instance to the Error state, returns fmi2Error. */
static fmi2Status fail(Instance *inst, const char *fmt, ...) {
    va_list args;
    va_start(args, fmt);
    logv(inst, fmi2Error, fmt, args);
    va_end(args);
    inst->v.state = ERROR;
    return fmi2Error;
}

/* The instance behind c if `fn` is allowed in its state (cs for Co-Simulation, me for Model
 * Exchange instances); NULL (after logging) otherwise. */
static Instance *enter(fmi2Component c, int cs, int me, const char *fn) {
    Instance *inst = (Instance *)c;
    if (!inst) return NULL;
    int mask = inst->type == fmi2CoSimulation ? cs : me;
    if (!(inst->v.state & mask)) {
        fail(inst, "%s is not allowed in state %s", fn, state_name(inst->v.state));
        return NULL;
    }
    return inst;
}

#define ENTER(cs, me) \
    Instance *inst = enter(c, cs, me, __func__); \
    if (!inst) return fmi2Error

static double derivative(const Values *v) { return -v->k * v->x + v->u; }

/* x after Initialization Mode; before it, what initialization will compute. */
static double state_now(const Values *v) { return v->initialized ? v->x : v->x0; }

/* The domain of the event indicator z = x - threshold: 1 for z <= 0. */
static int below_of(const Values *v) { return state_now(v) - v->threshold <= 0; }

static double real_value(const Values *v, fmi2ValueReference vr) {
    Values now = *v;
    now.x = state_now(v);
    switch (vr) {
    case VR_TIME: return v->time;
    case VR_X: return now.x;
    case VR_DER_X: return derivative(&now);
    case VR_K: return v->k;
    case VR_X0: return v->x0;
    case VR_THRESHOLD: return v->threshold;
    case VR_U: return v->u;
    case VR_TAU: return 1.0 / v->k;
    default: return 0.6931471805599453; /* VR_LN2 */
    }
}

/* Whether the Real `vr` may be set now, per the table's conditions 1, 3, 4, 5 and 6. */
static int real_settable(const Instance *inst, fmi2ValueReference vr) {
    int s = inst->v.state, cs = inst->type == fmi2CoSimulation;
    switch (vr) {
    case VR_K:
    case VR_X0:
#ifdef FAULT_ILLEGAL
        return s & (INSTANTIATED | INIT | STEP_COMPLETE | EVENT);
#else
        return s & (INSTANTIATED | INIT);
#endif
    case VR_THRESHOLD: return s & (INSTANTIATED | INIT | (cs ? STEP_COMPLETE : EVENT));
    case VR_U: return s & (INSTANTIATED | INIT | (cs ? STEP_COMPLETE : EVENT | CONTINUOUS));
    case VR_X: return !cs && (s & CONTINUOUS); /* a continuous state, condition 5 */
    default: return 0;
    }
}

static void *allocate(Instance *inst, size_t n) { return inst->cb.allocateMemory(1, n); }

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[]) {
    ENTER(LIVE, LIVE);
    (void)on;
    if (n > 0 && !categories) return fail(inst, "fmi2SetDebugLogging: categories is NULL but n = %zu", n);
    return fmi2OK;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging_on) {
    (void)resources; (void)visible; (void)logging_on;
#ifdef FAULT_CRASH_EARLY
    volatile int *nowhere = NULL;
    *nowhere = 1;
#endif
#ifdef FORKS
    static int helper_started = 0;
    if (!helper_started) {
        helper_started = 1;
        if (fork() == 0) {
            sleep(120);
            _exit(0);
        }
    }
#endif
    if (!cb || !cb->allocateMemory || !cb->freeMemory || !name || !name[0]) return NULL;
    Instance *inst = cb->allocateMemory(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->cb = *cb;
    inst->name = cb->allocateMemory(strlen(name) + 1, 1);
    if (!inst->name) { cb->freeMemory(inst); return NULL; }
    strcpy(inst->name, name);
    int known_type = type == fmi2CoSimulation || type == fmi2ModelExchange;
#ifdef FAULT_ANY_GUID
    int guid_ok = 1;
#else
    int guid_ok = guid && strcmp(guid, GUID) == 0;
#endif
    if (!known_type || !guid_ok) {
        fail(inst, "fmi2Instantiate: fmuType %d or GUID %s does not fit this binary (GUID %s)", (int)type, guid ? guid : "(NULL)", GUID);
        cb->freeMemory(inst->name);
        cb->freeMemory(inst);
        return NULL;
    }
    inst->type = type;
    inst->v.state = INSTANTIATED;
    inst->v.k = 1.0;
    inst->v.x0 = 1.0;
    inst->v.threshold = 0.5;
    strcpy(inst->v.label, "faults");
    return inst;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!inst) return;
    void (*release)(void *) = inst->cb.freeMemory;
    release(inst->name);
    release(inst);
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol, fmi2Real start,
                                      fmi2Boolean stop_defined, fmi2Real stop) {
    ENTER(INSTANTIATED, INSTANTIATED);
    (void)tol_defined; (void)tol;
    if (stop_defined && !(stop > start)) return fail(inst, "fmi2SetupExperiment: stop time %g is not after start time %g", stop, start);
    inst->v.time = start;
    inst->v.stop = stop;
    inst->v.stop_defined = stop_defined;
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
#ifdef FAULT_NULL_COMPONENT
    if (((Instance *)c)->v.state == ERROR) return fmi2Error;
#endif
    ENTER(INSTANTIATED, INSTANTIATED);
    inst->v.state = INIT;
    return fmi2OK;
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    ENTER(INIT, INIT);
    if (!(inst->v.k > 0)) return fail(inst, "k = %g must be positive", inst->v.k);
    inst->v.below = below_of(&inst->v);
    inst->v.x = inst->v.x0;
    inst->v.initialized = 1;
    inst->v.crossings = 0;
    inst->v.state = inst->type == fmi2CoSimulation ? STEP_COMPLETE : EVENT;
    return fmi2OK;
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    ENTER(STEP_COMPLETE | STEP_FAILED, EVENT | CONTINUOUS);
#ifdef FAULT_EXIT
    exit(3);
#endif
    inst->v.state = TERMINATED;
    return fmi2OK;
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    ENTER(LIVE, LIVE);
    memset(&inst->v, 0, sizeof inst->v);
    inst->v.state = INSTANTIATED;
    inst->v.k = 1.0;
    inst->v.x0 = 1.0;
    inst->v.threshold = 0.5;
    strcpy(inst->v.label, "faults");
    return fmi2OK;
}

/* The common checks of a get or set: arrays for n > 0, value references below `count`. */
static fmi2Status check_access(Instance *inst, const char *fn, const fmi2ValueReference vr[], size_t n, const void *values,
                               unsigned count) {
    if (n == 0) return fmi2OK;
    if (!vr || !values) return fail(inst, "%s: %s is NULL but n = %zu", fn, vr ? "value" : "vr", n);
    for (size_t i = 0; i < n; i++)
        if (vr[i] >= count) return fail(inst, "%s: no such variable: value reference %u", fn, vr[i]);
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    ENTER(READABLE_CS, READABLE_ME);
#ifdef FAULT_NULL_VR
    if (n > 0 && vr[0] >= N_REALS) return fail(inst, "fmi2GetReal: no such variable: value reference %u", vr[0]);
#endif
    if (check_access(inst, __func__, vr, n, value, N_REALS) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < n; i++) value[i] = real_value(&inst->v, vr[i]);
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
    ENTER(READABLE_CS, READABLE_ME);
    if (check_access(inst, __func__, vr, n, value, 1) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < n; i++) value[i] = inst->v.crossings;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]) {
    ENTER(READABLE_CS, READABLE_ME);
    if (check_access(inst, __func__, vr, n, value, 1) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < n; i++) value[i] = inst->v.initialized ? inst->v.below : below_of(&inst->v);
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    ENTER(READABLE_CS, READABLE_ME);
    if (check_access(inst, __func__, vr, n, value, 1) != fmi2OK) return fmi2Error;
#ifdef FAULT_STRING_COPY
    for (size_t i = 0; i < n; i++) value[i] = inst->label_pointer ? inst->label_pointer : inst->v.label;
#else
    for (size_t i = 0; i < n; i++) value[i] = inst->v.label;
#endif
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    ENTER(INSTANTIATED | INIT | STEP_COMPLETE, INSTANTIATED | INIT | EVENT | CONTINUOUS);
    if (check_access(inst, __func__, vr, n, value, N_REALS) != fmi2OK) return fmi2Error;
    /* All or nothing: every value is checked before any is stored. */
    for (size_t i = 0; i < n; i++) {
        if (!real_settable(inst, vr[i])) return fail(inst, "fmi2SetReal: value reference %u cannot be set in state %s", vr[i], state_name(inst->v.state));
        if (!isfinite(value[i])) return fail(inst, "fmi2SetReal: value reference %u: %g is not finite", vr[i], value[i]);
    }
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
        case VR_K: inst->v.k = value[i]; break;
        case VR_X0: inst->v.x0 = value[i]; break;
        case VR_THRESHOLD: inst->v.threshold = value[i]; break;
        case VR_U: inst->v.u = value[i]; break;
        default: inst->v.x = value[i]; break; /* VR_X, a state in Continuous-Time Mode */
        }
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[]) {
    ENTER(INSTANTIATED | INIT | STEP_COMPLETE, INSTANTIATED | INIT | EVENT);
    if (check_access(inst, __func__, vr, n, value, 1) != fmi2OK) return fmi2Error;
    return n == 0 ? fmi2OK : fail(inst, "fmi2SetInteger: crossings is an output and cannot be set");
}

EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[]) {
    ENTER(INSTANTIATED | INIT | STEP_COMPLETE, INSTANTIATED | INIT | EVENT);
    if (check_access(inst, __func__, vr, n, value, 1) != fmi2OK) return fmi2Error;
    return n == 0 ? fmi2OK : fail(inst, "fmi2SetBoolean: below is an output and cannot be set");
}

EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[]) {
    ENTER(INSTANTIATED | INIT | STEP_COMPLETE, INSTANTIATED | INIT | EVENT);
    if (check_access(inst, __func__, vr, n, value, 1) != fmi2OK) return fmi2Error;
    if (n == 0) return fmi2OK;
    if (!(inst->v.state & (INSTANTIATED | INIT))) return fail(inst, "fmi2SetString: label is fixed after initialization");
    for (size_t i = 0; i < n; i++) {
#ifdef FAULT_STRING_NULL_ELEMENT
        if (strlen(value[i]) >= sizeof inst->v.label) return fail(inst, "fmi2SetString: label must be a string of at most 63 bytes");
#else
        if (!value[i] || strlen(value[i]) >= sizeof inst->v.label) return fail(inst, "fmi2SetString: label must be a string of at most 63 bytes");
#endif
    }
    strcpy(inst->v.label, value[n - 1]);
#ifdef FAULT_STRING_COPY
    inst->label_pointer = value[n - 1];
#endif
    return fmi2OK;
}

/* FMU states: a copy of the values. */
EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    ENTER(LIVE, LIVE);
#ifndef FAULT_NULL_STATE
    if (!s) return fail(inst, "fmi2GetFMUstate: FMUstate is NULL");
#endif
    if (!*s) *s = allocate(inst, sizeof(Values));
    if (!*s) return fail(inst, "fmi2GetFMUstate: out of memory");
    memcpy(*s, &inst->v, sizeof(Values));
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    ENTER(LIVE, LIVE);
    if (!s) return fail(inst, "fmi2SetFMUstate: FMUstate is NULL");
#ifndef FAULT_ROLLBACK
    memcpy(&inst->v, s, sizeof(Values));
#endif
    return fmi2OK;
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    ENTER(LIVE, LIVE);
    if (s && *s) {
        inst->cb.freeMemory(*s);
        *s = NULL;
    }
    return fmi2OK;
}

#define MAGIC "FLTS"
#define SERIALIZED_SIZE (4 + sizeof(Values))

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    ENTER(LIVE, LIVE);
    if (!s || !size) return fail(inst, "fmi2SerializedFMUstateSize: NULL argument");
    *size = SERIALIZED_SIZE;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte bytes[], size_t size) {
    ENTER(LIVE, LIVE);
    if (!s || !bytes) return fail(inst, "fmi2SerializeFMUstate: NULL argument");
    if (size < SERIALIZED_SIZE) return fail(inst, "fmi2SerializeFMUstate: %zu bytes are too few", size);
    memcpy(bytes, MAGIC, 4);
    memcpy(bytes + 4, s, sizeof(Values));
    return fmi2OK;
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *s) {
    ENTER(LIVE, LIVE);
    if (!bytes || !s) return fail(inst, "fmi2DeSerializeFMUstate: NULL argument");
    if (size != SERIALIZED_SIZE || memcmp(bytes, MAGIC, 4) != 0) return fail(inst, "fmi2DeSerializeFMUstate: not a state of this FMU");
    if (!*s) *s = allocate(inst, sizeof(Values));
    if (!*s) return fail(inst, "fmi2DeSerializeFMUstate: out of memory");
    memcpy(*s, bytes + 4, sizeof(Values));
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu, const fmi2ValueReference z[],
                                               size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    ENTER(READABLE_CS, READABLE_ME);
    (void)u; (void)z; (void)dv; (void)dz;
    if (nu == 0 && nz == 0) return fmi2OK;
    return fail(inst, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=\"false\")");
}

/* Co-Simulation. */
EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[],
                                              const fmi2Real value[]) {
    ENTER(INSTANTIATED | INIT | STEP_COMPLETE, 0);
    (void)vr; (void)order; (void)value;
    return n == 0 ? fmi2OK : fail(inst, "fmi2SetRealInputDerivatives: this FMU cannot interpolate inputs");
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[],
                                               fmi2Real value[]) {
    ENTER(STEP_COMPLETE | STEP_FAILED | TERMINATED | ERROR, 0);
    (void)vr; (void)order; (void)value;
    return n == 0 ? fmi2OK : fail(inst, "fmi2GetRealOutputDerivatives: this FMU provides no output derivatives");
}

/* The exact solution over h, and the crossings of the threshold it makes. */
static void advance(Values *v, double h) {
    double rest = v->u / v->k;
    v->x = rest + (v->x - rest) * exp(-v->k * h);
    v->time += h;
#ifdef FAULT_NAN
    if (v->time >= 1.0) v->x = NAN;
#endif
    int below = below_of(v);
    if (below != v->below) {
        v->below = below;
        v->crossings++;
    }
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    ENTER(STEP_COMPLETE, 0);
    (void)no_prior;
#ifdef NOISY
    printf("{\"Done\": null} fmi2DoStep at t = %g\n", t);
    fprintf(stderr, "fmi2DoStep at t = %g\n", t);
#endif
#ifdef FAULT_HANG
    volatile int spin = 1;
    while (spin) {
    }
#endif
    if (fabs(t - inst->v.time) > 1e-9 * fmax(1.0, fabs(t)))
        return fail(inst, "fmi2DoStep: currentCommunicationPoint %.17g is not the FMU's time %.17g", t, inst->v.time);
    if (!(h > 0)) return fail(inst, "fmi2DoStep: communicationStepSize %g must be positive", h);
    if (inst->v.stop_defined && t + h > inst->v.stop + 1e-9 * fmax(1.0, fabs(inst->v.stop)))
        return fail(inst, "fmi2DoStep: the step to %g passes the stop time %g", t + h, inst->v.stop);
    advance(&inst->v, h);
    inst->v.time = t + h;
    return fmi2OK;
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) {
    ENTER(0, 0);
    return fmi2OK;
}

#define STATUS_STATES (STEP_COMPLETE | STEP_FAILED | TERMINATED)

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *value) {
    ENTER(STATUS_STATES, 0);
    (void)k; (void)value;
    return fmi2Discard; /* steps are synchronous: there is never a pending status */
}

#ifndef FAULT_NO_EXPORT
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *value) {
    ENTER(STATUS_STATES, 0);
    if (k != fmi2LastSuccessfulTime) return fmi2Discard;
    if (!value) return fail(inst, "fmi2GetRealStatus: value is NULL");
    *value = inst->v.time;
    return fmi2OK;
}
#endif

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *value) {
    ENTER(STATUS_STATES, 0);
    (void)k; (void)value;
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *value) {
    ENTER(STATUS_STATES, 0);
    if (k != fmi2Terminated) return fmi2Discard;
    if (!value) return fail(inst, "fmi2GetBooleanStatus: value is NULL");
    *value = 0;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *value) {
    ENTER(STATUS_STATES, 0);
    (void)k; (void)value;
    return fmi2Discard;
}

/* Model Exchange. */
EXPORT fmi2Status fmi2EnterEventMode(fmi2Component c) {
#ifdef FAULT_NO_EVENTS
    ENTER(0, EVENT);
#else
    ENTER(0, EVENT | CONTINUOUS);
#endif
    inst->v.state = EVENT;
    return fmi2OK;
}

EXPORT fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    ENTER(0, EVENT);
    if (!info) return fail(inst, "fmi2NewDiscreteStates: eventInfo is NULL");
    int below = below_of(&inst->v);
    if (below != inst->v.below) {
        inst->v.below = below;
        inst->v.crossings++;
    }
#ifdef FAULT_EVENT_LOOP
    info->newDiscreteStatesNeeded = 1;
#else
    info->newDiscreteStatesNeeded = 0;
#endif
    info->terminateSimulation = 0;
    info->nominalsOfContinuousStatesChanged = 0;
    info->valuesOfContinuousStatesChanged = 0;
    info->nextEventTimeDefined = 0;
    info->nextEventTime = 0;
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    ENTER(0, EVENT);
    inst->v.state = CONTINUOUS;
    return fmi2OK;
}

EXPORT fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean no_prior, fmi2Boolean *enter_event, fmi2Boolean *terminate) {
    ENTER(0, CONTINUOUS);
    (void)no_prior;
    if (!enter_event || !terminate) return fail(inst, "fmi2CompletedIntegratorStep: NULL argument");
    *enter_event = 0;
    *terminate = 0;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
    ENTER(0, CONTINUOUS);
    if (!isfinite(t)) return fail(inst, "fmi2SetTime: %g is not finite", t);
    inst->v.time = t;
    return fmi2OK;
}

/* The ME vector functions take exactly nx = 1 (or ni = 1) values. */
static fmi2Status check_vector(Instance *inst, const char *fn, const void *p, size_t n) {
    if (n != 1) return fail(inst, "%s: n = %zu, but this FMU has 1", fn, n);
    if (!p) return fail(inst, "%s: the array is NULL", fn);
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    ENTER(0, CONTINUOUS);
    if (check_vector(inst, __func__, x, nx) != fmi2OK) return fmi2Error;
    if (!isfinite(x[0])) return fail(inst, "fmi2SetContinuousStates: %g is not finite", x[0]);
    inst->v.x = x[0];
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real d[], size_t nx) {
    ENTER(0, READABLE_ME);
#ifndef FAULT_NULL_OUTPUT
    if (check_vector(inst, __func__, d, nx) != fmi2OK) return fmi2Error;
#endif
    Values now = inst->v;
    now.x = state_now(&inst->v);
    d[0] = derivative(&now);
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t ni) {
    ENTER(0, READABLE_ME);
    if (check_vector(inst, __func__, z, ni) != fmi2OK) return fmi2Error;
    z[0] = state_now(&inst->v) - inst->v.threshold;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    ENTER(0, READABLE_ME);
    if (check_vector(inst, __func__, x, nx) != fmi2OK) return fmi2Error;
    x[0] = state_now(&inst->v);
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    ENTER(0, INSTANTIATED | READABLE_ME);
    if (check_vector(inst, __func__, x_nominal, nx) != fmi2OK) return fmi2Error;
    x_nominal[0] = 1.0;
    return fmi2OK;
}
