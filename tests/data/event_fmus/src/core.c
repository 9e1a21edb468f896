/* core.c - instance, mode checks, event update and co-simulation step of the test FMUs.
 *
 * The co-simulation step integrates the model's continuous states with the classical RK4
 * method on a uniform internal grid no coarser than CS_STEP that lands exactly on the end of
 * the communication step and on the next time event. When an event indicator changes sign
 * inside an internal step (from > 0 to <= 0 or from < 0 to >= 0), the crossing is located by
 * bisection on the RK4 step length to 1e-13 s (relative to the time for t > 1 s) and the
 * discrete update runs at the first point past the crossing; a step event (the model's answer
 * to completedIntegratorStep) after an internal step runs it there. Discrete inputs set between
 * steps are taken in by a discrete update at the start of the next step.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"

#define NXA (NX > 0 ? NX : 1)
#define NZA (NZ > 0 ? NZ : 1)
#define MAX_EVENT_ITERATIONS 100

static const char *MODE_NAMES[] = {"instantiated", "initialization", "event",
                                   "continuous-time", "step", "terminated", "configuration"};

double core_time_tol(double t) { return 1e-10 * fmax(1.0, fabs(t)); }

void core_log(Instance *c, Status status, const char *fmt, ...) {
    char buf[512];
    va_list ap;
    if (c == NULL || c->log == NULL) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    c->log(c, status, buf);
}

void core_reset(Instance *c) {
    memset(&c->m, 0, sizeof c->m);
    c->mode = M_INSTANTIATED;
    c->time = 0.0;
    c->t_start = 0.0;
    c->needs_update = c->terminate = c->values_changed = false;
    c->next_defined = false;
    c->next_time = 0.0;
    c->dinput_changed = false;
    model_start(c);
}

Instance *core_new(const char *name, bool me, LogFn log, void *env) {
    Instance *c = (Instance *)calloc(1, sizeof(Instance));
    if (c == NULL) return NULL;
    c->name = (char *)malloc(strlen(name ? name : "") + 1);
    if (c->name == NULL) {
        free(c);
        return NULL;
    }
    strcpy(c->name, name ? name : "");
    c->me = me;
    c->log = log;
    c->env = env;
    core_reset(c);
    return c;
}

void core_free(Instance *c) {
    if (c == NULL) return;
    free(c->name);
    free(c);
}

const VarDef *core_var(Instance *c, unsigned vr, const char *function) {
    size_t i;
    for (i = 0; i < model_nvars; i++)
        if (model_vars[i].vr == vr) return &model_vars[i];
    core_log(c, S_ERROR, "%s: %s has no variable with value reference %u", function, MODEL_NAME,
             vr);
    return NULL;
}

void *core_ptr(Instance *c, const VarDef *v) { return (char *)c + v->offset; }

Status core_check_mode(Instance *c, unsigned allowed_modes, const char *function) {
    if (c == NULL) return S_ERROR;
    if (allowed_modes & MODES(c->mode)) return S_OK;
    core_log(c, S_ERROR, "%s is not allowed in %s mode", function, MODE_NAMES[c->mode]);
    return S_ERROR;
}

Status core_can_get(Instance *c, const char *function) {
    if (c == NULL) return S_ERROR;
    model_calc(c);
    (void)function;
    return S_OK;
}

Status core_can_set(Instance *c, const VarDef *v, const char *function) {
    switch (v->kind) {
    case K_TIME:
    case K_CALC:
        core_log(c, S_ERROR, "%s: variable '%s' (value reference %u) is computed by the FMU and "
                 "cannot be set", function, v->name, v->vr);
        return S_ERROR;
    case K_SPARAM:
        if (c->mode == M_CONFIG) return S_OK;
        core_log(c, S_ERROR, "%s: variable '%s' (value reference %u) is a structural parameter: "
                 "it can only be set in Configuration Mode, not in %s mode", function, v->name,
                 v->vr, MODE_NAMES[c->mode]);
        return S_ERROR;
    case K_PARAM:
    case K_START:
        if (c->mode == M_INSTANTIATED || c->mode == M_INIT) return S_OK;
        core_log(c, S_ERROR, "%s: variable '%s' (value reference %u) is %s: it can only be set "
                 "before or in initialization mode, not in %s mode", function, v->name, v->vr,
                 v->kind == K_PARAM ? "a fixed parameter" : "a start value", MODE_NAMES[c->mode]);
        return S_ERROR;
    case K_DINPUT:
        if (c->mode == M_CONT) {
            core_log(c, S_ERROR, "%s: variable '%s' (value reference %u) is a discrete input: it "
                     "can only be set in initialization mode or event mode, not in "
                     "continuous-time mode", function, v->name, v->vr);
            return S_ERROR;
        }
        /* fall through */
    case K_INPUT:
        if (c->mode != M_TERMINATED) return S_OK;
        core_log(c, S_ERROR, "%s: variable '%s' cannot be set in terminated mode", function,
                 v->name);
        return S_ERROR;
    }
    return S_ERROR;
}

