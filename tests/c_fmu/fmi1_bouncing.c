/* An FMI 1.0 FMU of a bouncing ball, for state events: h' = v, v' = -g; when h falls through 0
 * the ball is put on the floor, its velocity turns to -e v and `bounces` counts up. Built as Model Exchange, or as
 * Co-Simulation with -DFMI1_CO_SIMULATION (fmi1_frame.h); modelDescription: fmi1_bouncing.xml. */

#define MODEL_IDENTIFIER fmi1_bouncing
#define GUID "{3f6a9d10-7b2c-4a81-8e3d-fmi1bounce01}"
#define NX 2
#define NZ 1
#define NR 4
#define NI 1
#define NB 1

enum { H, V, G, E };
enum { BOUNCES };
enum { BOUNCED };

#include "fmi1_frame.h"

static void model_start(Instance *m) {
    m->r[H] = 1;
    m->r[V] = 0;
    m->r[G] = 9.81;
    m->r[E] = 0.7;
    m->i[BOUNCES] = 0;
    m->b[BOUNCED] = 0;
}

static void model_derivatives(Instance *m, double *dx) {
    dx[0] = m->r[V];
    dx[1] = -m->r[G];
}

static void model_indicators(Instance *m, double *z) { z[0] = m->r[H]; }

static double model_next_event(Instance *m) {
    (void)m;
    return INFINITY;
}

/* Only a fall through the floor bounces. The ball is put on the floor (h = 0, as the Reference
 * FMU BouncingBall does): left a hair below it, its indicator would rise through 0 again right
 * after the bounce, an out-and-back crossing within one integrator step. */
static void model_event(Instance *m) {
    if (m->r[H] <= 0 && m->r[V] < 0) {
        m->r[H] = 0;
        m->r[V] = -m->r[E] * m->r[V];
        m->i[BOUNCES] += 1;
        m->b[BOUNCED] = 1;
    }
}

static void model_outputs(Instance *m) { (void)m; }
