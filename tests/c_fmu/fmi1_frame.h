/* The FMI 1.0 C API around one small model, as an older tool would export it: Model Exchange
 * by default, Co-Simulation with -DFMI1_CO_SIMULATION (the FMU then integrates itself with
 * classical RK4 sub-steps and locates its state events by bisection on the step). The model
 * file defines MODEL_IDENTIFIER, GUID, NX (states), NZ (event indicators), NR (Reals, the
 * states first), NI (Integers), NB (Booleans), and the hooks below, then includes this file.
 * Every function name carries the modelIdentifier as its prefix, as FMI 1.0 wants; the FMI
 * types are declared here so no header beyond libc's is needed. */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

typedef void *fmiComponent;
typedef unsigned int fmiValueReference;
typedef double fmiReal;
typedef int fmiInteger;
typedef char fmiBoolean;
typedef const char *fmiString;
typedef enum { fmiOK, fmiWarning, fmiDiscard, fmiError, fmiFatal, fmiPending } fmiStatus;
typedef void (*fmiCallbackLogger)(fmiComponent, fmiString, fmiStatus, fmiString, fmiString, ...);
#ifdef FMI1_CO_SIMULATION
typedef struct {
    fmiCallbackLogger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmiComponent, fmiStatus);
} fmiCallbackFunctions;
typedef enum { fmiDoStepStatus, fmiPendingStatus, fmiLastSuccessfulTime } fmiStatusKind;
#else
typedef struct {
    fmiCallbackLogger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
} fmiCallbackFunctions;
#endif
typedef struct {
    fmiBoolean iterationConverged;
    fmiBoolean stateValueReferencesChanged;
    fmiBoolean stateValuesChanged;
    fmiBoolean terminateSimulation;
    fmiBoolean upcomingTimeEvent;
    fmiReal nextEventTime;
} fmiEventInfo;

#define EXPORT __attribute__((visibility("default")))
#define JOIN2(a, b) a##_##b
#define JOIN(a, b) JOIN2(a, b)
#define F(name) JOIN(MODEL_IDENTIFIER, name)

typedef struct {
    fmiCallbackFunctions cb;
    char name[64];
    double time;
    double r[NR];
    int i[NI > 0 ? NI : 1];
    char b[NB > 0 ? NB : 1];
    int initialized;
    int terminate;
} Instance;

/* The model's hooks. */
static void model_start(Instance *m);                   /* start values */
static void model_derivatives(Instance *m, double *dx); /* dx = f(t, x) */
static void model_indicators(Instance *m, double *z);   /* state event indicators */
static void model_event(Instance *m);                   /* discrete changes at an event */
static void model_outputs(Instance *m);                 /* outputs from the states */
static double model_next_event(Instance *m);            /* the next time event, INFINITY if none */

#define LOG(m, status, ...) (m)->cb.logger((m), (m)->name, (status), "model", __VA_ARGS__)

static Instance *instantiate(fmiString name, fmiString guid, fmiCallbackFunctions cb) {
    if (cb.logger == NULL || cb.allocateMemory == NULL || cb.freeMemory == NULL) return NULL;
    if (guid == NULL || strcmp(guid, GUID) != 0) {
        cb.logger(NULL, name, fmiError, "model", "wrong GUID %s, expected %s", guid ? guid : "(null)", GUID);
        return NULL;
    }
    Instance *m = cb.allocateMemory(1, sizeof(Instance));
    if (m == NULL) return NULL;
    m->cb = cb;
    snprintf(m->name, sizeof m->name, "%s", name ? name : "");
    model_start(m);
    return m;
}

static fmiStatus check_vrs(Instance *m, const fmiValueReference vr[], size_t n, unsigned int count, const char *what) {
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= count) {
            LOG(m, fmiError, "%s: no variable has value reference %u", what, vr[k]);
            return fmiError;
        }
    }
    return fmiOK;
}

EXPORT const char *F(fmiGetVersion)(void) { return "1.0"; }

EXPORT fmiStatus F(fmiSetDebugLogging)(fmiComponent c, fmiBoolean on) {
    (void)c;
    (void)on;
    return fmiOK;
}

EXPORT fmiStatus F(fmiSetReal)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiReal v[]) {
    Instance *m = c;
    if (check_vrs(m, vr, n, NR, "fmiSetReal")) return fmiError;
    for (size_t k = 0; k < n; k++) m->r[vr[k]] = v[k];
    return fmiOK;
}

