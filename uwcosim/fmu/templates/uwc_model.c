/* uwc_model.c - model core of the uwcosim FMUs: variables, evaluation of the CasADi
 * equations, fixed-step RK4 co-simulation step, terrain kernel, hooks of test models, FMU
 * state.
 * FMI-version independent; uwc_fmi2.c / uwc_fmi3.c map the FMI API onto these functions.
 * No mutable globals: several instances in one process are independent.
 */
#if !defined(_WIN32) && !defined(_POSIX_C_SOURCE)
#define _POSIX_C_SOURCE 200809L
#endif
#define UWC_DEFINE_TABLES
#include "uwc_model.h"

#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* CasADi generated equations (uwc_eqs.c) */
int ode(const double **arg, double **res, long long int *iw, double *w, int mem);
int out(const double **arg, double **res, long long int *iw, double *w, int mem);

#define UWC_STATE_MAGIC 0x55574331u /* "UWC1" */

typedef struct {
    unsigned int magic;
    unsigned int nr;
    int mode;
    int is_cs;
    double r[UWC_NR];
} uwc_state;

static char *dupstr(const char *s) {
    size_t n;
    char *d;
    if (s == NULL) s = "";
    n = strlen(s) + 1;
    d = (char *)malloc(n);
    if (d != NULL) memcpy(d, s, n);
    return d;
}

void uwc_log(uwc_inst *m, int status, const char *fmt, ...) {
    char buf[2048];
    va_list ap;
    const char *category;
    if (m == NULL || m->log == NULL) return;
    if (status == UWC_OK && !m->logging_on) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof(buf), fmt, ap);
    va_end(ap);
    category = status >= UWC_ERROR     ? "logStatusError"
               : status == UWC_WARNING ? "logStatusWarning"
                                       : "logAll";
    m->log(m, status, category, buf);
}

static const char *mode_name(int mode) {
    switch (mode) {
        case UWC_INSTANTIATED: return "the Instantiated state";
        case UWC_INIT: return "Initialization Mode";
        case UWC_EVENT: return "Event Mode";
        case UWC_CONT: return "Continuous-Time Mode";
        case UWC_STEP: return "Step Mode";
        case UWC_TERMINATED: return "the Terminated state";
        default: return "the error state (call reset or free the instance)";
    }
}

int uwc_allowed(uwc_inst *m, const char *fn, int modes) {
    if (m == NULL) return 0;
    if (m->mode & modes) return 1;
    uwc_log(m, UWC_ERROR, "%s: %s must not be called in %s", m->name, fn, mode_name(m->mode));
    return 0;
}

int uwc_unsupported(uwc_inst *m, const char *fn) {
    uwc_log(m, UWC_ERROR, "%s: %s is not supported by %s", m ? m->name : "?", fn,
            UWC_MODEL_NAME);
    return UWC_ERROR;
}

static int fail(uwc_inst *m) {
    m->mode = UWC_FAILED;
    return UWC_ERROR;
}

/* ---- URI and paths ------------------------------------------------------------------ */