Status core_enter_init(Instance *c, double t_start) {
    if (core_check_mode(c, MODES(M_INSTANTIATED), "EnterInitializationMode") != S_OK)
        return S_ERROR;
    c->time = c->t_start = t_start;
    c->mode = M_INIT;
    return S_OK;
}

Status core_update(Instance *c) {
    c->needs_update = false;
    c->values_changed = false;
    model_update(c);
    c->dinput_changed = false;
    return S_OK;
}

static void event_iteration(Instance *c) {
    int i;
    for (i = 0; i < MAX_EVENT_ITERATIONS; i++) {
        core_update(c);
        if (!c->needs_update || c->terminate) return;
    }
    core_log(c, S_WARNING, "the event iteration at t=%.17g did not converge in %d passes",
             c->time, MAX_EVENT_ITERATIONS);
}

Status core_exit_init(Instance *c) {
    if (core_check_mode(c, MODES(M_INIT), "ExitInitializationMode") != S_OK) return S_ERROR;
    model_initialize(c);
    if (c->me) {
        c->mode = M_EVENT; /* the importer runs the discrete update */
    } else {
        event_iteration(c);
        c->mode = M_STEP;
    }
    return S_OK;
}

/* one RK4 step of length dt from (t0, x0) with the inputs held; leaves states and time at the
 * last stage evaluation (the caller sets them) */
