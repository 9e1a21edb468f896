/* model.c - Stair equations.
 *
 *   counter := counter + 1   at every time event t = k * period (k = 1, 2, ... after the start)
 *   the FMU requests termination at t = t_terminate (after the tick due at that time)
 *   even = (counter mod 2 == 0), computed from the counter of the previous discrete-update pass
 *          (like Modelica's pre()): a tick sets newDiscreteStatesNeeded and even follows in the
 *          next pass, so an importer that does not iterate the update sees a stale value.
 *
 * The next event time is the earlier of the next tick and t_terminate; termination is
 * requested in the pass where the iteration converges.
 * Should several ticks be due at once (never with a master that honours nextEventTime), one
 * is taken per discrete-update pass with newDiscreteStatesNeeded = true.
 */
#include <math.h>

#include "core.h"

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {1, "counter", VT_I32, K_START, VAR_OFFSET(counter), 1},
    {2, "period", VT_F64, K_PARAM, VAR_OFFSET(period), 1},
    {3, "t_terminate", VT_F64, K_PARAM, VAR_OFFSET(t_terminate), 1},
    {4, "even", VT_BOOL, K_CALC, VAR_OFFSET(even), 1},
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    c->m.counter = 1;
    c->m.period = 1.0;
    c->m.t_terminate = 1e9;
    c->m.k = 1;
}

static double tick_time(const ModelData *m) {
    return m->period > 0.0 ? (double)m->k * m->period : INFINITY;
}

void model_initialize(Instance *c) {
    ModelData *m = &c->m;
    m->even = m->counter % 2 == 0;
    if (m->period > 0.0) {
        m->k = (int64_t)floor(c->time / m->period) + 1;
        if (tick_time(m) <= c->time + core_time_tol(c->time)) m->k++;
    } else {
        core_log(c, S_WARNING, "period=%g is not positive: the counter never ticks", m->period);
    }
}

void model_update(Instance *c) {
    ModelData *m = &c->m;
    double tol = core_time_tol(c->time), next;
    m->even = m->counter % 2 == 0; /* from the counter before this pass */
    if (c->time >= tick_time(m) - tol) {
        m->counter++;
        m->k++;
        c->needs_update = true; /* even follows in the next pass */
        core_log(c, S_OK, "tick: counter=%d at t=%.17g", (int)m->counter, c->time);
    }
    /* terminate once the event iteration has converged (even is up to date) */
    if (!c->needs_update && c->time >= m->t_terminate - tol) c->terminate = true;
    next = tick_time(m);
    if (m->t_terminate > c->time + tol && m->t_terminate < next) next = m->t_terminate;
    c->next_defined = isfinite(next) && !c->terminate;
    c->next_time = c->next_defined ? next : 0.0;
}

void model_calc(Instance *c) {
    if (c->mode == M_INSTANTIATED || c->mode == M_INIT) c->m.even = c->m.counter % 2 == 0;
}
void model_get_x(Instance *c, double x[]) { (void)c; (void)x; }
void model_set_x(Instance *c, const double x[]) { (void)c; (void)x; }
void model_der(Instance *c, double dx[]) { (void)c; (void)dx; }
void model_nominals(Instance *c, double nominal[]) { (void)c; (void)nominal; }
void model_indicators(Instance *c, double z[]) { (void)c; (void)z; }

bool model_step_event(Instance *c) {
    (void)c;
    return false;
}