static int hexval(int c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

int uwc_uri_to_path(const char *uri, char *out, size_t n) {
    const char *p = uri;
    size_t k = 0;
    int is_uri = 0;
    if (uri == NULL || n == 0) return -1;
    if (strncmp(p, "file://", 7) == 0) {
        p += 7;
        if (strncmp(p, "localhost/", 10) == 0) p += 9;
        is_uri = 1;
    } else if (strncmp(p, "file:", 5) == 0) {
        p += 5;
        is_uri = 1;
    }
#ifdef _WIN32
    if (is_uri && p[0] == '/' && isalpha((unsigned char)p[1]) && p[2] == ':') p++;
#endif
    for (; *p; p++) {
        int c = (unsigned char)*p;
        if (is_uri && c == '%' && hexval(p[1]) >= 0 && hexval(p[2]) >= 0) {
            c = hexval(p[1]) * 16 + hexval(p[2]);
            p += 2;
        }
        if (k + 1 >= n) return -1;
        out[k++] = (char)c;
    }
    out[k] = '\0';
    return 0;
}

/* ---- life cycle --------------------------------------------------------------------- */

static void reset_values(uwc_inst *m) {
    int i;
    for (i = 0; i < UWC_NR; i++) m->r[i] = uwc_start[i];
    for (i = 0; i < UWC_NS; i++) {
        free(m->s[i]);
        m->s[i] = dupstr(uwc_string_start[i]);
    }
    m->dirty = 1;
}

uwc_inst *uwc_new(const char *name, const char *token, const char *resource_dir, int is_cs,
                  int logging_on, uwc_log_fn log, void *env, const void *callbacks) {
    uwc_inst *m = (uwc_inst *)calloc(1, sizeof(uwc_inst));
    size_t n;
    int i;
    if (m == NULL) return NULL;
    m->log = log;
    m->env = env;
    m->callbacks = callbacks;
    m->logging_on = logging_on;
    m->is_cs = is_cs;
    m->name = dupstr(name != NULL && name[0] ? name : UWC_MODEL_NAME);
    if (token == NULL || strcmp(token, UWC_GUID) != 0) {
        uwc_log(m, UWC_ERROR,
                "%s: instantiation token '%s' does not match this binary's '%s' (rebuild the "
                "FMU: modelDescription.xml and binary are from different builds)",
                m->name ? m->name : UWC_MODEL_NAME, token ? token : "(null)", UWC_GUID);
        free(m->name);
        free(m);
        return NULL;
    }
    if (resource_dir != NULL && resource_dir[0]) {
        n = strlen(resource_dir);
        m->resource_dir = (char *)malloc(n + 2);
        if (m->resource_dir != NULL) {
            memcpy(m->resource_dir, resource_dir, n + 1);
            if (resource_dir[n - 1] != '/' && resource_dir[n - 1] != '\\') {
                m->resource_dir[n] = '/';
                m->resource_dir[n + 1] = '\0';
            }
        }
    }
    for (i = 0; i < UWC_NS; i++) m->s[i] = NULL;
    reset_values(m);
    m->mode = UWC_INSTANTIATED;
    uwc_log(m, UWC_OK, "%s: instantiated %s (%s)", m->name, UWC_MODEL_NAME,
            is_cs ? "co-simulation" : "model exchange");
    return m;
}

void uwc_free(uwc_inst *m) {
    int i;
    if (m == NULL) return;
    for (i = 0; i < UWC_NS; i++) free(m->s[i]);
    uwc_map_free(&m->map);
    free(m->map_path);
    free(m->resource_dir);
    free(m->name);
    free(m);
}

int uwc_reset(uwc_inst *m) {
    reset_values(m);
    m->mode = UWC_INSTANTIATED;
    return UWC_OK;
}

/* ---- terrain map (DepthSounder) ------------------------------------------------------ */

static int ensure_map(uwc_inst *m) {
#if UWC_KIND_BATHY
    char path[4096], err[4096 + 256];
    const char *file = m->s[UWC_S_MAPFILE];
    if (file == NULL || file[0] == '\0') {
        if (m->resource_dir == NULL) {
            uwc_log(m, UWC_ERROR, "%s: mapFile is empty and no resource directory was given",
                    m->name);
            return UWC_ERROR;
        }
        snprintf(path, sizeof(path), "%s%s", m->resource_dir, UWC_BATHY_DEFAULT_MAP);
    } else if (uwc_uri_to_path(file, path, sizeof(path)) != 0) {
        uwc_log(m, UWC_ERROR, "%s: mapFile '%s' is too long", m->name, file);
        return UWC_ERROR;
    }
    if (m->map.c != NULL && m->map_path != NULL && strcmp(m->map_path, path) == 0) {
        return UWC_OK;
    }
    uwc_map_free(&m->map);
    free(m->map_path);
    m->map_path = NULL;
    if (uwc_map_load(&m->map, path, err, sizeof(err)) != 0) {
        uwc_log(m, UWC_ERROR, "%s: %s", m->name, err);
        return UWC_ERROR;
    }
    m->map_path = dupstr(path);
    uwc_map_extent(&m->map, m->r + UWC_OFF_C);
    uwc_log(m, UWC_OK, "%s: loaded map '%s' (%d x %d nodes)", m->name, path, m->map.nx,
            m->map.ny);
#else
    (void)m;
#endif
    return UWC_OK;
}

/* ---- equations ---------------------------------------------------------------------- */

static int f_ode(uwc_inst *m, const double *x, double *xdot) {
    m->arg[0] = x;
    m->arg[1] = m->r + UWC_OFF_U;
    m->arg[2] = m->r + UWC_OFF_P;
    m->res[0] = xdot;
    return ode(m->arg, m->res, m->iw, m->w, 0);
}

static int eval(uwc_inst *m) {
    if (!m->dirty) return UWC_OK;
#if UWC_HOOKS
    if (uwc_hook_eval(m) != UWC_OK) return fail(m);
#endif
#if UWC_KIND_BATHY
    {
        const double x = m->r[UWC_OFF_U + UWC_BATHY_IX], y = m->r[UWC_OFF_U + UWC_BATHY_IY];
        if (ensure_map(m) != UWC_OK) return fail(m);
        if (!uwc_map_inside(&m->map, x, y)) {
            const double *e = m->r + UWC_OFF_C;
            uwc_log(m, UWC_ERROR,
                    "%s: position (x, y) = (%.15g, %.15g) m at t = %.15g is outside the map "
                    "'%s' (x in [%.15g, %.15g], y in [%.15g, %.15g])",
                    m->name, x, y, m->r[0], m->map_path, e[0], e[1], e[2], e[3]);
            return fail(m);
        }
        m->z[0] = uwc_map_depth(&m->map, x, y);
    }
#endif
    if (f_ode(m, m->r + UWC_OFF_X, m->r + UWC_OFF_DX) != 0) {
        uwc_log(m, UWC_ERROR, "%s: evaluation of the derivatives failed", m->name);
        return fail(m);
    }
    m->arg[0] = m->r + UWC_OFF_X;
    m->arg[1] = m->r + UWC_OFF_U;
    m->arg[2] = m->r + UWC_OFF_P;
    m->arg[3] = m->z;
    m->res[0] = m->r + UWC_OFF_Y;
    if (out(m->arg, m->res, m->iw, m->w, 0) != 0) {
        uwc_log(m, UWC_ERROR, "%s: evaluation of the outputs failed", m->name);
        return fail(m);
    }
#if UWC_HOOKS
    uwc_hook_outputs(m);
#endif
    m->dirty = 0;
    return UWC_OK;
}

/* ---- initialization ----------------------------------------------------------------- */

int uwc_enter_init(uwc_inst *m, double start_time) {
    if (!uwc_allowed(m, "EnterInitializationMode", UWC_INSTANTIATED)) return UWC_ERROR;
    m->r[0] = start_time;
    m->mode = UWC_INIT;
    m->dirty = 1;
    return UWC_OK;
}

int uwc_exit_init(uwc_inst *m) {
    int i;
    if (!uwc_allowed(m, "ExitInitializationMode", UWC_INIT)) return UWC_ERROR;
    for (i = 0; i < UWC_NX; i++) {
        if (!isfinite(m->r[UWC_OFF_X + i])) {
            uwc_log(m, UWC_ERROR, "%s: start value of state %s is not finite", m->name,
                    uwc_names[UWC_OFF_X + i]);
            return fail(m);
        }
    }
    if (ensure_map(m) != UWC_OK) return fail(m);
    m->mode = m->is_cs ? UWC_STEP : UWC_EVENT;
    m->dirty = 1;
    return UWC_OK;
}

int uwc_terminate(uwc_inst *m) {
    if (!uwc_allowed(m, "Terminate", UWC_EVENT | UWC_CONT | UWC_STEP | UWC_FAILED))
        return UWC_ERROR;
    m->mode = UWC_TERMINATED;
    return UWC_OK;
}

/* ---- variables ---------------------------------------------------------------------- */

static int check_vr(uwc_inst *m, unsigned int vr, const char *fn) {
    if (vr < UWC_NR) return 1;
    uwc_log(m, UWC_ERROR, "%s: %s: unknown Float64 value reference %u", m->name, fn, vr);
    return 0;
}

int uwc_get_real(uwc_inst *m, const unsigned int vr[], size_t n, double v[]) {
    size_t i;
    int need_eval = 0, need_map = 0;
    if (n > 0 && (vr == NULL || v == NULL)) return UWC_ERROR;
    for (i = 0; i < n; i++) {
        if (!check_vr(m, vr[i], "GetReal")) return UWC_ERROR;
        if (uwc_kind[vr[i]] == UWC_K_DER || uwc_kind[vr[i]] == UWC_K_OUTPUT) need_eval = 1;
        if (uwc_kind[vr[i]] == UWC_K_CALC) need_map = 1;
    }
    if (need_map && m->mode != UWC_FAILED && ensure_map(m) != UWC_OK) return fail(m);
    if (need_eval && m->mode != UWC_FAILED && eval(m) != UWC_OK) return UWC_ERROR;
    for (i = 0; i < n; i++) v[i] = m->r[vr[i]];
    return UWC_OK;
}

int uwc_set_real(uwc_inst *m, const unsigned int vr[], size_t n, const double v[]) {
    size_t i;
    int modes;
    if (n > 0 && (vr == NULL || v == NULL)) return UWC_ERROR;
    for (i = 0; i < n; i++) {
        if (!check_vr(m, vr[i], "SetReal")) return UWC_ERROR;
        switch (uwc_kind[vr[i]]) {
            case UWC_K_INPUT:
                modes = UWC_INSTANTIATED | UWC_INIT | UWC_EVENT | UWC_CONT | UWC_STEP;
                break;
            case UWC_K_STATE:
            case UWC_K_PARAM: modes = UWC_INSTANTIATED | UWC_INIT; break;
            case UWC_K_TUNABLE: modes = UWC_INSTANTIATED | UWC_INIT | UWC_EVENT | UWC_STEP; break;
            default:
                uwc_log(m, UWC_ERROR, "%s: variable %s (value reference %u) cannot be set",
                        m->name, uwc_names[vr[i]], vr[i]);
                return UWC_ERROR;
        }
        if (!(m->mode & modes)) {
            uwc_log(m, UWC_ERROR, "%s: variable %s cannot be set in %s", m->name,
                    uwc_names[vr[i]], mode_name(m->mode));
            return UWC_ERROR;
        }
        m->r[vr[i]] = v[i];
    }
    if (n > 0) m->dirty = 1;
    return UWC_OK;
}

int uwc_get_string(uwc_inst *m, const unsigned int vr[], size_t n, const char *v[]) {
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] < UWC_NR || vr[i] >= UWC_NR + UWC_NS) {
            uwc_log(m, UWC_ERROR, "%s: unknown String value reference %u", m->name, vr[i]);
            return UWC_ERROR;
        }
        v[i] = m->s[vr[i] - UWC_NR];
    }
    return UWC_OK;
}

