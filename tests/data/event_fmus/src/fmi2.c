/* fmi2.c - the FMI 2.0 C API (Co-Simulation and Model Exchange) of the test FMUs on core.c.
 *
 * Real accesses Float64 (and Float32) variables, Integer the integer and enumeration
 * variables (range-checked to 32 bits), Boolean and String their own. Co-simulation handles
 * all events inside fmi2DoStep; a request to terminate ends fmi2DoStep with fmi2Discard,
 * fmi2GetBooleanStatus(fmi2Terminated) = fmi2True and fmi2GetRealStatus(fmi2LastSuccessfulTime)
 * = the time reached. Directional derivatives where the model defines MODEL_DIRECTIONAL. Not
 * supported (fmi2Error and a log message): FMU states, input derivatives, asynchronous steps.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "core.h"

typedef struct {
    fmi2CallbackFunctions cb;
    bool logging_on;
} Env2;

static void log_fmi2(Instance *c, Status status, const char *message) {
    Env2 *e = (Env2 *)c->env;
    if (e == NULL || e->cb.logger == NULL || (status == S_OK && !e->logging_on)) return;
    /* the message is passed as the format: our messages contain no '%' */
    e->cb.logger(e->cb.componentEnvironment, c->name, (fmi2Status)status,
                 status == S_OK ? "logEvents" : "logStatusError", message);
}

static fmi2Status unsupported(fmi2Component comp, const char *function) {
    core_log((Instance *)comp, S_ERROR, "%s is not supported by " MODEL_NAME, function);
    return fmi2Error;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Instance *c = (Instance *)comp;
    (void)nCategories;
    (void)categories;
    if (c == NULL) return fmi2Error;
    ((Env2 *)c->env)->logging_on = loggingOn != fmi2False;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    Env2 *e;
    Instance *c;
    (void)fmuResourceLocation;
    (void)visible;
    if (functions == NULL) return NULL;
    if (fmuGUID == NULL || strcmp(fmuGUID, TOKEN2) != 0) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                              "logStatusError", "the GUID does not match " MODEL_NAME "'s");
        return NULL;
    }
    e = (Env2 *)calloc(1, sizeof(Env2));
    if (e == NULL) return NULL;
    e->cb = *functions;
    e->logging_on = loggingOn != fmi2False;
    c = core_new(instanceName, fmuType == fmi2ModelExchange, log_fmi2, e);
    if (c == NULL) free(e);
    return c;
}

void fmi2FreeInstance(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (c == NULL) return;
    free(c->env);
    core_free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *c = (Instance *)comp;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (core_check_mode(c, MODES(M_INSTANTIATED), "fmi2SetupExperiment") != S_OK)
        return fmi2Error;
    c->time = c->t_start = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (c == NULL) return fmi2Error;
    return (fmi2Status)core_enter_init(c, c->t_start);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    if (comp == NULL) return fmi2Error;
    return (fmi2Status)core_exit_init((Instance *)comp);
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (core_check_mode(c, MODES(M_EVENT) | MODES(M_CONT) | MODES(M_STEP) | MODES(M_INIT),
                        "fmi2Terminate") != S_OK)
        return fmi2Error;
    c->mode = M_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    if (comp == NULL) return fmi2Error;
    core_reset((Instance *)comp);
    return fmi2OK;
}

/* ---- getters and setters ---- */

static bool is_int(VarType t) {
    return t == VT_I8 || t == VT_U8 || t == VT_I16 || t == VT_U16 || t == VT_I32 ||
           t == VT_U32 || t == VT_I64 || t == VT_U64 || t == VT_ENUM;
}

/* read an integer variable as a 64-bit signed value (UInt64 above INT64_MAX saturates) */
static int64_t read_int(const VarDef *v, const void *p) {
    switch (v->type) {
    case VT_I8: return *(const int8_t *)p;
    case VT_U8: return *(const uint8_t *)p;
    case VT_I16: return *(const int16_t *)p;
    case VT_U16: return *(const uint16_t *)p;
    case VT_I32: return *(const int32_t *)p;
    case VT_U32: return *(const uint32_t *)p;
    case VT_U64: {
        uint64_t u = *(const uint64_t *)p;
        return u > (uint64_t)INT64_MAX ? INT64_MAX : (int64_t)u;
    }
    default: return *(const int64_t *)p; /* VT_I64, VT_ENUM */
    }
}