EXPORT fmiStatus F(fmiSetInteger)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiInteger v[]) {
    Instance *m = c;
    if (check_vrs(m, vr, n, NI, "fmiSetInteger")) return fmiError;
    for (size_t k = 0; k < n; k++) m->i[vr[k]] = v[k];
    return fmiOK;
}

EXPORT fmiStatus F(fmiSetBoolean)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiBoolean v[]) {
    Instance *m = c;
    if (check_vrs(m, vr, n, NB, "fmiSetBoolean")) return fmiError;
    for (size_t k = 0; k < n; k++) m->b[vr[k]] = v[k] != 0;
    return fmiOK;
}

EXPORT fmiStatus F(fmiSetString)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiString v[]) {
    (void)v;
    return check_vrs(c, vr, n, 0, "fmiSetString");
}

EXPORT fmiStatus F(fmiGetReal)(fmiComponent c, const fmiValueReference vr[], size_t n, fmiReal v[]) {
    Instance *m = c;
    if (check_vrs(m, vr, n, NR, "fmiGetReal")) return fmiError;
    model_outputs(m);
    for (size_t k = 0; k < n; k++) v[k] = m->r[vr[k]];
    return fmiOK;
}

EXPORT fmiStatus F(fmiGetInteger)(fmiComponent c, const fmiValueReference vr[], size_t n, fmiInteger v[]) {
    Instance *m = c;
    if (check_vrs(m, vr, n, NI, "fmiGetInteger")) return fmiError;
    for (size_t k = 0; k < n; k++) v[k] = m->i[vr[k]];
    return fmiOK;
}

EXPORT fmiStatus F(fmiGetBoolean)(fmiComponent c, const fmiValueReference vr[], size_t n, fmiBoolean v[]) {
    Instance *m = c;
    if (check_vrs(m, vr, n, NB, "fmiGetBoolean")) return fmiError;
    for (size_t k = 0; k < n; k++) v[k] = m->b[vr[k]];
    return fmiOK;
}

EXPORT fmiStatus F(fmiGetString)(fmiComponent c, const fmiValueReference vr[], size_t n, fmiString v[]) {
    (void)v;
    return check_vrs(c, vr, n, 0, "fmiGetString");
}

#ifdef FMI1_CO_SIMULATION

/* Sub-steps of the FMU's own RK4 per communication step. */
#define SUBSTEPS 20

EXPORT const char *F(fmiGetTypesPlatform)(void) { return "standard32"; }

EXPORT fmiComponent F(fmiInstantiateSlave)(fmiString name, fmiString guid, fmiString location, fmiString mime, fmiReal timeout,
                                           fmiBoolean visible, fmiBoolean interactive, fmiCallbackFunctions cb, fmiBoolean loggingOn) {
    (void)location, (void)mime, (void)timeout, (void)visible, (void)interactive, (void)loggingOn;
    return instantiate(name, guid, cb);
}

EXPORT fmiStatus F(fmiInitializeSlave)(fmiComponent c, fmiReal tStart, fmiBoolean stopDefined, fmiReal tStop) {
    Instance *m = c;
    (void)stopDefined, (void)tStop;
    m->time = tStart;
    m->initialized = 1;
    return fmiOK;
}

EXPORT fmiStatus F(fmiTerminateSlave)(fmiComponent c) {
    (void)c;
    return fmiOK;
}

EXPORT fmiStatus F(fmiResetSlave)(fmiComponent c) {
    Instance *m = c;
    model_start(m);
    m->initialized = 0;
    return fmiOK;
}

EXPORT void F(fmiFreeSlaveInstance)(fmiComponent c) {
    Instance *m = c;
    if (m != NULL) m->cb.freeMemory(m);
}

/* One RK4 step of h from the instance's states into x. */
static void rk4(Instance *m, double h, double *x) {
    double x0[NX], k1[NX], k2[NX], k3[NX], k4[NX];
    double t0 = m->time;
    memcpy(x0, m->r, sizeof x0);
    model_derivatives(m, k1);
    for (int j = 0; j < NX; j++) m->r[j] = x0[j] + h / 2 * k1[j];
    m->time = t0 + h / 2;
    model_derivatives(m, k2);
    for (int j = 0; j < NX; j++) m->r[j] = x0[j] + h / 2 * k2[j];
    model_derivatives(m, k3);
    for (int j = 0; j < NX; j++) m->r[j] = x0[j] + h * k3[j];
    m->time = t0 + h;
    model_derivatives(m, k4);
    for (int j = 0; j < NX; j++) x[j] = x0[j] + h / 6 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
    memcpy(m->r, x0, sizeof x0);
    m->time = t0;
}