int uwc_set_string(uwc_inst *m, const unsigned int vr[], size_t n, const char *const v[]) {
    size_t i;
    for (i = 0; i < n; i++) {
        char *copy;
        if (vr[i] < UWC_NR || vr[i] >= UWC_NR + UWC_NS) {
            uwc_log(m, UWC_ERROR, "%s: unknown String value reference %u", m->name, vr[i]);
            return UWC_ERROR;
        }
        if (!(m->mode & (UWC_INSTANTIATED | UWC_INIT))) {
            uwc_log(m, UWC_ERROR, "%s: parameter %s cannot be set in %s", m->name,
                    uwc_string_names[vr[i] - UWC_NR], mode_name(m->mode));
            return UWC_ERROR;
        }
        copy = dupstr(v[i]);
        if (copy == NULL) return UWC_ERROR;
        free(m->s[vr[i] - UWC_NR]);
        m->s[vr[i] - UWC_NR] = copy;
    }
    if (n > 0) m->dirty = 1;
    return UWC_OK;
}

int uwc_no_variables(uwc_inst *m, const char *fn, size_t n) {
    if (n == 0) return UWC_OK;
    uwc_log(m, UWC_ERROR, "%s: %s: %s has no variables of this type", m->name, fn,
            UWC_MODEL_NAME);
    return UWC_ERROR;
}

