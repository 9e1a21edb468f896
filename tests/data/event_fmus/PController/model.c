/* model.c - PController equations (no states, no events):
 *
 *   u = kp (r - y)          reference r, measurement y (both continuous inputs)
 */
#include "core.h"

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {1, "r", VT_F64, K_INPUT, VAR_OFFSET(r), 1},
    {2, "y", VT_F64, K_INPUT, VAR_OFFSET(y), 1},
    {3, "u", VT_F64, K_CALC, VAR_OFFSET(u), 1},
    {4, "kp", VT_F64, K_PARAM, VAR_OFFSET(kp), 1},
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    c->m.r = 0.0;
    c->m.y = 0.0;
    c->m.kp = 2.0;
}

void model_calc(Instance *c) { c->m.u = c->m.kp * (c->m.r - c->m.y); }

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
