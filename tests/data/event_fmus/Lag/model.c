/* model.c - Lag equations (one state, no events):
 *
 *   der(x) = (K u - x) / T
 *   y      = x + D u        (direct feed-through from u)
 *
 * Around it a PController u = kp (r - y) closes an algebraic loop: u = kp (r - x) / (1 + kp D),
 * so der(x) = -(x - x_inf) / tau with tau = T (1 + kp D) / (1 + kp D + K kp) and
 * x_inf = K kp r / (1 + kp D + K kp) (tests/test_loops.py).
 */
#include "core.h"

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {1, "u", VT_F64, K_INPUT, VAR_OFFSET(u), 1},
    {2, "y", VT_F64, K_CALC, VAR_OFFSET(y), 1},
    {3, "x", VT_F64, K_START, VAR_OFFSET(x), 1},
    {4, "der(x)", VT_F64, K_CALC, VAR_OFFSET(der_x), 1},
    {5, "T", VT_F64, K_PARAM, VAR_OFFSET(T), 1},
    {6, "K", VT_F64, K_PARAM, VAR_OFFSET(K), 1},
    {7, "D", VT_F64, K_PARAM, VAR_OFFSET(D), 1},
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    ModelData *m = &c->m;
    m->u = 0.0;
    m->x = 0.0;
    m->T = 1.0;
    m->K = 1.0;
    m->D = 0.5;
}

void model_der(Instance *c, double dx[]) { dx[0] = (c->m.K * c->m.u - c->m.x) / c->m.T; }

void model_calc(Instance *c) {
    double dx[NX];
    model_der(c, dx);
    c->m.der_x = dx[0];
    c->m.y = c->m.x + c->m.D * c->m.u;
}

void model_get_x(Instance *c, double x[]) { x[0] = c->m.x; }
void model_set_x(Instance *c, const double x[]) { c->m.x = x[0]; }

void model_nominals(Instance *c, double nominal[]) {
    (void)c;
    nominal[0] = 1.0;
}

void model_initialize(Instance *c) { c->next_defined = false; }
void model_update(Instance *c) { (void)c; }
void model_indicators(Instance *c, double z[]) { (void)c; (void)z; }

bool model_step_event(Instance *c) {
    (void)c;
    return false;
}