/* ---- co-simulation ------------------------------------------------------------------ */

#if UWC_NX > 0
static int rk4(uwc_inst *m, double h) {
    double *x = m->r + UWC_OFF_X;
    int i;
    if (f_ode(m, x, m->k[0]) != 0) return UWC_ERROR;
    for (i = 0; i < UWC_NX; i++) m->xt[i] = x[i] + h / 2 * m->k[0][i];
    if (f_ode(m, m->xt, m->k[1]) != 0) return UWC_ERROR;
    for (i = 0; i < UWC_NX; i++) m->xt[i] = x[i] + h / 2 * m->k[1][i];
    if (f_ode(m, m->xt, m->k[2]) != 0) return UWC_ERROR;
    for (i = 0; i < UWC_NX; i++) m->xt[i] = x[i] + h * m->k[2][i];
    if (f_ode(m, m->xt, m->k[3]) != 0) return UWC_ERROR;
    for (i = 0; i < UWC_NX; i++) {
        x[i] = x[i] + h / 6 * (m->k[0][i] + 2 * m->k[1][i] + 2 * m->k[2][i] + m->k[3][i]);
    }
    return UWC_OK;
}
#endif

int uwc_do_step(uwc_inst *m, double t, double h) {
    if (!uwc_allowed(m, "DoStep", UWC_STEP)) return UWC_ERROR;
    if (!isfinite(t) || !isfinite(h) || h < 0) {
        uwc_log(m, UWC_ERROR, "%s: invalid communication step (t = %g, h = %g)", m->name, t, h);
        return UWC_ERROR;
    }
    m->r[0] = t;
    m->dirty = 1;
#if UWC_HOOKS
    if (uwc_hook_step(m, t) != UWC_OK) return fail(m);
#endif
#if UWC_NX > 0
    {
        double n = 1.0, dt;
        long k;
        int i;
#if UWC_P_MAX_STEP >= 0
        const double hmax = m->r[UWC_OFF_P + UWC_P_MAX_STEP];
        if (hmax > 0 && h > hmax) n = ceil(h / hmax - 1e-9);
#endif
        if (n > 1e8) {
            uwc_log(m, UWC_ERROR, "%s: step h = %g needs more than 1e8 internal steps", m->name,
                    h);
            return fail(m);
        }
        dt = h / n;
        for (k = 0; k < (long)n; k++) {
            if (rk4(m, dt) != UWC_OK) {
                uwc_log(m, UWC_ERROR, "%s: evaluation of the derivatives failed", m->name);
                return fail(m);
            }
        }
        for (i = 0; i < UWC_NX; i++) {
            if (!isfinite(m->r[UWC_OFF_X + i])) {
                uwc_log(m, UWC_ERROR, "%s: state %s is not finite after the step from t = %g",
                        m->name, uwc_names[UWC_OFF_X + i], t);
                return fail(m);
            }
        }
    }
#endif
    m->r[0] = t + h;
    m->dirty = 1;
    return UWC_OK;
}

