/* model.c - Feedthrough equations (no states, no events):
 *
 *   y = u,  yk = k * u    (Float64/Real, continuous)
 *   iy = iu               (Int32/Integer, discrete)
 *   by = bu               (Boolean, discrete)
 */
#include "core.h"

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {1, "u", VT_F64, K_INPUT, VAR_OFFSET(u), 1},
    {2, "y", VT_F64, K_CALC, VAR_OFFSET(y), 1},
    {3, "iu", VT_I32, K_DINPUT, VAR_OFFSET(iu), 1},
    {4, "iy", VT_I32, K_CALC, VAR_OFFSET(iy), 1},
    {5, "bu", VT_BOOL, K_DINPUT, VAR_OFFSET(bu), 1},
    {6, "by", VT_BOOL, K_CALC, VAR_OFFSET(by), 1},
    {7, "k", VT_F64, K_PARAM, VAR_OFFSET(k), 1},
    {8, "yk", VT_F64, K_CALC, VAR_OFFSET(yk), 1},
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    c->m.u = 0.0;
    c->m.iu = 0;
    c->m.bu = false;
    c->m.k = 2.0;
}

void model_calc(Instance *c) {
    ModelData *m = &c->m;
    m->y = m->u;
    m->yk = m->k * m->u;
    m->iy = m->iu;
    m->by = m->bu;
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