static bool write_int(const VarDef *v, void *p, int64_t x) {
    switch (v->type) {
    case VT_I8:
        if (x < INT8_MIN || x > INT8_MAX) return false;
        *(int8_t *)p = (int8_t)x;
        break;
    case VT_U8:
        if (x < 0 || x > UINT8_MAX) return false;
        *(uint8_t *)p = (uint8_t)x;
        break;
    case VT_I16:
        if (x < INT16_MIN || x > INT16_MAX) return false;
        *(int16_t *)p = (int16_t)x;
        break;
    case VT_U16:
        if (x < 0 || x > UINT16_MAX) return false;
        *(uint16_t *)p = (uint16_t)x;
        break;
    case VT_I32: *(int32_t *)p = (int32_t)x; break;
    case VT_U32:
        if (x < 0) return false;
        *(uint32_t *)p = (uint32_t)x;
        break;
    case VT_U64:
        if (x < 0) return false;
        *(uint64_t *)p = (uint64_t)x;
        break;
    default: *(int64_t *)p = x; break;
    }
    return true;
}

typedef enum { T_REAL, T_INTEGER, T_BOOLEAN, T_STRING } Fmi2Type;
static const char *FMI2_TYPE_NAMES[] = {"Real", "Integer", "Boolean", "String"};

static bool matches(const VarDef *v, Fmi2Type t) {
    switch (t) {
    case T_REAL: return v->type == VT_F64 || v->type == VT_F32;
    case T_INTEGER: return is_int(v->type);
    case T_BOOLEAN: return v->type == VT_BOOL;
    case T_STRING: return v->type == VT_STR;
    }
    return false;
}

static const VarDef *lookup(Instance *c, fmi2ValueReference vr, Fmi2Type t, const char *function) {
    const VarDef *v = core_var(c, vr, function);
    if (v == NULL) return NULL;
    if (!matches(v, t) || v->count != 1) {
        core_log(c, S_ERROR, "%s: variable '%s' (value reference %u) is not a scalar %s",
                 function, v->name, v->vr, FMI2_TYPE_NAMES[t]);
        return NULL;
    }
    return v;
}

static fmi2Status get_any(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                          Fmi2Type t, void *values, const char *function) {
    Instance *c = (Instance *)comp;
    size_t i;
    if (c == NULL || core_can_get(c, function) != S_OK) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        const VarDef *v = lookup(c, vr[i], t, function);
        const void *p;
        if (v == NULL) return fmi2Error;
        p = core_ptr(c, v);
        switch (t) {
        case T_REAL:
            ((fmi2Real *)values)[i] = v->type == VT_F32 ? *(const float *)p : *(const double *)p;
            break;
        case T_INTEGER: {
            int64_t x = read_int(v, p);
            if (x < INT32_MIN || x > INT32_MAX) {
                core_log(c, S_ERROR, "%s: the value of '%s' does not fit an fmi2Integer",
                         function, v->name);
                return fmi2Error;
            }
            ((fmi2Integer *)values)[i] = (fmi2Integer)x;
            break;
        }
        case T_BOOLEAN:
            ((fmi2Boolean *)values)[i] = *(const bool *)p ? fmi2True : fmi2False;
            break;
        case T_STRING: ((fmi2String *)values)[i] = (const char *)p; break;
        }
    }
    return fmi2OK;
}

