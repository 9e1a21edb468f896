/* fmi3.c - the FMI 3.0 C API (Co-Simulation and Model Exchange) of the test FMUs on core.c.
 *
 * Every variable is accessed through the getter/setter of its own FMI 3 type (Enumeration
 * through Int64), arrays as their elements in row-major order. Co-simulation handles all events
 * inside fmi3DoStep (the FMU declares no event mode); a request to terminate returns
 * terminateSimulation = true with lastSuccessfulTime = the time reached, and earlyReturn = true
 * if that is before the end of the step and the importer allowed early return.
 * Configuration mode (entered from the instantiated mode) is where structural parameters are set.
 * Directional derivatives where the model defines MODEL_DIRECTIONAL. Not supported (an error
 * status and a log message): FMU states, adjoint derivatives, clocks, binaries, reconfiguration
 * in step mode, scheduled execution.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "core.h"

typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    bool logging_on;
    bool early_return_allowed;
} Env3;

static void log_fmi3(Instance *c, Status status, const char *message) {
    Env3 *e = (Env3 *)c->env;
    if (e == NULL || e->log == NULL || (status == S_OK && !e->logging_on)) return;
    e->log(e->env, (fmi3Status)status, status == S_OK ? "logEvents" : "logStatusError", message);
}

static Instance *make(fmi3String name, fmi3String token, bool me, bool logging_on,
                      fmi3InstanceEnvironment env, fmi3LogMessageCallback log_message) {
    Env3 *e;
    Instance *c;
    if (token == NULL || strcmp(token, TOKEN3) != 0) {
        if (log_message)
            log_message(env, fmi3Error, "logStatusError",
                        "the instantiation token does not match " MODEL_NAME "'s");
        return NULL;
    }
    e = (Env3 *)calloc(1, sizeof(Env3));
    if (e == NULL) return NULL;
    e->env = env;
    e->log = log_message;
    e->logging_on = logging_on;
    c = core_new(name, me, log_fmi3, e);
    if (c == NULL) free(e);
    return c;
}

static fmi3Status unsupported(fmi3Instance instance, const char *function) {
    core_log((Instance *)instance, S_ERROR, "%s is not supported by " MODEL_NAME, function);
    return fmi3Error;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    Instance *c = (Instance *)instance;
    (void)nCategories;
    (void)categories;
    if (c == NULL) return fmi3Error;
    ((Env3 *)c->env)->logging_on = loggingOn;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)resourcePath;
    (void)visible;
    return make(instanceName, instantiationToken, true, loggingOn, instanceEnvironment,
                logMessage);
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    Instance *c;
    (void)resourcePath;
    (void)visible;
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (eventModeUsed) {
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       MODEL_NAME " has no co-simulation event mode (hasEventMode=false)");
        return NULL;
    }
    c = make(instanceName, instantiationToken, false, loggingOn, instanceEnvironment,
             logMessage);
    if (c != NULL) ((Env3 *)c->env)->early_return_allowed = earlyReturnAllowed;
    return c;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn; (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   MODEL_NAME " does not support scheduled execution");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Instance *c = (Instance *)instance;
    if (c == NULL) return;
    free(c->env);
    core_free(c);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)core_enter_init((Instance *)instance, startTime);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)core_exit_init((Instance *)instance);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, MODES(M_CONT) | MODES(M_EVENT), "fmi3EnterEventMode") != S_OK)
        return fmi3Error;
    c->mode = M_EVENT;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, MODES(M_EVENT) | MODES(M_CONT) | MODES(M_STEP) | MODES(M_INIT),
                        "fmi3Terminate") != S_OK)
        return fmi3Error;
    c->mode = M_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    core_reset((Instance *)instance);
    return fmi3OK;
}

/* ---- getters and setters ---- */

static size_t type_size(VarType t) {
    switch (t) {
    case VT_F64: return sizeof(double);
    case VT_F32: return sizeof(float);
    case VT_I8: case VT_U8: return 1;
    case VT_I16: case VT_U16: return 2;
    case VT_I32: case VT_U32: return 4;
    case VT_I64: case VT_U64: case VT_ENUM: return 8;
    case VT_BOOL: return sizeof(bool);
    case VT_STR: return sizeof(char *);
    }
    return 0;
}

static bool type_matches(VarType declared, VarType requested) {
    return declared == requested || (declared == VT_ENUM && requested == VT_I64);
}