/* ---- model exchange ----------------------------------------------------------------- */

static int check_n(uwc_inst *m, const char *fn, size_t n, size_t expected) {
    if (n == expected) return 1;
    uwc_log(m, UWC_ERROR, "%s: %s: expected %lu values, got %lu", m->name, fn,
            (unsigned long)expected, (unsigned long)n);
    return 0;
}

int uwc_set_time(uwc_inst *m, double t) {
    if (!uwc_allowed(m, "SetTime", UWC_EVENT | UWC_CONT)) return UWC_ERROR;
    m->r[0] = t;
    m->dirty = 1;
    return UWC_OK;
}

int uwc_set_states(uwc_inst *m, const double x[], size_t n) {
    size_t i;
    if (!uwc_allowed(m, "SetContinuousStates", UWC_EVENT | UWC_CONT)) return UWC_ERROR;
    if (!check_n(m, "SetContinuousStates", n, UWC_NX)) return UWC_ERROR;
    for (i = 0; i < n; i++) m->r[UWC_OFF_X + i] = x[i];
    m->dirty = 1;
    return UWC_OK;
}

int uwc_get_states(uwc_inst *m, double x[], size_t n) {
    size_t i;
    if (!check_n(m, "GetContinuousStates", n, UWC_NX)) return UWC_ERROR;
    for (i = 0; i < n; i++) x[i] = m->r[UWC_OFF_X + i];
    return UWC_OK;
}