static fmi2Status set_any(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                          Fmi2Type t, const void *values, const char *function) {
    Instance *c = (Instance *)comp;
    size_t i;
    if (c == NULL) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        const VarDef *v = lookup(c, vr[i], t, function);
        void *p;
        if (v == NULL || core_can_set(c, v, function) != S_OK) return fmi2Error;
        p = core_ptr(c, v);
        switch (t) {
        case T_REAL:
            if (v->type == VT_F32) *(float *)p = (float)((const fmi2Real *)values)[i];
            else *(double *)p = ((const fmi2Real *)values)[i];
            break;
        case T_INTEGER:
            if (!write_int(v, p, ((const fmi2Integer *)values)[i])) {
                core_log(c, S_ERROR, "%s: %d is out of the range of '%s'", function,
                         ((const fmi2Integer *)values)[i], v->name);
                return fmi2Error;
            }
            break;
        case T_BOOLEAN: *(bool *)p = ((const fmi2Boolean *)values)[i] != fmi2False; break;
        case T_STRING: {
            const char *s = ((const fmi2String *)values)[i];
            if (s == NULL || strlen(s) >= STR_LEN) {
                core_log(c, S_ERROR, "%s: the value of '%s' must be a string shorter than %d "
                         "characters", function, v->name, STR_LEN);
                return fmi2Error;
            }
            strcpy((char *)p, s);
            break;
        }
        }
        if (v->kind == K_DINPUT) c->dinput_changed = true;
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    return get_any(c, vr, nvr, T_REAL, value, "fmi2GetReal");
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    return get_any(c, vr, nvr, T_INTEGER, value, "fmi2GetInteger");
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    return get_any(c, vr, nvr, T_BOOLEAN, value, "fmi2GetBoolean");
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    return get_any(c, vr, nvr, T_STRING, value, "fmi2GetString");
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    return set_any(c, vr, nvr, T_REAL, value, "fmi2SetReal");
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    return set_any(c, vr, nvr, T_INTEGER, value, "fmi2SetInteger");
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    return set_any(c, vr, nvr, T_BOOLEAN, value, "fmi2SetBoolean");
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    return set_any(c, vr, nvr, T_STRING, value, "fmi2SetString");
}

/* ---- not supported ---- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    return unsupported(c, "fmi2GetFMUstate");
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    (void)FMUstate;
    return unsupported(c, "fmi2SetFMUstate");
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    return unsupported(c, "fmi2FreeFMUstate");
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate; (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    (void)FMUstate; (void)serializedState; (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    (void)serializedState; (void)size; (void)FMUstate;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
#ifdef MODEL_DIRECTIONAL
    if (c == NULL) return fmi2Error;
    return (fmi2Status)core_directional((Instance *)c, vUnknown_ref, nUnknown, vKnown_ref, nKnown,
                                        dvKnown, dvUnknown, "fmi2GetDirectionalDerivative");
#else
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown;
    (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
#endif
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}
fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }

/* ---- model exchange ---- */

fmi2Status fmi2EnterEventMode(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (core_check_mode(c, MODES(M_CONT) | MODES(M_EVENT), "fmi2EnterEventMode") != S_OK)
        return fmi2Error;
    c->mode = M_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component comp, fmi2EventInfo *eventInfo) {
    Instance *c = (Instance *)comp;
    if (core_check_mode(c, MODES(M_EVENT), "fmi2NewDiscreteStates") != S_OK) return fmi2Error;
    core_update(c);
    eventInfo->newDiscreteStatesNeeded = c->needs_update;
    eventInfo->terminateSimulation = c->terminate;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = c->values_changed;
    eventInfo->nextEventTimeDefined = c->next_defined;
    eventInfo->nextEventTime = c->next_defined ? c->next_time : 0.0;
    if (c->terminate)
        core_log(c, S_OK, "the FMU requests to terminate the simulation at t=%.17g", c->time);
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (core_check_mode(c, MODES(M_EVENT), "fmi2EnterContinuousTimeMode") != S_OK)
        return fmi2Error;
    c->mode = M_CONT;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component comp,
                                       fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation) {
    Instance *c = (Instance *)comp;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (core_check_mode(c, MODES(M_CONT), "fmi2CompletedIntegratorStep") != S_OK)
        return fmi2Error;
    *enterEventMode = model_step_event(c) ? fmi2True : fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component comp, fmi2Real time) {
    Instance *c = (Instance *)comp;
    if (core_check_mode(c, MODES(M_EVENT) | MODES(M_CONT), "fmi2SetTime") != S_OK)
        return fmi2Error;
    c->time = time;
    return fmi2OK;
}