static void rk4(Instance *c, double t0, const double x0[], double dt, double x1[]) {
    double k1[NXA], k2[NXA], k3[NXA], k4[NXA], xs[NXA];
    int i;
    c->time = t0;
    model_set_x(c, x0);
    model_der(c, k1);
    for (i = 0; i < NX; i++) xs[i] = x0[i] + 0.5 * dt * k1[i];
    c->time = t0 + 0.5 * dt;
    model_set_x(c, xs);
    model_der(c, k2);
    for (i = 0; i < NX; i++) xs[i] = x0[i] + 0.5 * dt * k2[i];
    model_set_x(c, xs);
    model_der(c, k3);
    for (i = 0; i < NX; i++) xs[i] = x0[i] + dt * k3[i];
    c->time = t0 + dt;
    model_set_x(c, xs);
    model_der(c, k4);
    for (i = 0; i < NX; i++)
        x1[i] = x0[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

static bool crossed(const double z0[], const double z1[]) {
    int i;
    for (i = 0; i < NZ; i++)
        if ((z0[i] > 0.0 && z1[i] <= 0.0) || (z0[i] < 0.0 && z1[i] >= 0.0)) return true;
    return false;
}

/* integrate from c->time to target (no time event in between); returns true on a state event,
 * with the states and time at the first point past the crossing, or on a step event (the model
 * asks for an event after an internal step, as completedIntegratorStep would) */
static bool advance(Instance *c, double target) {
    double x0[NXA], x1[NXA], z0[NZA], z1[NZA];
    double t0 = c->time, span = target - t0;
    long n = (long)ceil(span / CS_STEP - 1e-9), k;
    if (n < 1) n = 1;
    for (k = 1; k <= n; k++) {
        double ta = c->time, tb = (k == n) ? target : t0 + span * (double)k / (double)n;
        double dt = tb - ta;
        if (NX == 0) {
            c->time = tb;
            continue;
        }
        model_get_x(c, x0);
        model_indicators(c, z0);
        rk4(c, ta, x0, dt, x1);
        model_set_x(c, x1);
        c->time = tb;
        model_indicators(c, z1);
        if (!crossed(z0, z1)) {
            if (model_step_event(c)) return true; /* a step event */
        } else {
            double a = 0.0, b = dt;
            int it;
            for (it = 0; it < 200 && b - a > 1e-13 * fmax(1.0, fabs(ta)); it++) {
                double mid = 0.5 * (a + b);
                rk4(c, ta, x0, mid, x1);
                model_set_x(c, x1);
                c->time = ta + mid;
                model_indicators(c, z1);
                if (crossed(z0, z1)) b = mid; else a = mid;
            }
            rk4(c, ta, x0, b, x1);
            model_set_x(c, x1);
            c->time = ta + b;
            return true;
        }
    }
    return false;
}

Status core_do_step(Instance *c, double t, double h, double *t_reached) {
    double t_end = t + h;
    *t_reached = c->time;
    if (core_check_mode(c, MODES(M_STEP), "DoStep") != S_OK) return S_ERROR;
    if (c->terminate) { /* asked before (e.g. in initialization): report it again, no progress */
        core_log(c, S_WARNING, "DoStep: the FMU has requested to terminate at t=%.17g",
                 c->time);
        return S_OK;
    }
    if (h < 0.0 || fabs(t - c->time) > core_time_tol(t)) {
        core_log(c, S_ERROR, "DoStep from t=%.17g with step %.17g but the FMU is at t=%.17g", t, h,
                 c->time);
        return S_ERROR;
    }
    c->time = t;
    if (c->dinput_changed) event_iteration(c);
    while (!c->terminate && c->time < t_end - core_time_tol(t_end)) {
        double target = t_end;
        bool state_event;
        if (c->next_defined && c->next_time <= c->time + core_time_tol(c->time)) {
            event_iteration(c); /* a time event due now */
            if (c->terminate) break;
            if (c->next_defined && c->next_time <= c->time + core_time_tol(c->time)) {
                core_log(c, S_ERROR, "DoStep: the next event time %.17g is not after t=%.17g",
                         c->next_time, c->time);
                return S_ERROR;
            }
        }
        if (c->next_defined && c->next_time < target - core_time_tol(target))
            target = c->next_time;
        state_event = advance(c, target);
        if (state_event ||
            (c->next_defined && c->time >= c->next_time - core_time_tol(c->next_time)))
            event_iteration(c);
    }
    if (!c->terminate) c->time = t_end;
    *t_reached = c->time;
    return S_OK;
}

#ifdef MODEL_DIRECTIONAL
Status core_directional(Instance *c, const unsigned unknowns[], size_t n_unknown,
                        const unsigned knowns[], size_t n_known, const double seed[],
                        double sensitivity[], const char *function) {
    size_t i, j;
    if (core_check_mode(c, MODES(M_INIT) | MODES(M_EVENT) | MODES(M_CONT) | MODES(M_STEP),
                        function) != S_OK)
        return S_ERROR;
    model_calc(c);
    for (i = 0; i < n_unknown; i++) {
        double sum = 0.0;
        for (j = 0; j < n_known; j++) {
            double d;
            if (model_partial(c, unknowns[i], knowns[j], &d) != S_OK) {
                core_log(c, S_ERROR, "%s: no partial derivative of value reference %u with "
                         "respect to %u", function, unknowns[i], knowns[j]);
                return S_ERROR;
            }
            sum += d * seed[j];
        }
        sensitivity[i] = sum;
    }
    return S_OK;
}
#endif
