/* A Co-Simulation FMU written directly against the FMI 2.0 C API, as a third-party tool would:
 * the Dahlquist test equation x' = -k x, x(0) = x0, advanced with its exact solution
 * x(t + h) = x(t) exp(-k h), so an importer's results can be checked against exp(-k t).
 * If x_min > 0 the model ends the run when x falls below x_min, returning fmi2Discard with
 * fmi2Terminated and the crossing time as fmi2LastSuccessfulTime (the importer's early-end path).
 * It exports all 34 fmi2 functions of a Co-Simulation FMU; compile with -DOMIT_DO_STEP to leave
 * fmi2DoStep out (the importer's missing-symbol path). The FMI types are in fmi2_types.h beside it,
 * so the file needs no headers beyond libc's. */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_types.h"

#define GUID "{8c4e810f-3df3-4a00-8276-176fa3c9f000}"

enum { VR_X, VR_K, VR_X0, VR_X_MIN, VR_STEPS, VR_ENDED };

typedef struct {
    fmi2CallbackFunctions cb;
    char *name;
    int logging_on;
    double k, x0, x_min, x, time;
    int steps, ended;
} Instance;

#define LOG(inst, status, ...) \
    do { if ((inst)->cb.logger) (inst)->cb.logger((inst)->cb.componentEnvironment, (inst)->name, status, "logAll", __VA_ARGS__); } while (0)

static fmi2Status unsupported(fmi2Component c, const char *what) {
    Instance *inst = (Instance *)c;
    if (inst) LOG(inst, fmi2Error, "%s is not supported by this FMU", what);
    return fmi2Error;
}

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)n; (void)cats;
    ((Instance *)c)->logging_on = on;
    return fmi2OK;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging_on) {
    (void)resources; (void)visible;
    if (!cb || !cb->allocateMemory || !name || !name[0]) return NULL;
    Instance *inst = cb->allocateMemory(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->cb = *cb;
    inst->name = cb->allocateMemory(strlen(name) + 1, 1);
    strcpy(inst->name, name);
    if (type != fmi2CoSimulation || !guid || strcmp(guid, GUID) != 0) {
        LOG(inst, fmi2Error, "fmi2Instantiate: wrong type %d or GUID %s (expected %s)", (int)type, guid ? guid : "(null)", GUID);
        cb->freeMemory(inst->name);
        cb->freeMemory(inst);
        return NULL;
    }
    inst->logging_on = logging_on;
    inst->k = 1.0;
    inst->x0 = 1.0;
    inst->x_min = 0.0;
    if (logging_on) LOG(inst, fmi2OK, "instantiated %s with k = %g, x0 = %g", name, inst->k, inst->x0);
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
    if (inst->k < 0) {
        LOG(inst, fmi2Error, "k = %g must not be negative (the solution would grow without bound)", inst->k);
        return fmi2Error;
    }
    inst->x = inst->x0;
    return fmi2OK;
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = (Instance *)c;
    inst->k = 1.0; inst->x0 = 1.0; inst->x_min = 0.0; inst->x = 0.0; inst->time = 0.0;
    inst->steps = 0; inst->ended = 0;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
        case VR_X: v[i] = inst->x; break;
        case VR_K: v[i] = inst->k; break;
        case VR_X0: v[i] = inst->x0; break;
        case VR_X_MIN: v[i] = inst->x_min; break;
        default: LOG(inst, fmi2Error, "fmi2GetReal: no Real with value reference %u", vr[i]); return fmi2Error;
        }
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != VR_STEPS) { LOG(inst, fmi2Error, "fmi2GetInteger: no Integer with value reference %u", vr[i]); return fmi2Error; }
        v[i] = inst->steps;
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != VR_ENDED) { LOG(inst, fmi2Error, "fmi2GetBoolean: no Boolean with value reference %u", vr[i]); return fmi2Error; }
        v[i] = inst->ended;
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2GetString (the model has no String variables)");
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
        case VR_K: inst->k = v[i]; break;
        case VR_X0: inst->x0 = v[i]; break;
        case VR_X_MIN: inst->x_min = v[i]; break;
        default: LOG(inst, fmi2Error, "fmi2SetReal: value reference %u is not a parameter", vr[i]); return fmi2Error;
        }
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2SetInteger (no Integer parameters)");
}
EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2SetBoolean (no Boolean parameters)");
}
EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : unsupported(c, "fmi2SetString (no String parameters)");
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
EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], const fmi2Real v[]) {
    (void)vr; (void)n; (void)o; (void)v;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}
EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], fmi2Real v[]) {
    (void)vr; (void)n; (void)o; (void)v;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

#ifndef OMIT_DO_STEP
EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    (void)no_prior;
    Instance *inst = (Instance *)c;
    if (inst->ended) {
        LOG(inst, fmi2Error, "fmi2DoStep: the model has already ended");
        return fmi2Error;
    }
    double next = inst->x * exp(-inst->k * h);
    inst->steps++;
    if (inst->x_min > 0 && next < inst->x_min) {
        /* Stop exactly where x reaches x_min: t* = t + ln(x / x_min) / k. */
        inst->time = t + log(inst->x / inst->x_min) / inst->k;
        inst->x = inst->x_min;
        inst->ended = 1;
        LOG(inst, fmi2Discard, "x fell below x_min = %g at t = %.6f; the model ends here", inst->x_min, inst->time);
        return fmi2Discard;
    }
    inst->x = next;
    inst->time = t + h;
    return fmi2OK;
}
#endif

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }
EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) { (void)k; (void)v; return unsupported(c, "fmi2GetStatus"); }

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Instance *inst = (Instance *)c;
    if (k != fmi2LastSuccessfulTime) return unsupported(c, "fmi2GetRealStatus for this status kind");
    *v = inst->time;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) { (void)k; (void)v; return unsupported(c, "fmi2GetIntegerStatus"); }

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    Instance *inst = (Instance *)c;
    if (k != fmi2Terminated) return unsupported(c, "fmi2GetBooleanStatus for this status kind");
    *v = inst->ended;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) { (void)k; (void)v; return unsupported(c, "fmi2GetStringStatus"); }
