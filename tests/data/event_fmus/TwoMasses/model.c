/* model.c - TwoMasses equations (four states, no events):
 *
 *   der(x1) = v1,  der(v1) = (-c (x1 - x2) - c1 x1 - d1 v1) / m1
 *   der(x2) = v2,  der(v2) = (-c (x2 - x1) - c2 x2 - d2 v2) / m2
 *
 * The equations of two SpringMass FMUs coupled by their positions, in one model.
 */
#include "core.h"

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {1, "x1", VT_F64, K_START, VAR_OFFSET(x1), 1},
    {2, "der(x1)", VT_F64, K_CALC, VAR_OFFSET(der_x1), 1},
    {3, "v1", VT_F64, K_START, VAR_OFFSET(v1), 1},
    {4, "der(v1)", VT_F64, K_CALC, VAR_OFFSET(der_v1), 1},
    {5, "x2", VT_F64, K_START, VAR_OFFSET(x2), 1},
    {6, "der(x2)", VT_F64, K_CALC, VAR_OFFSET(der_x2), 1},
    {7, "v2", VT_F64, K_START, VAR_OFFSET(v2), 1},
    {8, "der(v2)", VT_F64, K_CALC, VAR_OFFSET(der_v2), 1},
    {9, "m1", VT_F64, K_PARAM, VAR_OFFSET(m1), 1},
    {10, "m2", VT_F64, K_PARAM, VAR_OFFSET(m2), 1},
    {11, "c", VT_F64, K_PARAM, VAR_OFFSET(c), 1},
    {12, "c1", VT_F64, K_PARAM, VAR_OFFSET(c1), 1},
    {13, "c2", VT_F64, K_PARAM, VAR_OFFSET(c2), 1},
    {14, "d1", VT_F64, K_PARAM, VAR_OFFSET(d1), 1},
    {15, "d2", VT_F64, K_PARAM, VAR_OFFSET(d2), 1},
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    ModelData *m = &c->m;
    m->x1 = m->v1 = m->x2 = m->v2 = 0.0;
    m->m1 = m->m2 = 1.0;
    m->c = 1.0;
    m->c1 = m->c2 = 0.0;
    m->d1 = m->d2 = 0.0;
}

void model_der(Instance *c, double dx[]) {
    const ModelData *m = &c->m;
    dx[0] = m->v1;
    dx[1] = (-m->c * (m->x1 - m->x2) - m->c1 * m->x1 - m->d1 * m->v1) / m->m1;
    dx[2] = m->v2;
    dx[3] = (-m->c * (m->x2 - m->x1) - m->c2 * m->x2 - m->d2 * m->v2) / m->m2;
}

void model_calc(Instance *c) {
    double dx[NX];
    model_der(c, dx);
    c->m.der_x1 = dx[0];
    c->m.der_v1 = dx[1];
    c->m.der_x2 = dx[2];
    c->m.der_v2 = dx[3];
}

void model_get_x(Instance *c, double x[]) {
    x[0] = c->m.x1;
    x[1] = c->m.v1;
    x[2] = c->m.x2;
    x[3] = c->m.v2;
}

void model_set_x(Instance *c, const double x[]) {
    c->m.x1 = x[0];
    c->m.v1 = x[1];
    c->m.x2 = x[2];
    c->m.v2 = x[3];
}

void model_nominals(Instance *c, double nominal[]) {
    (void)c;
    nominal[0] = nominal[1] = nominal[2] = nominal[3] = 1.0;
}

void model_initialize(Instance *c) { c->next_defined = false; }
void model_update(Instance *c) { (void)c; }
void model_indicators(Instance *c, double z[]) { (void)c; (void)z; }

bool model_step_event(Instance *c) {
    (void)c;
    return false;
}
