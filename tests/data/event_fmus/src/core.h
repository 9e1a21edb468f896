/* core.h - the model-independent part of the uwcosim event test FMUs.
 *
 * Each model (BouncingBall, Stair, TypedBlock, Feedthrough, ...) provides a config.h (name,
 * instantiation tokens, numbers of states and event indicators, the ModelData struct) and a
 * model.c (variable table and equations). The core keeps the instance (mode, time, event
 * information), checks when a variable may be set, and implements the co-simulation step
 * (RK4 with a fixed internal step, state events located by bisection on the event indicators,
 * time events hit exactly). fmi2.c and fmi3.c map the FMI 2.0 / 3.0 C API onto it; every
 * binary offers both Co-Simulation and Model Exchange.
 */
#ifndef EVFMU_CORE_H
#define EVFMU_CORE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* storage types of the variables (FMI 2 Real = VT_F64, Integer = VT_I32, Enumeration = VT_ENUM) */
typedef enum {
    VT_F64, VT_F32, VT_I8, VT_U8, VT_I16, VT_U16, VT_I32, VT_U32, VT_I64, VT_U64,
    VT_BOOL, VT_STR, VT_ENUM /* stored as int64_t */
} VarType;

/* what may be done with a variable */
typedef enum {
    K_TIME,   /* the independent variable: read only */
    K_PARAM,  /* fixed parameter: set before/in initialization mode only */
    K_INPUT,  /* continuous input: set in any mode but terminated */
    K_DINPUT, /* discrete input: never in continuous-time mode */
    K_START,  /* state or output with initial="exact": set before/in initialization mode */
    K_CALC,   /* computed: never set */
    K_SPARAM  /* FMI 3 structural parameter: set in configuration mode only */
} VarKind;

typedef enum { M_INSTANTIATED, M_INIT, M_EVENT, M_CONT, M_STEP, M_TERMINATED, M_CONFIG } Mode;

typedef enum { S_OK, S_WARNING, S_DISCARD, S_ERROR } Status;

#define STR_LEN 128 /* capacity of String variables including the terminating NUL */

typedef struct {
    unsigned vr;
    const char *name;
    VarType type;
    VarKind kind;
    size_t offset; /* into Instance */
    size_t count;  /* 1 for scalars, the number of elements of an FMI 3 array */
} VarDef;

#include "config.h" /* MODEL_NAME, TOKEN2, TOKEN3, NX, NZ, CS_STEP, ModelData */

struct Instance;
typedef void (*LogFn)(struct Instance *c, Status status, const char *message);

typedef struct Instance {
    char *name;
    bool me;   /* model exchange (else co-simulation) */
    Mode mode;
    double time;
    double t_start;
    /* event information of the last discrete update */
    bool needs_update;    /* newDiscreteStatesNeeded / discreteStatesNeedUpdate */
    bool terminate;       /* terminateSimulation (sticky) */
    bool values_changed;  /* valuesOfContinuousStatesChanged */
    bool next_defined;    /* nextEventTimeDefined */
    double next_time;     /* nextEventTime */
    bool dinput_changed;  /* a discrete input was set since the last discrete update */
    LogFn log;
    void *env; /* the wrapper's callbacks */
    ModelData m;
} Instance;

#define VAR_OFFSET(field) offsetof(Instance, m.field)
#define TIME_OFFSET offsetof(Instance, time)

/* ---- provided by model.c ---- */
extern const VarDef model_vars[];
extern const size_t model_nvars;
void model_start(Instance *c);              /* start values */
void model_initialize(Instance *c);         /* at exit of initialization mode */
void model_calc(Instance *c);               /* outputs and locals from states and inputs */
void model_get_x(Instance *c, double x[]);  /* continuous states */
void model_set_x(Instance *c, const double x[]);
void model_der(Instance *c, double dx[]);   /* their derivatives */
void model_nominals(Instance *c, double nominal[]);
void model_indicators(Instance *c, double z[]);
void model_update(Instance *c);             /* one pass of the discrete (event) update */
bool model_step_event(Instance *c);         /* after an integrator step: enter event mode? */
#ifdef MODEL_DIRECTIONAL
/* d(unknown)/d(known) at the current values (models that define MODEL_DIRECTIONAL in config.h
 * provide directional derivatives); S_ERROR for a pair the model does not know */
Status model_partial(Instance *c, unsigned unknown, unsigned known, double *d);
#endif

/* ---- core.c ---- */
Instance *core_new(const char *name, bool me, LogFn log, void *env);
void core_free(Instance *c);
void core_reset(Instance *c);
void core_log(Instance *c, Status status, const char *fmt, ...);
const VarDef *core_var(Instance *c, unsigned vr, const char *function);
void *core_ptr(Instance *c, const VarDef *v);
Status core_can_set(Instance *c, const VarDef *v, const char *function);
Status core_can_get(Instance *c, const char *function);
Status core_check_mode(Instance *c, unsigned allowed_modes, const char *function);
#define MODES(m) (1u << (m))
Status core_enter_init(Instance *c, double t_start);
Status core_exit_init(Instance *c);
Status core_update(Instance *c);            /* one event update pass (FMI newDiscreteStates) */
Status core_do_step(Instance *c, double t, double h, double *t_reached);
double core_time_tol(double t);
#ifdef MODEL_DIRECTIONAL
/* sensitivity = d(unknowns)/d(knowns) * seed, from model_partial */
Status core_directional(Instance *c, const unsigned unknowns[], size_t n_unknown,
                        const unsigned knowns[], size_t n_known, const double seed[],
                        double sensitivity[], const char *function);
#endif

#endif
