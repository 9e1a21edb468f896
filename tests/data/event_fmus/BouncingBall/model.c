/* model.c - BouncingBall equations.
 *
 *   der(h) = v,  der(v) = -g            (g > 0 is the acceleration of gravity, downwards)
 *   event indicator z = h (z = 1 once the ball rests)
 *   at h <= 0 with v < 0:  h := 0,  v := -e v,  bounces := bounces + 1;
 *   if then v < v_min the ball rests: h = v = 0 and der(h) = der(v) = 0 from then on.
 *
 * The bounce condition accepts h <= 1e-9 m so that an importer whose root finder stops just
 * before the crossing still gets the bounce (1e-9 m is 2e-10 s at the first impact speed).
 */
#include "core.h"

#define H_EPS 1e-9

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {1, "h", VT_F64, K_START, VAR_OFFSET(h), 1},
    {2, "der(h)", VT_F64, K_CALC, VAR_OFFSET(der_h), 1},
    {3, "v", VT_F64, K_START, VAR_OFFSET(v), 1},
    {4, "der(v)", VT_F64, K_CALC, VAR_OFFSET(der_v), 1},
    {5, "g", VT_F64, K_PARAM, VAR_OFFSET(g), 1},
    {6, "e", VT_F64, K_PARAM, VAR_OFFSET(e), 1},
    {7, "v_min", VT_F64, K_PARAM, VAR_OFFSET(v_min), 1},
    {8, "bounces", VT_I32, K_START, VAR_OFFSET(bounces), 1},
    {9, "z", VT_F64, K_CALC, VAR_OFFSET(z), 1},
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    ModelData *m = &c->m;
    m->h = 1.0;
    m->v = 0.0;
    m->g = 9.81;
    m->e = 0.7;
    m->v_min = 0.1;
    m->bounces = 0;
    m->resting = false;
}

void model_initialize(Instance *c) {
    ModelData *m = &c->m;
    m->resting = m->h <= 0.0 && m->v <= 0.0; /* starts on the floor */
    if (m->resting) m->h = m->v = 0.0;
    c->next_defined = false;
}

void model_der(Instance *c, double dx[]) {
    const ModelData *m = &c->m;
    dx[0] = m->resting ? 0.0 : m->v;
    dx[1] = m->resting ? 0.0 : -m->g;
}

void model_indicators(Instance *c, double z[]) { z[0] = c->m.resting ? 1.0 : c->m.h; }

void model_calc(Instance *c) {
    double dx[NX], z[NZ];
    model_der(c, dx);
    model_indicators(c, z);
    c->m.der_h = dx[0];
    c->m.der_v = dx[1];
    c->m.z = z[0];
}

void model_get_x(Instance *c, double x[]) {
    x[0] = c->m.h;
    x[1] = c->m.v;
}

void model_set_x(Instance *c, const double x[]) {
    c->m.h = x[0];
    c->m.v = x[1];
}

void model_nominals(Instance *c, double nominal[]) {
    (void)c;
    nominal[0] = nominal[1] = 1.0;
}

void model_update(Instance *c) {
    ModelData *m = &c->m;
    if (!m->resting && m->h <= H_EPS && m->v < 0.0) {
        double v_new = -m->e * m->v;
        m->bounces++;
        m->h = 0.0;
        if (v_new < m->v_min) {
            m->resting = true;
            m->v = 0.0;
        } else {
            m->v = v_new;
        }
        c->values_changed = true;
        core_log(c, S_OK, "bounce %d at t=%.17g", (int)m->bounces, c->time);
    }
}

bool model_step_event(Instance *c) {
    (void)c;
    return false;
}
