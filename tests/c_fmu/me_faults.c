/* A Model Exchange FMU written directly against the FMI 2.0 C API, as a third-party tool
 * would, for the importer's bad-input paths: the Dahlquist equation x' = -k x with a time
 * event every `period` seconds that counts in `ticks`, and a fault switched on by the Integer
 * parameter `fault` from time `t_fault` on:
 *   1  fmi2GetDerivatives returns fmi2Error (with a logged reason),
 *   2  fmi2GetDerivatives returns NaN with fmi2OK,
 *   3  the time event's iteration never settles (newDiscreteStatesNeeded stays true),
 *   4  fmi2GetEventIndicators returns NaN (the indicator is x - x_low),
 *   5  fmi2NewDiscreteStates ends the run with terminateSimulation and a logged reason,
 *   6  fmi2GetDerivatives dereferences NULL (a crash, SIGSEGV).
 * It exports the 25 common and the 10 Model Exchange functions of FMI 2.0. The FMI types are
 * declared here so the file needs no headers beyond libc's. */

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

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
#define GUID "{5d1e6c8a-2f0b-4c7e-9a31-me0faults0001}"

enum { VR_X, VR_K, VR_X0, VR_PERIOD, VR_T_FAULT, VR_X_LOW, VR_FAULT, VR_TICKS, VR_DER_X };

typedef struct {
    fmi2CallbackFunctions cb;
    char *name;
    double k, x0, period, t_fault, x_low, x, time, next_tick;
    int fault, ticks;
} Instance;

#define LOG(inst, status, ...) \
    do { if ((inst)->cb.logger) (inst)->cb.logger((inst)->cb.componentEnvironment, (inst)->name, status, "logAll", __VA_ARGS__); } while (0)

static fmi2Status unsupported(fmi2Component c, const char *what) {
    Instance *inst = (Instance *)c;
    if (inst) LOG(inst, fmi2Error, "%s is not supported by this FMU", what);
    return fmi2Error;
}

static int faulty(const Instance *inst, int fault) { return inst->fault == fault && inst->time >= inst->t_fault; }

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }
EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)c; (void)on; (void)n; (void)cats;
    return fmi2OK;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging_on) {
    (void)resources; (void)visible; (void)logging_on;
    if (!cb || !cb->allocateMemory || !name || !name[0]) return NULL;
    Instance *inst = cb->allocateMemory(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->cb = *cb;
    inst->name = cb->allocateMemory(strlen(name) + 1, 1);
    strcpy(inst->name, name);
    if (type != fmi2ModelExchange || !guid || strcmp(guid, GUID) != 0) {
        LOG(inst, fmi2Error, "fmi2Instantiate: wrong type %d or GUID %s", (int)type, guid ? guid : "(null)");
        cb->freeMemory(inst->name);
        cb->freeMemory(inst);
        return NULL;
    }
    inst->k = 1.0; inst->x0 = 1.0; inst->period = 0.5; inst->t_fault = 1.0; inst->x_low = -1.0;
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
    (void)tol_defined; (void)tol; (void)stop_defined; (void)stop;
    ((Instance *)c)->time = start;
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    inst->x = inst->x0;
    inst->next_tick = inst->time + inst->period;
    return fmi2OK;
}
EXPORT fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2Reset(fmi2Component c) { return unsupported(c, "fmi2Reset"); }

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
        case VR_X: v[i] = inst->x; break;
        case VR_K: v[i] = inst->k; break;
        case VR_X0: v[i] = inst->x0; break;
        case VR_PERIOD: v[i] = inst->period; break;
        case VR_T_FAULT: v[i] = inst->t_fault; break;
        case VR_X_LOW: v[i] = inst->x_low; break;
        case VR_DER_X: v[i] = -inst->k * inst->x; break;
        default: LOG(inst, fmi2Error, "fmi2GetReal: no Real with value reference %u", vr[i]); return fmi2Error;
        }
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
        case VR_FAULT: v[i] = inst->fault; break;
        case VR_TICKS: v[i] = inst->ticks; break;
        default: LOG(inst, fmi2Error, "fmi2GetInteger: no Integer with value reference %u", vr[i]); return fmi2Error;
        }
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2GetBoolean (no Boolean variables)");
}
EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2GetString (no String variables)");
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
        case VR_K: inst->k = v[i]; break;
        case VR_X0: inst->x0 = v[i]; break;
        case VR_PERIOD: inst->period = v[i]; break;
        case VR_T_FAULT: inst->t_fault = v[i]; break;
        case VR_X_LOW: inst->x_low = v[i]; break;
        default: LOG(inst, fmi2Error, "fmi2SetReal: value reference %u is not a parameter", vr[i]); return fmi2Error;
        }
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != VR_FAULT) { LOG(inst, fmi2Error, "fmi2SetInteger: value reference %u is not a parameter", vr[i]); return fmi2Error; }
        inst->fault = v[i];
    }
    return fmi2OK;
}
EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2SetBoolean");
}
EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2SetString");
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2GetFMUstate"); }
EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; return unsupported(c, "fmi2SetFMUstate"); }
EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2FreeFMUstate"); }
EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) { (void)s; (void)n; return unsupported(c, "fmi2SerializedFMUstateSize"); }
EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { (void)s; (void)b; (void)n; return unsupported(c, "fmi2SerializeFMUstate"); }
EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) { (void)b; (void)n; (void)s; return unsupported(c, "fmi2DeSerializeFMUstate"); }
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu, const fmi2ValueReference z[],
                                               size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

EXPORT fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }

EXPORT fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    Instance *inst = (Instance *)c;
    memset(info, 0, sizeof *info);
    if (inst->time >= inst->next_tick - 1e-12) {
        inst->ticks++;
        inst->next_tick += inst->period;
    }
    if (faulty(inst, 3)) info->newDiscreteStatesNeeded = 1;
    if (faulty(inst, 5)) {
        LOG(inst, fmi2OK, "the run is over at t = %g: the fault ends it", inst->time);
        info->terminateSimulation = 1;
    }
    info->nextEventTimeDefined = 1;
    info->nextEventTime = inst->next_tick;
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2OK; }

EXPORT fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean no_prior, fmi2Boolean *enter, fmi2Boolean *terminate) {
    (void)c; (void)no_prior;
    *enter = 0;
    *terminate = 0;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { ((Instance *)c)->time = t; return fmi2OK; }

EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (nx != 1) { LOG(inst, fmi2Error, "fmi2SetContinuousStates: nx = %zu, expected 1", nx); return fmi2Error; }
    inst->x = x[0];
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (nx != 1) return fmi2Error;
    if (faulty(inst, 1)) {
        LOG(inst, fmi2Error, "the derivative cannot be evaluated at t = %g (fault 1)", inst->time);
        return fmi2Error;
    }
    if (faulty(inst, 6)) *(volatile int *)NULL = 1;
    dx[0] = faulty(inst, 2) ? NAN : -inst->k * inst->x;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    Instance *inst = (Instance *)c;
    if (nz != 1) return fmi2Error;
    z[0] = faulty(inst, 4) ? NAN : inst->x - inst->x_low;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    if (nx != 1) return fmi2Error;
    x[0] = ((Instance *)c)->x;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    (void)c;
    if (nx != 1) return fmi2Error;
    x[0] = 1.0;
    return fmi2OK;
}
