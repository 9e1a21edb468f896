/* uwc_model.h - instance data and model core shared by the FMI 2.0 and FMI 3.0 wrappers.
 *
 * The model equations come from CasADi generated C code (functions `ode` and `out`):
 *   ode(x[NX], u[NU], p[NP])        -> xdot[NX]
 *   out(x[NX], u[NU], p[NP], z[NZ]) -> y[NY]
 * where z are values from C kernels (the terrain depth of the DepthSounder).
 * Every Float64 variable lives in r[] and its value reference is its index in r[]:
 *   [time | states | derivatives | inputs | parameters | calculated parameters | outputs]
 * String parameters follow with value references UWC_NR + k.
 * The per-model sizes and tables are in the generated uwc_config.h.
 */
#ifndef UWC_MODEL_H
#define UWC_MODEL_H

#include <stddef.h>

/* status codes: identical to fmi2Status / fmi3Status for OK..Fatal */
enum { UWC_OK = 0, UWC_WARNING = 1, UWC_DISCARD = 2, UWC_ERROR = 3, UWC_FATAL = 4 };

/* kinds of Float64 variables (uwc_kind[] table of uwc_config.h) */
enum {
    UWC_K_TIME = 0,
    UWC_K_STATE = 1,
    UWC_K_DER = 2,
    UWC_K_INPUT = 3,
    UWC_K_PARAM = 4,      /* fixed parameter */
    UWC_K_TUNABLE = 5,    /* tunable parameter */
    UWC_K_CALC = 6,       /* calculated parameter */
    UWC_K_OUTPUT = 7
};

#include "uwc_config.h"
#include "uwc_map.h"

/* modes (bit mask, so that calls can list the modes they are allowed in) */
enum {
    UWC_INSTANTIATED = 1,
    UWC_INIT = 2,
    UWC_EVENT = 4,
    UWC_CONT = 8,
    UWC_STEP = 16,
    UWC_TERMINATED = 32,
    UWC_FAILED = 64
};
#define UWC_ANY_MODE 127

struct uwc_inst;
typedef void (*uwc_log_fn)(struct uwc_inst *m, int status, const char *category,
                           const char *message);

typedef struct uwc_inst {
    char *name;
    char *resource_dir;   /* native path ending in a separator, or NULL */
    int is_cs;            /* 1: co-simulation, 0: model exchange */
    int mode;
    int logging_on;
    int dirty;            /* derivatives / outputs need re-evaluation */
    double r[UWC_NR];
    char *s[UWC_NS_ALLOC];
    /* CasADi work memory (one set per instance: instances are independent) */
    const double *arg[UWC_SZ_ARG];
    double *res[UWC_SZ_RES];
    long long int iw[UWC_SZ_IW];
    double w[UWC_SZ_W];
    double k[4][UWC_NX_ALLOC];
    double xt[UWC_NX_ALLOC];
    double z[UWC_NZ_ALLOC];
    /* terrain map (DepthSounder) */
    uwc_map map;
    char *map_path;
    /* wrapper's logger */
    uwc_log_fn log;
    void *env;
    const void *callbacks;
} uwc_inst;

/* life cycle */
uwc_inst *uwc_new(const char *name, const char *token, const char *resource_dir, int is_cs,
                  int logging_on, uwc_log_fn log, void *env, const void *callbacks);
void uwc_free(uwc_inst *m);
int uwc_reset(uwc_inst *m);
void uwc_log(uwc_inst *m, int status, const char *fmt, ...);
int uwc_allowed(uwc_inst *m, const char *fn, int modes);
int uwc_enter_init(uwc_inst *m, double start_time);
int uwc_exit_init(uwc_inst *m);
int uwc_terminate(uwc_inst *m);

/* variables */
int uwc_get_real(uwc_inst *m, const unsigned int vr[], size_t n, double v[]);
int uwc_set_real(uwc_inst *m, const unsigned int vr[], size_t n, const double v[]);
int uwc_get_string(uwc_inst *m, const unsigned int vr[], size_t n, const char *v[]);
int uwc_set_string(uwc_inst *m, const unsigned int vr[], size_t n, const char *const v[]);
int uwc_no_variables(uwc_inst *m, const char *fn, size_t n);

/* co-simulation */
int uwc_do_step(uwc_inst *m, double t, double h);

/* hooks of a test model (UWC_HOOKS = 1: the spec's C source defines them; none of the shipped
 * FMUs has hooks). UWC_OK or UWC_ERROR (the instance then fails, as on an evaluation error). */
#if UWC_HOOKS
int uwc_hook_eval(uwc_inst *m);           /* before the equations are evaluated */
void uwc_hook_outputs(uwc_inst *m);       /* after the outputs are computed */
int uwc_hook_step(uwc_inst *m, double t); /* at the start of doStep from t */
#endif

/* model exchange */
int uwc_set_time(uwc_inst *m, double t);
int uwc_set_states(uwc_inst *m, const double x[], size_t n);
int uwc_get_states(uwc_inst *m, double x[], size_t n);
int uwc_get_derivatives(uwc_inst *m, double dx[], size_t n);
int uwc_get_nominals(uwc_inst *m, double x[], size_t n);

/* FMU state */
int uwc_state_get(uwc_inst *m, void **state);
int uwc_state_set(uwc_inst *m, const void *state);
int uwc_state_free(uwc_inst *m, void **state);
size_t uwc_state_size(void);
int uwc_state_serialize(uwc_inst *m, const void *state, unsigned char *buf, size_t size);
int uwc_state_deserialize(uwc_inst *m, const unsigned char *buf, size_t size, void **state);

int uwc_unsupported(uwc_inst *m, const char *fn);

/* file URI (file:///a/b, file:/a/b, file://localhost/a/b) or plain path -> native path */
int uwc_uri_to_path(const char *uri, char *out, size_t n);

#endif
