/* An FMI 1.0 FMU of a linear system, a damped oscillator driven by a step input:
 *   x1' = x2,  x2' = -k x1 - c x2 + u,  y = x1,
 * where u steps from 0 to 1 at the time event t = t_switch. Built as Model Exchange, or as
 * Co-Simulation with -DFMI1_CO_SIMULATION (fmi1_frame.h); modelDescription: fmi1_linear.xml. */

#define MODEL_IDENTIFIER fmi1_linear
#define GUID "{8c4e1b2a-1d0f-4e55-9b0a-fmi1linear01}"
#define NX 2
#define NZ 0
#define NR 7
#define NI 0
#define NB 0

enum { X1, X2, K, C, T_SWITCH, U, Y };

#include "fmi1_frame.h"

static void model_start(Instance *m) {
    m->r[X1] = 1;
    m->r[X2] = 0;
    m->r[K] = 4;
    m->r[C] = 0.4;
    m->r[T_SWITCH] = 2;
    m->r[U] = 0;
}

static void model_derivatives(Instance *m, double *dx) {
    dx[0] = m->r[X2];
    dx[1] = -m->r[K] * m->r[X1] - m->r[C] * m->r[X2] + m->r[U];
}

static void model_indicators(Instance *m, double *z) { (void)m, (void)z; }

static double model_next_event(Instance *m) { return m->r[U] == 0 ? m->r[T_SWITCH] : INFINITY; }

static void model_event(Instance *m) {
    if (m->time >= m->r[T_SWITCH] - 1e-12) m->r[U] = 1;
}

static void model_outputs(Instance *m) { m->r[Y] = m->r[X1]; }
