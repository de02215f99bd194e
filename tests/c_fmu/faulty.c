/* A Co-Simulation FMU that misbehaves on request, as third-party FMUs do: the Dahlquist equation
 * x' = -k x stepped with its exact solution (as dahlquist.c), plus a parameter `fault` that makes
 * fmi2DoStep, at the first step from t >= fault_time, crash with SIGSEGV (1), abort() (2), hang
 * in a busy loop (3), exit the process with code 3 (4), leak leak_mb MB per step for good (5),
 * return fmi2Error with a logged reason (7) or fmi2Fatal with one (8), or fmi2Error with its
 * reason logged as information (9), as FMUs with one info logger do, or fmi2Error with its
 * reason logged only when debug logging is on (10), as many FMUs do;
 * fault 6 leaks leak_mb MB once per instance, at fmi2Instantiate. The output `pid` is the process
 * the instance runs in, so tests can count the processes a sweep used. Compiled with
 * -DONCE_PER_PROCESS, fmi2Instantiate refuses a second instance in one process (its
 * modelDescription then declares canBeInstantiatedOnlyOncePerProcess); with -DSLOW_LOAD, loading
 * the binary takes a second (an initializer that sleeps); with -DCRASH_ON_LOAD, loading it
 * crashes the process with SIGSEGV (an initializer, as a broken static constructor does); with
 * -DSLOW_STEP, each fmi2DoStep takes 5 ms more (a model whose rows come slowly); with
 * -DEXIT_HANDLER, the first
 * fmi2Instantiate registers code of the binary to run at process exit; with -DNEEDS_PYTHON, it
 * leaves a libpython symbol undefined. It also has the solver
 * controls `runner compare` sets (solver, fixed_step, abs_tol; n_steps and n_rhs count steps),
 * and fault_solver >= 0 confines the fault to runs with that `solver`. Exports every fmi2
 * function the runner resolves; the FMI types are in fmi2_types.h, so only libc is needed. */

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fmi2_types.h"

#define GUID "{5a1f0b7e-3c1d-4e55-9a0e-faulty000001}"

enum { VR_X, VR_K, VR_X0, VR_FAULT, VR_FAULT_TIME, VR_LEAK_MB, VR_PID, VR_SOLVER, VR_FIXED_STEP, VR_ABS_TOL, VR_N_STEPS, VR_N_RHS, VR_FAULT_SOLVER };

typedef struct {
    fmi2CallbackFunctions cb;
    char name[256];
    double k, x0, fault_time, leak_mb, x, fixed_step, abs_tol;
    int fault, solver, fault_solver, steps, logging_on;
} Instance;

#define LOG(inst, status, ...) \
    do { if ((inst)->cb.logger) (inst)->cb.logger((inst)->cb.componentEnvironment, (inst)->name, status, "logAll", __VA_ARGS__); } while (0)

#ifdef ONCE_PER_PROCESS
static int instances_made;
#endif

#ifdef SLOW_LOAD
__attribute__((constructor)) static void slow_load(void) { sleep(1); }
#endif

#ifdef CRASH_ON_LOAD
/* A write through NULL, not raise(SIGSEGV): Rust's runtime in the host has a SIGSEGV handler
 * (for stack overflows) that returns from a raised signal, but not from a real fault. */
static int *volatile nowhere; /* NULL, read at run time */
__attribute__((constructor)) static void crash_on_load(void) { *nowhere = 1; }
#endif

#ifdef NEEDS_PYTHON
/* A symbol of libpython left for the host to provide, as FMUs made with PythonFMU leave them. */
extern char _Py_NoneStruct;
EXPORT const void *python_none(void) { return &_Py_NoneStruct; }
#endif

#ifdef EXIT_HANDLER
/* Code of this binary that runs when the process exits, registered for the whole process (no
 * DSO handle, so unloading the binary does not run or remove it), as libraries an FMU brings do
 * (a PythonFMU's libpython with numpy): the exit crashes with SIGSEGV if the binary was unloaded
 * first. */
extern int __cxa_atexit(void (*f)(void *), void *arg, void *dso);
static volatile int exit_handler_ran;
static void at_process_exit(void *arg) { (void)arg; exit_handler_ran = 1; }
#endif

/* Memory this FMU allocates and never frees, touched so that it is resident, and chained to a
 * global list so that the compiler cannot drop the allocation as unused. */