static fmi2Status check_nx(Instance *c, size_t n, const char *function) {
    if (n == (size_t)NX) return fmi2OK;
    core_log(c, S_ERROR, "%s: " MODEL_NAME " has %d continuous states, not %zu", function, NX, n);
    return fmi2Error;
}

fmi2Status fmi2SetContinuousStates(fmi2Component comp, const fmi2Real x[], size_t nx) {
    Instance *c = (Instance *)comp;
    if (core_check_mode(c, MODES(M_EVENT) | MODES(M_CONT), "fmi2SetContinuousStates") != S_OK ||
        check_nx(c, nx, "fmi2SetContinuousStates") != fmi2OK)
        return fmi2Error;
    if (NX > 0) model_set_x(c, x);
    return fmi2OK;
}

#define EVAL_MODES (MODES(M_INIT) | MODES(M_EVENT) | MODES(M_CONT) | MODES(M_TERMINATED))

fmi2Status fmi2GetDerivatives(fmi2Component comp, fmi2Real derivatives[], size_t nx) {
    Instance *c = (Instance *)comp;
    if (core_check_mode(c, EVAL_MODES, "fmi2GetDerivatives") != S_OK ||
        check_nx(c, nx, "fmi2GetDerivatives") != fmi2OK)
        return fmi2Error;
    if (NX > 0) model_der(c, derivatives);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component comp, fmi2Real eventIndicators[], size_t ni) {
    Instance *c = (Instance *)comp;
    if (core_check_mode(c, EVAL_MODES, "fmi2GetEventIndicators") != S_OK) return fmi2Error;
    if (ni != (size_t)NZ) {
        core_log(c, S_ERROR, "fmi2GetEventIndicators: " MODEL_NAME " has %d event indicators, "
                 "not %zu", NZ, ni);
        return fmi2Error;
    }
    if (NZ > 0) model_indicators(c, eventIndicators);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component comp, fmi2Real x[], size_t nx) {
    Instance *c = (Instance *)comp;
    if (core_check_mode(c, EVAL_MODES, "fmi2GetContinuousStates") != S_OK ||
        check_nx(c, nx, "fmi2GetContinuousStates") != fmi2OK)
        return fmi2Error;
    if (NX > 0) model_get_x(c, x);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component comp, fmi2Real x_nominal[],
                                             size_t nx) {
    Instance *c = (Instance *)comp;
    if (c == NULL || check_nx(c, nx, "fmi2GetNominalsOfContinuousStates") != fmi2OK)
        return fmi2Error;
    if (NX > 0) model_nominals(c, x_nominal);
    return fmi2OK;
}

/* ---- co-simulation ---- */

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentCommunicationPoint) {
    Instance *c = (Instance *)comp;
    double t_reached;
    Status s;
    (void)noSetFMUStatePriorToCurrentCommunicationPoint;
    if (c == NULL) return fmi2Error;
    s = core_do_step(c, currentCommunicationPoint, communicationStepSize, &t_reached);
    if (s != S_OK) return (fmi2Status)s;
    if (c->terminate) {
        core_log(c, S_OK, "the FMU requests to terminate the simulation at t=%.17g", t_reached);
        return fmi2Discard;
    }
    return fmi2OK;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    if (c == NULL) return fmi2Error;
    if (s != fmi2DoStepStatus) return fmi2Discard;
    *value = fmi2OK; /* steps are synchronous */
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    Instance *c = (Instance *)comp;
    if (c == NULL) return fmi2Error;
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = c->time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s; (void)value;
    return c == NULL ? fmi2Error : fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value) {
    Instance *c = (Instance *)comp;
    if (c == NULL) return fmi2Error;
    if (s != fmi2Terminated) return fmi2Discard;
    *value = c->terminate ? fmi2True : fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s; (void)value;
    return c == NULL ? fmi2Error : fmi2Discard;
}