static const char *TYPE_NAMES[] = {"Float64", "Float32", "Int8", "UInt8", "Int16", "UInt16",
                                   "Int32", "UInt32", "Int64", "UInt64", "Boolean", "String",
                                   "Enumeration"};

static fmi3Status get_values(Instance *c, const fmi3ValueReference vrs[], size_t nvr,
                             VarType type, void *values, size_t n_values, const char *function) {
    size_t i, k = 0, size = type_size(type);
    if (c == NULL || core_can_get(c, function) != S_OK) return fmi3Error;
    for (i = 0; i < nvr; i++) {
        const VarDef *v = core_var(c, vrs[i], function);
        if (v == NULL) return fmi3Error;
        if (!type_matches(v->type, type)) {
            core_log(c, S_ERROR, "%s: variable '%s' (value reference %u) is of type %s", function,
                     v->name, v->vr, TYPE_NAMES[v->type]);
            return fmi3Error;
        }
        if (k + v->count > n_values) {
            core_log(c, S_ERROR, "%s: nValues=%zu is too small", function, n_values);
            return fmi3Error;
        }
        if (type == VT_STR) {
            ((fmi3String *)values)[k] = (const char *)core_ptr(c, v);
        } else {
            memcpy((char *)values + k * size, core_ptr(c, v), v->count * size);
        }
        k += v->count;
    }
    if (k != n_values) {
        core_log(c, S_ERROR, "%s: nValues=%zu but the variables have %zu values", function,
                 n_values, k);
        return fmi3Error;
    }
    return fmi3OK;
}

static fmi3Status set_values(Instance *c, const fmi3ValueReference vrs[], size_t nvr,
                             VarType type, const void *values, size_t n_values,
                             const char *function) {
    size_t i, k = 0, size = type_size(type);
    if (c == NULL) return fmi3Error;
    for (i = 0; i < nvr; i++) {
        const VarDef *v = core_var(c, vrs[i], function);
        if (v == NULL) return fmi3Error;
        if (!type_matches(v->type, type)) {
            core_log(c, S_ERROR, "%s: variable '%s' (value reference %u) is of type %s", function,
                     v->name, v->vr, TYPE_NAMES[v->type]);
            return fmi3Error;
        }
        if (core_can_set(c, v, function) != S_OK) return fmi3Error;
        if (k + v->count > n_values) {
            core_log(c, S_ERROR, "%s: nValues=%zu is too small", function, n_values);
            return fmi3Error;
        }
        if (type == VT_STR) {
            const char *s = ((const fmi3String *)values)[k];
            if (s == NULL || strlen(s) >= STR_LEN) {
                core_log(c, S_ERROR, "%s: the value of '%s' must be a string shorter than %d "
                         "characters", function, v->name, STR_LEN);
                return fmi3Error;
            }
            strcpy((char *)core_ptr(c, v), s);
        } else {
            memcpy(core_ptr(c, v), (const char *)values + k * size, v->count * size);
        }
        if (v->kind == K_DINPUT) c->dinput_changed = true;
        k += v->count;
    }
    if (k != n_values) {
        core_log(c, S_ERROR, "%s: nValues=%zu but the variables have %zu values", function,
                 n_values, k);
        return fmi3Error;
    }
    return fmi3OK;
}

#define ACCESSORS(NAME, CTYPE, VTYPE)                                                          \
    fmi3Status fmi3Get##NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, CTYPE values[], size_t nValues) {        \
        return get_values((Instance *)instance, valueReferences, nValueReferences, VTYPE,      \
                          (void *)values, nValues, "fmi3Get" #NAME);                           \
    }                                                                                          \
    fmi3Status fmi3Set##NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, const CTYPE values[], size_t nValues) {  \
        return set_values((Instance *)instance, valueReferences, nValueReferences, VTYPE,      \
                          (const void *)values, nValues, "fmi3Set" #NAME);                     \
    }

