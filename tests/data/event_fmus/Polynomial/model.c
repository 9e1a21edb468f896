/* model.c - Polynomial equations (no states, no events):
 *
 *   y = c0 + c1 u + c2 u^2        dy/du = c1 + 2 c2 u (fmi2/fmi3GetDirectionalDerivative)
 *
 * Two of them in a loop (y of each the input of the other) form an algebraic loop: linear with
 * c2 = 0 (fixed point x = (b + a d)/(1 - a c) for y1 = a u1 + b, y2 = c u2 + d), nonlinear
 * otherwise (tests/test_loops.py).
 */
#include "core.h"

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {1, "u", VT_F64, K_INPUT, VAR_OFFSET(u), 1},
    {2, "y", VT_F64, K_CALC, VAR_OFFSET(y), 1},
    {3, "c0", VT_F64, K_PARAM, VAR_OFFSET(c0), 1},
    {4, "c1", VT_F64, K_PARAM, VAR_OFFSET(c1), 1},
    {5, "c2", VT_F64, K_PARAM, VAR_OFFSET(c2), 1},
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    c->m.u = 0.0;
    c->m.c0 = 0.0;
    c->m.c1 = 1.0;
    c->m.c2 = 0.0;
}

void model_calc(Instance *c) {
    ModelData *m = &c->m;
    m->y = m->c0 + (m->c1 + m->c2 * m->u) * m->u;
}

Status model_partial(Instance *c, unsigned unknown, unsigned known, double *d) {
    if (unknown != 2) return S_ERROR;
    *d = known == 1 ? c->m.c1 + 2.0 * c->m.c2 * c->m.u : 0.0;
    return S_OK;
}

void model_initialize(Instance *c) { c->next_defined = false; }
void model_update(Instance *c) { (void)c; }
void model_get_x(Instance *c, double x[]) { (void)c; (void)x; }
void model_set_x(Instance *c, const double x[]) { (void)c; (void)x; }
void model_der(Instance *c, double dx[]) { (void)c; (void)dx; }
void model_nominals(Instance *c, double nominal[]) { (void)c; (void)nominal; }
void model_indicators(Instance *c, double z[]) { (void)c; (void)z; }

bool model_step_event(Instance *c) {
    (void)c;
    return false;
}