int uwc_get_derivatives(uwc_inst *m, double dx[], size_t n) {
    size_t i;
    if (!check_n(m, "GetDerivatives", n, UWC_NX)) return UWC_ERROR;
    if (m->mode != UWC_FAILED && eval(m) != UWC_OK) return UWC_ERROR;
    for (i = 0; i < n; i++) dx[i] = m->r[UWC_OFF_DX + i];
    return UWC_OK;
}

int uwc_get_nominals(uwc_inst *m, double x[], size_t n) {
    size_t i;
    if (!check_n(m, "GetNominalsOfContinuousStates", n, UWC_NX)) return UWC_ERROR;
    for (i = 0; i < n; i++) x[i] = 1.0;
    return UWC_OK;
}

/* ---- FMU state ---------------------------------------------------------------------- */

int uwc_state_get(uwc_inst *m, void **state) {
    uwc_state *s;
    if (state == NULL) return UWC_ERROR;
    s = (uwc_state *)(*state != NULL ? *state : malloc(sizeof(uwc_state)));
    if (s == NULL) {
        uwc_log(m, UWC_ERROR, "%s: out of memory for the FMU state", m->name);
        return UWC_ERROR;
    }
    s->magic = UWC_STATE_MAGIC;
    s->nr = UWC_NR;
    s->mode = m->mode;
    s->is_cs = m->is_cs;
    memcpy(s->r, m->r, sizeof(m->r));
    *state = s;
    return UWC_OK;
}

static int valid_state(uwc_inst *m, const uwc_state *s) {
    if (s != NULL && s->magic == UWC_STATE_MAGIC && s->nr == UWC_NR && s->is_cs == m->is_cs)
        return 1;
    uwc_log(m, UWC_ERROR, "%s: the FMU state does not belong to this model or interface",
            m->name);
    return 0;
}

int uwc_state_set(uwc_inst *m, const void *state) {
    const uwc_state *s = (const uwc_state *)state;
    if (!valid_state(m, s)) return UWC_ERROR;
    memcpy(m->r, s->r, sizeof(m->r));
    m->mode = s->mode;
    m->dirty = 1;
    return UWC_OK;
}

int uwc_state_free(uwc_inst *m, void **state) {
    (void)m;
    if (state != NULL) {
        free(*state);
        *state = NULL;
    }
    return UWC_OK;
}

size_t uwc_state_size(void) { return sizeof(uwc_state); }

int uwc_state_serialize(uwc_inst *m, const void *state, unsigned char *buf, size_t size) {
    if (!valid_state(m, (const uwc_state *)state)) return UWC_ERROR;
    if (size < sizeof(uwc_state)) {
        uwc_log(m, UWC_ERROR, "%s: buffer too small to serialize the FMU state", m->name);
        return UWC_ERROR;
    }
    memcpy(buf, state, sizeof(uwc_state));
    return UWC_OK;
}

int uwc_state_deserialize(uwc_inst *m, const unsigned char *buf, size_t size, void **state) {
    uwc_state tmp;
    if (size != sizeof(uwc_state)) {
        uwc_log(m, UWC_ERROR, "%s: serialized FMU state has %lu bytes, expected %lu", m->name,
                (unsigned long)size, (unsigned long)sizeof(uwc_state));
        return UWC_ERROR;
    }
    memcpy(&tmp, buf, sizeof(tmp));
    if (!valid_state(m, &tmp)) return UWC_ERROR;
    if (*state == NULL) *state = malloc(sizeof(uwc_state));
    if (*state == NULL) return UWC_ERROR;
    memcpy(*state, &tmp, sizeof(tmp));
    return UWC_OK;
}