ACCESSORS(Float32, fmi3Float32, VT_F32)
ACCESSORS(Float64, fmi3Float64, VT_F64)
ACCESSORS(Int8, fmi3Int8, VT_I8)
ACCESSORS(UInt8, fmi3UInt8, VT_U8)
ACCESSORS(Int16, fmi3Int16, VT_I16)
ACCESSORS(UInt16, fmi3UInt16, VT_U16)
ACCESSORS(Int32, fmi3Int32, VT_I32)
ACCESSORS(UInt32, fmi3UInt32, VT_U32)
ACCESSORS(Int64, fmi3Int64, VT_I64)
ACCESSORS(UInt64, fmi3UInt64, VT_U64)
ACCESSORS(Boolean, fmi3Boolean, VT_BOOL)
ACCESSORS(String, fmi3String, VT_STR)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[],
                         size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)valueSizes; (void)values; (void)nValues;
    return unsupported(instance, "fmi3GetBinary");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)valueSizes; (void)values; (void)nValues;
    return unsupported(instance, "fmi3SetBinary");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[]) {
    (void)valueReferences; (void)nValueReferences; (void)values;
    return unsupported(instance, "fmi3GetClock");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[]) {
    (void)valueReferences; (void)nValueReferences; (void)values;
    return unsupported(instance, "fmi3SetClock");
}

/* ---- not supported ---- */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                               fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference; (void)nDependencies;
    return unsupported(instance, "fmi3GetNumberOfVariableDependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents;
    (void)elementIndicesOfIndependents; (void)dependencyKinds; (void)nDependencies;
    return unsupported(instance, "fmi3GetVariableDependencies");
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    (void)FMUState;
    return unsupported(instance, "fmi3GetFMUState");
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    (void)FMUState;
    return unsupported(instance, "fmi3SetFMUState");
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    (void)FMUState;
    return unsupported(instance, "fmi3FreeFMUState");
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) {
    (void)FMUState; (void)size;
    return unsupported(instance, "fmi3SerializedFMUStateSize");
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    (void)FMUState; (void)serializedState; (void)size;
    return unsupported(instance, "fmi3SerializeFMUState");
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    (void)serializedState; (void)size; (void)FMUState;
    return unsupported(instance, "fmi3DeserializeFMUState");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance,
                                        const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns,
                                        const fmi3Float64 seed[], size_t nSeed,
                                        fmi3Float64 sensitivity[], size_t nSensitivity) {
#ifdef MODEL_DIRECTIONAL
    Instance *c = (Instance *)instance;
    if (c == NULL) return fmi3Error;
    if (nSeed != nKnowns || nSensitivity != nUnknowns) {
        core_log(c, S_ERROR, "fmi3GetDirectionalDerivative: the scalar variables of " MODEL_NAME
                 " need nSeed = nKnowns and nSensitivity = nUnknowns");
        return fmi3Error;
    }
    return (fmi3Status)core_directional(c, unknowns, nUnknowns, knowns, nKnowns, seed,
                                        sensitivity, "fmi3GetDirectionalDerivative");
#else
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed;
    (void)sensitivity; (void)nSensitivity;
    return unsupported(instance, "fmi3GetDirectionalDerivative");
#endif
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                    size_t nUnknowns, const fmi3ValueReference knowns[],
                                    size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                    fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed;
    (void)sensitivity; (void)nSensitivity;
    return unsupported(instance, "fmi3GetAdjointDerivative");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, MODES(M_INSTANTIATED), "fmi3EnterConfigurationMode") != S_OK)
        return fmi3Error;
    c->mode = M_CONFIG;
    return fmi3OK;
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, MODES(M_CONFIG), "fmi3ExitConfigurationMode") != S_OK)
        return fmi3Error;
    c->mode = M_INSTANTIATED;
    return fmi3OK;
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance,
                                  const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences; (void)nValueReferences; (void)intervals; (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalDecimal");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance,
                                   const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[],
                                   fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalFraction");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) {
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return unsupported(instance, "fmi3GetShiftDecimal");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance,
                                const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[],
                                fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3GetShiftFraction");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance,
                                  const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[]) {
    (void)valueReferences; (void)nValueReferences; (void)intervals;
    return unsupported(instance, "fmi3SetIntervalDecimal");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance,
                                   const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3SetIntervalFraction");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) {
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return unsupported(instance, "fmi3SetShiftDecimal");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance,
                                const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3SetShiftFraction");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    return unsupported(instance, "fmi3EvaluateDiscreteStates");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    return unsupported(instance, "fmi3ActivateModelPartition");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance,
                                    const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[],
                                    fmi3Float64 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)orders; (void)values; (void)nValues;
    return unsupported(instance, "fmi3GetOutputDerivatives");
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterStepMode (no co-simulation event mode)");
}