static void *volatile leaked;
static void leak(double mb) {
    size_t bytes = (size_t)(mb * 1048576.0);
    void **p = malloc(bytes);
    memset(p, 1, bytes); /* like much C code, no check: a NULL from an exhausted limit crashes here */
    *p = leaked;
    leaked = p;
}

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }
EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)n; (void)cats;
    if (c) ((Instance *)c)->logging_on = on;
    return fmi2OK;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging_on) {
    (void)resources; (void)visible;
    if (!cb || !cb->allocateMemory || !name || type != fmi2CoSimulation || !guid || strcmp(guid, GUID) != 0) return NULL;
    Instance *inst = cb->allocateMemory(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->cb = *cb;
    inst->logging_on = logging_on;
    strncpy(inst->name, name, sizeof inst->name - 1);
#ifdef ONCE_PER_PROCESS
    if (instances_made++ > 0) {
        LOG(inst, fmi2Error, "this FMU can be instantiated only once per process (instance %d in process %d)", instances_made, (int)getpid());
        cb->freeMemory(inst);
        return NULL;
    }
#endif
#ifdef EXIT_HANDLER
    static int registered;
    if (!registered++) __cxa_atexit(at_process_exit, NULL, NULL);
#endif
    inst->k = 1.0;
    inst->x0 = 1.0;
    inst->fault_time = 0.31;
    inst->leak_mb = 40.0;
    inst->solver = 2;
    inst->fault_solver = -1;
    inst->fixed_step = 0.01;
    inst->abs_tol = 1e-6;
    return inst;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst) inst->cb.freeMemory(inst);
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean a, fmi2Real b, fmi2Real d, fmi2Boolean e, fmi2Real f) {
    (void)c; (void)a; (void)b; (void)d; (void)e; (void)f;
    return fmi2OK;
}
EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    inst->x = inst->x0;
    if (inst->fault == 6) leak(inst->leak_mb);
    return fmi2OK;
}
EXPORT fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
        case VR_X: v[i] = inst->x; break;
        case VR_K: v[i] = inst->k; break;
        case VR_X0: v[i] = inst->x0; break;
        case VR_FAULT_TIME: v[i] = inst->fault_time; break;
        case VR_LEAK_MB: v[i] = inst->leak_mb; break;
        case VR_FIXED_STEP: v[i] = inst->fixed_step; break;
        case VR_ABS_TOL: v[i] = inst->abs_tol; break;
        case VR_N_STEPS: case VR_N_RHS: v[i] = inst->steps; break;
        default: return fmi2Error;
        }
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_PID) v[i] = (int)getpid();
        else if (vr[i] == VR_FAULT) v[i] = inst->fault;
        else if (vr[i] == VR_SOLVER) v[i] = inst->solver;
        else if (vr[i] == VR_FAULT_SOLVER) v[i] = inst->fault_solver;
        else return fmi2Error;
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    (void)c; (void)vr; (void)v;
    return n == 0 ? fmi2OK : fmi2Error;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
        case VR_K: inst->k = v[i]; break;
        case VR_X0: inst->x0 = v[i]; break;
        case VR_FAULT_TIME: inst->fault_time = v[i]; break;
        case VR_LEAK_MB: inst->leak_mb = v[i]; break;
        case VR_FIXED_STEP: inst->fixed_step = v[i]; break;
        case VR_ABS_TOL: inst->abs_tol = v[i]; break;
        default: return fmi2Error;
        }
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    Instance *inst = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_FAULT) inst->fault = v[i];
        else if (vr[i] == VR_SOLVER) inst->solver = v[i];
        else if (vr[i] == VR_FAULT_SOLVER) inst->fault_solver = v[i];
        else return fmi2Error;
    }
    return fmi2OK;
}
EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    (void)c; (void)vr; (void)v;
    return n == 0 ? fmi2OK : fmi2Error;
}
EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)c; (void)vr; (void)v;
    return n == 0 ? fmi2OK : fmi2Error;
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    (void)no_prior;
    Instance *inst = (Instance *)c;
    inst->steps++;
#ifdef SLOW_STEP
    usleep(5000);
#endif
    if (inst->fault && (inst->fault_solver < 0 || inst->fault_solver == inst->solver) && t + 1e-12 >= inst->fault_time) {
        switch (inst->fault) {
        case 1: *(volatile int *)NULL = 1; break;
        case 2: abort();
        case 3: for (volatile unsigned long spin = 0;; spin++) {} break;
        case 4: exit(3);
        case 5: leak(inst->leak_mb); break;
        case 7: LOG(inst, fmi2Error, "fault 7: this step is refused"); return fmi2Error;
        case 8: LOG(inst, fmi2Fatal, "fault 8: the model is corrupted"); return fmi2Fatal;
        case 9: LOG(inst, fmi2OK, "fault 9: the step size is too large for the table"); return fmi2Error;
        case 10: if (inst->logging_on) LOG(inst, fmi2Error, "fault 10: said with debug logging only"); return fmi2Error;
        default: break;
        }
    }
    inst->x *= exp(-inst->k * h);
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    (void)c; (void)k;
    *v = 0;
    return fmi2OK;
}
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    (void)c; (void)k; (void)v;
    return fmi2Error;
}
