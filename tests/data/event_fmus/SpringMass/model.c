/* model.c - SpringMass equations (two states, no events):
 *
 *   der(x) = v
 *   der(v) = (-c (x - x_other) - c_wall x - d v) / m
 *
 * Two of them with each one's x the other's x_other are two masses joined by a spring of
 * stiffness c (both FMUs with the same c), each on its own wall spring and damper: a linear
 * system with the exact solution expm(A t) x0 (tests/test_coupled_me.py), the same equations as
 * TwoMasses in one FMU.
 */
#include "core.h"

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {1, "x_other", VT_F64, K_INPUT, VAR_OFFSET(x_other), 1},
    {2, "x", VT_F64, K_START, VAR_OFFSET(x), 1},
    {3, "der(x)", VT_F64, K_CALC, VAR_OFFSET(der_x), 1},
    {4, "v", VT_F64, K_START, VAR_OFFSET(v), 1},
    {5, "der(v)", VT_F64, K_CALC, VAR_OFFSET(der_v), 1},
    {6, "m", VT_F64, K_PARAM, VAR_OFFSET(m), 1},
    {7, "c", VT_F64, K_PARAM, VAR_OFFSET(c), 1},
    {8, "c_wall", VT_F64, K_PARAM, VAR_OFFSET(c_wall), 1},
    {9, "d", VT_F64, K_PARAM, VAR_OFFSET(d), 1},
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    ModelData *m = &c->m;
    m->x_other = 0.0;
    m->x = 0.0;
    m->v = 0.0;
    m->m = 1.0;
    m->c = 1.0;
    m->c_wall = 0.0;
    m->d = 0.0;
}

void model_der(Instance *c, double dx[]) {
    const ModelData *m = &c->m;
    dx[0] = m->v;
    dx[1] = (-m->c * (m->x - m->x_other) - m->c_wall * m->x - m->d * m->v) / m->m;
}

void model_calc(Instance *c) {
    double dx[NX];
    model_der(c, dx);
    c->m.der_x = dx[0];
    c->m.der_v = dx[1];
}

void model_get_x(Instance *c, double x[]) {
    x[0] = c->m.x;
    x[1] = c->m.v;
}

void model_set_x(Instance *c, const double x[]) {
    c->m.x = x[0];
    c->m.v = x[1];
}

void model_nominals(Instance *c, double nominal[]) {
    (void)c;
    nominal[0] = nominal[1] = 1.0;
}

void model_initialize(Instance *c) { c->next_defined = false; }
void model_update(Instance *c) { (void)c; }
void model_indicators(Instance *c, double z[]) { (void)c; (void)z; }

bool model_step_event(Instance *c) {
    (void)c;
    return false;
}