/* ---- model exchange ---- */

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, MODES(M_EVENT), "fmi3UpdateDiscreteStates") != S_OK) return fmi3Error;
    core_update(c);
    *discreteStatesNeedUpdate = c->needs_update;
    *terminateSimulation = c->terminate;
    *nominalsOfContinuousStatesChanged = false;
    *valuesOfContinuousStatesChanged = c->values_changed;
    *nextEventTimeDefined = c->next_defined;
    *nextEventTime = c->next_defined ? c->next_time : 0.0;
    return fmi3OK;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, MODES(M_EVENT), "fmi3EnterContinuousTimeMode") != S_OK)
        return fmi3Error;
    c->mode = M_CONT;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) {
    Instance *c = (Instance *)instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (core_check_mode(c, MODES(M_CONT), "fmi3CompletedIntegratorStep") != S_OK)
        return fmi3Error;
    *enterEventMode = model_step_event(c) ? true : false;
    *terminateSimulation = false;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, MODES(M_EVENT) | MODES(M_CONT), "fmi3SetTime") != S_OK)
        return fmi3Error;
    c->time = time;
    return fmi3OK;
}

static fmi3Status check_nx(Instance *c, size_t n, const char *function) {
    if (n == (size_t)NX) return fmi3OK;
    core_log(c, S_ERROR, "%s: " MODEL_NAME " has %d continuous states, not %zu", function, NX, n);
    return fmi3Error;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, MODES(M_EVENT) | MODES(M_CONT), "fmi3SetContinuousStates") != S_OK ||
        check_nx(c, nContinuousStates, "fmi3SetContinuousStates") != fmi3OK)
        return fmi3Error;
    if (NX > 0) model_set_x(c, continuousStates);
    return fmi3OK;
}

#define EVAL_MODES (MODES(M_INIT) | MODES(M_EVENT) | MODES(M_CONT) | MODES(M_TERMINATED))

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, EVAL_MODES, "fmi3GetContinuousStateDerivatives") != S_OK ||
        check_nx(c, nContinuousStates, "fmi3GetContinuousStateDerivatives") != fmi3OK)
        return fmi3Error;
    if (NX > 0) model_der(c, derivatives);
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, EVAL_MODES, "fmi3GetEventIndicators") != S_OK) return fmi3Error;
    if (nEventIndicators != (size_t)NZ) {
        core_log(c, S_ERROR, "fmi3GetEventIndicators: " MODEL_NAME " has %d event indicators, "
                 "not %zu", NZ, nEventIndicators);
        return fmi3Error;
    }
    if (NZ > 0) model_indicators(c, eventIndicators);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    Instance *c = (Instance *)instance;
    if (core_check_mode(c, EVAL_MODES, "fmi3GetContinuousStates") != S_OK ||
        check_nx(c, nContinuousStates, "fmi3GetContinuousStates") != fmi3OK)
        return fmi3Error;
    if (NX > 0) model_get_x(c, continuousStates);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    Instance *c = (Instance *)instance;
    if (c == NULL || check_nx(c, nContinuousStates, "fmi3GetNominalsOfContinuousStates") != fmi3OK)
        return fmi3Error;
    if (NX > 0) model_nominals(c, nominals);
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    if (instance == NULL) return fmi3Error;
    *nEventIndicators = (size_t)NZ;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    if (instance == NULL) return fmi3Error;
    *nContinuousStates = (size_t)NX;
    return fmi3OK;
}

/* ---- co-simulation ---- */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    Instance *c = (Instance *)instance;
    double t_end = currentCommunicationPoint + communicationStepSize, t_reached;
    Status s;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL) return fmi3Error;
    s = core_do_step(c, currentCommunicationPoint, communicationStepSize, &t_reached);
    *eventHandlingNeeded = false;
    *terminateSimulation = c->terminate;
    *earlyReturn = c->terminate && ((Env3 *)c->env)->early_return_allowed &&
                   t_reached < t_end - core_time_tol(t_end);
    *lastSuccessfulTime = t_reached;
    if (c->terminate && s == S_OK)
        core_log(c, S_OK, "the FMU requests to terminate the simulation at t=%.17g", t_reached);
    return (fmi3Status)s;
}