/* Whether an indicator changes sign from z0 to z1. */
static int crossed(const double *z0, const double *z1) {
    for (int j = 0; j < NZ; j++)
        if ((z0[j] > 0) != (z1[j] > 0)) return 1;
    return 0;
}

EXPORT fmiStatus F(fmiDoStep)(fmiComponent c, fmiReal t, fmiReal h, fmiBoolean newStep) {
    Instance *m = c;
    (void)newStep;
    if (!m->initialized) {
        LOG(m, fmiError, "fmiDoStep before fmiInitializeSlave");
        return fmiError;
    }
    if (fabs(t - m->time) > 1e-9 * fmax(1.0, fabs(t))) {
        LOG(m, fmiError, "fmiDoStep from t = %g, but the slave is at t = %g", t, m->time);
        return fmiError;
    }
    double end = t + h, sub = h / SUBSTEPS, eps = 1e-12 * fmax(1.0, fabs(end)), x[NX], z0[NZ > 0 ? NZ : 1], z1[NZ > 0 ? NZ : 1];
    while (m->time < end - eps) {
        double dt = fmin(sub, end - m->time), te = model_next_event(m);
        if (te <= m->time + eps) {
            /* A time event due now (reached at the end of the last sub-step or step). */
            model_event(m);
            continue;
        }
        int time_event = te - m->time <= dt;
        if (time_event) dt = te - m->time;
        rk4(m, dt, x);
        if (NZ > 0) {
            double saved[NX];
            memcpy(saved, m->r, sizeof saved);
            model_indicators(m, z0);
            memcpy(m->r, x, sizeof x);
            m->time += dt;
            model_indicators(m, z1);
            m->time -= dt;
            memcpy(m->r, saved, sizeof saved);
            if (crossed(z0, z1)) {
                /* Bisection on the RK4 step for the crossing, to 1e-12 s. */
                double lo = 0, hi = dt;
                while (hi - lo > 1e-12) {
                    double mid = (lo + hi) / 2, zm[NZ > 0 ? NZ : 1];
                    rk4(m, mid, x);
                    memcpy(m->r, x, sizeof x);
                    m->time += mid;
                    model_indicators(m, zm);
                    m->time -= mid;
                    memcpy(m->r, saved, sizeof saved);
                    if (crossed(z0, zm)) hi = mid;
                    else lo = mid;
                }
                rk4(m, hi, x);
                memcpy(m->r, x, sizeof x);
                m->time += hi;
                model_event(m);
                continue;
            }
        }
        memcpy(m->r, x, sizeof x);
        m->time = time_event ? te : m->time + dt;
        if (time_event) model_event(m);
    }
    m->time = end;
    if (model_next_event(m) <= end + eps) model_event(m);
    return fmiOK;
}

EXPORT fmiStatus F(fmiCancelStep)(fmiComponent c) {
    (void)c;
    return fmiError;
}

EXPORT fmiStatus F(fmiSetRealInputDerivatives)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiInteger order[],
                                               const fmiReal v[]) {
    (void)vr, (void)n, (void)order, (void)v;
    LOG((Instance *)c, fmiError, "fmiSetRealInputDerivatives: the model has no inputs");
    return fmiError;
}

EXPORT fmiStatus F(fmiGetRealOutputDerivatives)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiInteger order[],
                                                fmiReal v[]) {
    (void)vr, (void)n, (void)order, (void)v;
    LOG((Instance *)c, fmiError, "fmiGetRealOutputDerivatives: not provided");
    return fmiError;
}

EXPORT fmiStatus F(fmiGetStatus)(fmiComponent c, fmiStatusKind s, fmiStatus *v) {
    (void)c, (void)s;
    *v = fmiOK;
    return fmiDiscard;
}

EXPORT fmiStatus F(fmiGetRealStatus)(fmiComponent c, fmiStatusKind s, fmiReal *v) {
    Instance *m = c;
    if (s != fmiLastSuccessfulTime) return fmiDiscard;
    *v = m->time;
    return fmiOK;
}

EXPORT fmiStatus F(fmiGetIntegerStatus)(fmiComponent c, fmiStatusKind s, fmiInteger *v) {
    (void)c, (void)s, (void)v;
    return fmiDiscard;
}

EXPORT fmiStatus F(fmiGetBooleanStatus)(fmiComponent c, fmiStatusKind s, fmiBoolean *v) {
    (void)c, (void)s, (void)v;
    return fmiDiscard;
}

EXPORT fmiStatus F(fmiGetStringStatus)(fmiComponent c, fmiStatusKind s, fmiString *v) {
    (void)c, (void)s, (void)v;
    return fmiDiscard;
}

#else /* Model Exchange */

EXPORT const char *F(fmiGetModelTypesPlatform)(void) { return "standard32"; }

EXPORT fmiComponent F(fmiInstantiateModel)(fmiString name, fmiString guid, fmiCallbackFunctions cb, fmiBoolean loggingOn) {
    (void)loggingOn;
    return instantiate(name, guid, cb);
}

EXPORT void F(fmiFreeModelInstance)(fmiComponent c) {
    Instance *m = c;
    if (m != NULL) m->cb.freeMemory(m);
}

EXPORT fmiStatus F(fmiSetTime)(fmiComponent c, fmiReal t) {
    ((Instance *)c)->time = t;
    return fmiOK;
}

EXPORT fmiStatus F(fmiSetContinuousStates)(fmiComponent c, const fmiReal x[], size_t nx) {
    Instance *m = c;
    if (nx != NX) {
        LOG(m, fmiError, "fmiSetContinuousStates with nx = %zu, the model has %d", nx, NX);
        return fmiError;
    }
    memcpy(m->r, x, NX * sizeof(double));
    return fmiOK;
}

EXPORT fmiStatus F(fmiCompletedIntegratorStep)(fmiComponent c, fmiBoolean *callEventUpdate) {
    (void)c;
    *callEventUpdate = 0;
    return fmiOK;
}

static void no_event(Instance *m, fmiEventInfo *info) {
    double te = model_next_event(m);
    info->iterationConverged = 1;
    info->stateValueReferencesChanged = 0;
    info->stateValuesChanged = 0;
    info->terminateSimulation = 0;
    info->upcomingTimeEvent = isfinite(te) && te > m->time;
    info->nextEventTime = info->upcomingTimeEvent ? te : 0;
}

EXPORT fmiStatus F(fmiInitialize)(fmiComponent c, fmiBoolean toleranceControlled, fmiReal relTol, fmiEventInfo *info) {
    Instance *m = c;
    (void)toleranceControlled, (void)relTol;
    m->initialized = 1;
    no_event(m, info);
    return fmiOK;
}

EXPORT fmiStatus F(fmiGetDerivatives)(fmiComponent c, fmiReal dx[], size_t nx) {
    Instance *m = c;
    if (nx != NX) {
        LOG(m, fmiError, "fmiGetDerivatives with nx = %zu, the model has %d", nx, NX);
        return fmiError;
    }
    model_derivatives(m, dx);
    return fmiOK;
}

EXPORT fmiStatus F(fmiGetEventIndicators)(fmiComponent c, fmiReal z[], size_t nz) {
    Instance *m = c;
    if (nz != NZ) {
        LOG(m, fmiError, "fmiGetEventIndicators with ni = %zu, the model has %d", nz, NZ);
        return fmiError;
    }
    if (NZ > 0) model_indicators(m, z);
    return fmiOK;
}

EXPORT fmiStatus F(fmiEventUpdate)(fmiComponent c, fmiBoolean intermediateResults, fmiEventInfo *info) {
    Instance *m = c;
    (void)intermediateResults;
    model_event(m);
    no_event(m, info);
    info->stateValuesChanged = 1;
    info->terminateSimulation = (fmiBoolean)m->terminate;
    return fmiOK;
}

EXPORT fmiStatus F(fmiGetContinuousStates)(fmiComponent c, fmiReal x[], size_t nx) {
    Instance *m = c;
    if (nx != NX) return fmiError;
    memcpy(x, m->r, NX * sizeof(double));
    return fmiOK;
}

EXPORT fmiStatus F(fmiGetNominalContinuousStates)(fmiComponent c, fmiReal x[], size_t nx) {
    (void)c;
    for (size_t j = 0; j < nx; j++) x[j] = 1.0;
    return fmiOK;
}

EXPORT fmiStatus F(fmiGetStateValueReferences)(fmiComponent c, fmiValueReference vr[], size_t nx) {
    (void)c;
    for (size_t j = 0; j < nx; j++) vr[j] = (fmiValueReference)j;
    return fmiOK;
}

EXPORT fmiStatus F(fmiTerminate)(fmiComponent c) {
    (void)c;
    return fmiOK;
}

#endif
