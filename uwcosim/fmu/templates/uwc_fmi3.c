/* uwc_fmi3.c - FMI 3.0 API (model exchange and co-simulation) over the uwc_model core. */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "uwc_model.h"

#define M ((uwc_inst *)instance)
#define CHECK(fn, modes) \
    if (instance == NULL || !uwc_allowed(M, fn, modes)) return fmi3Error
#define UNSUPPORTED(fn) \
    return instance == NULL ? fmi3Error : (fmi3Status)uwc_unsupported(M, fn)

/* for uwc_fmi_common.h: the functions FMI 2.0 and 3.0 share */
#define FMI(name) fmi3##name
#define FMI_INSTANCE fmi3Instance
#define FMI_FLOAT fmi3Float64
#define FMI_FMUSTATE fmi3FMUState
#define FMI_GET_FMUSTATE fmi3GetFMUState
#define FMI_SET_FMUSTATE fmi3SetFMUState
#define FMI_FREE_FMUSTATE fmi3FreeFMUState
#define FMI_SERIALIZED_FMUSTATE_SIZE fmi3SerializedFMUStateSize
#define FMI_SERIALIZE_FMUSTATE fmi3SerializeFMUState
#define FMI_DESERIALIZE_FMUSTATE fmi3DeserializeFMUState
#define FMI_GET_DERIVATIVES fmi3GetContinuousStateDerivatives
#include "uwc_fmi_common.h"

typedef struct {
    fmi3LogMessageCallback log_message;
} callbacks3;

static void log_fmi3(uwc_inst *m, int status, const char *category, const char *message) {
    const callbacks3 *cb = (const callbacks3 *)m->callbacks;
    if (cb == NULL || cb->log_message == NULL) return;
    cb->log_message(m->env, (fmi3Status)status, category, message);
}

static uwc_inst *instantiate(fmi3String name, fmi3String token, fmi3String resourcePath,
                             int is_cs, fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                             fmi3LogMessageCallback logMessage) {
    callbacks3 *cb = (callbacks3 *)malloc(sizeof(callbacks3));
    uwc_inst *m;
    if (cb == NULL) return NULL;
    cb->log_message = logMessage;
    m = uwc_new(name, token, resourcePath, is_cs, loggingOn, log_fmi3, env, cb);
    if (m == NULL) free(cb);
    return m;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)visible;
    return instantiate(instanceName, instantiationToken, resourcePath, 0, loggingOn,
                       instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)visible;
    (void)eventModeUsed;
    (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    return instantiate(instanceName, instantiationToken, resourcePath, 1, loggingOn,
                       instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    if (logMessage != NULL) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   UWC_MODEL_NAME ": scheduled execution is not supported");
    }
    return NULL;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)uwc_enter_init(M, startTime);
}

/* ---- getters and setters ------------------------------------------------------------ */

static int same_n(uwc_inst *m, const char *fn, size_t nvr, size_t nvalues) {
    if (nvr == nvalues) return 1;
    uwc_log(m, UWC_ERROR, "%s: %s: %lu value references but %lu values (all scalars)", m->name,
            fn, (unsigned long)nvr, (unsigned long)nvalues);
    return 0;
}

/* types this FMU has variables of: forward to the core after the size check */
#define FORWARD(fn, ctype, qual, impl)                                                       \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference valueReferences[],        \
                  size_t nValueReferences, qual ctype values[], size_t nValues) {            \
        if (instance == NULL || !same_n(M, #fn, nValueReferences, nValues))                 \
            return fmi3Error;                                                                \
        return (fmi3Status)impl(M, valueReferences, nValueReferences, values);               \
    }

FORWARD(fmi3GetFloat64, fmi3Float64, , uwc_get_real)
FORWARD(fmi3SetFloat64, fmi3Float64, const, uwc_set_real)
FORWARD(fmi3GetString, fmi3String, , uwc_get_string)
FORWARD(fmi3SetString, fmi3String, const, uwc_set_string)

/* types this FMU has no variables of */
#define NO_VARIABLES(fn, ctype, qual)                                                        \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference valueReferences[],        \
                  size_t nValueReferences, qual ctype values[], size_t nValues) {            \
        (void)valueReferences;                                                               \
        (void)values;                                                                        \
        (void)nValues;                                                                       \
        return instance == NULL ? fmi3Error                                                  \
                                : (fmi3Status)uwc_no_variables(M, #fn, nValueReferences);    \
    }

NO_VARIABLES(fmi3GetFloat32, fmi3Float32, )
NO_VARIABLES(fmi3GetInt8, fmi3Int8, )
NO_VARIABLES(fmi3GetUInt8, fmi3UInt8, )
NO_VARIABLES(fmi3GetInt16, fmi3Int16, )
NO_VARIABLES(fmi3GetUInt16, fmi3UInt16, )
NO_VARIABLES(fmi3GetInt32, fmi3Int32, )
NO_VARIABLES(fmi3GetUInt32, fmi3UInt32, )
NO_VARIABLES(fmi3GetInt64, fmi3Int64, )
NO_VARIABLES(fmi3GetUInt64, fmi3UInt64, )
NO_VARIABLES(fmi3GetBoolean, fmi3Boolean, )
NO_VARIABLES(fmi3SetFloat32, fmi3Float32, const)
NO_VARIABLES(fmi3SetInt8, fmi3Int8, const)
NO_VARIABLES(fmi3SetUInt8, fmi3UInt8, const)
NO_VARIABLES(fmi3SetInt16, fmi3Int16, const)
NO_VARIABLES(fmi3SetUInt16, fmi3UInt16, const)
NO_VARIABLES(fmi3SetInt32, fmi3Int32, const)
NO_VARIABLES(fmi3SetUInt32, fmi3UInt32, const)
NO_VARIABLES(fmi3SetInt64, fmi3Int64, const)
NO_VARIABLES(fmi3SetUInt64, fmi3UInt64, const)
NO_VARIABLES(fmi3SetBoolean, fmi3Boolean, const)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[],
                         size_t nValues) {
    (void)valueReferences;
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return instance == NULL ? fmi3Error
                            : (fmi3Status)uwc_no_variables(M, "fmi3GetBinary", nValueReferences);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)valueReferences;
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return instance == NULL ? fmi3Error
                            : (fmi3Status)uwc_no_variables(M, "fmi3SetBinary", nValueReferences);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[]) {
    (void)valueReferences;
    (void)values;
    return instance == NULL ? fmi3Error
                            : (fmi3Status)uwc_no_variables(M, "fmi3GetClock", nValueReferences);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[]) {
    (void)valueReferences;
    (void)values;
    return instance == NULL ? fmi3Error
                            : (fmi3Status)uwc_no_variables(M, "fmi3SetClock", nValueReferences);
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                               fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference;
    (void)nDependencies;
    UNSUPPORTED("fmi3GetNumberOfVariableDependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    UNSUPPORTED("fmi3GetVariableDependencies");
}

/* ---- unsupported optional features -------------------------------------------------- */

/* derivatives: the same arguments for both */
#define UNSUPPORTED_DERIVATIVE(fn)                                                           \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference unknowns[],                \
                  size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,       \
                  const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[],         \
                  size_t nSensitivity) {                                                     \
        (void)unknowns;                                                                      \
        (void)nUnknowns;                                                                     \
        (void)knowns;                                                                        \
        (void)nKnowns;                                                                       \
        (void)seed;                                                                          \
        (void)nSeed;                                                                         \
        (void)sensitivity;                                                                   \
        (void)nSensitivity;                                                                  \
        UNSUPPORTED(#fn);                                                                    \
    }

UNSUPPORTED_DERIVATIVE(fmi3GetDirectionalDerivative)
UNSUPPORTED_DERIVATIVE(fmi3GetAdjointDerivative)

/* clock intervals and shifts: value references and one, two or three arrays */
#define CLOCK_HEAD(fn)                                                                       \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference valueReferences[],        \
                  size_t nValueReferences
#define CLOCK_BODY(fn, unused)                                                               \
    {                                                                                        \
        (void)valueReferences;                                                               \
        (void)nValueReferences;                                                              \
        unused;                                                                              \
        UNSUPPORTED(#fn);                                                                    \
    }
#define UNSUPPORTED_CLOCK1(fn, T1) CLOCK_HEAD(fn), T1 a[]) CLOCK_BODY(fn, (void)a)
#define UNSUPPORTED_CLOCK2(fn, T1, T2) \
    CLOCK_HEAD(fn), T1 a[], T2 b[]) CLOCK_BODY(fn, (void)a; (void)b)
#define UNSUPPORTED_CLOCK3(fn, T1, T2, T3) \
    CLOCK_HEAD(fn), T1 a[], T2 b[], T3 c[]) CLOCK_BODY(fn, (void)a; (void)b; (void)c)

UNSUPPORTED_CLOCK2(fmi3GetIntervalDecimal, fmi3Float64, fmi3IntervalQualifier)
UNSUPPORTED_CLOCK3(fmi3GetIntervalFraction, fmi3UInt64, fmi3UInt64, fmi3IntervalQualifier)
UNSUPPORTED_CLOCK1(fmi3GetShiftDecimal, fmi3Float64)
UNSUPPORTED_CLOCK2(fmi3GetShiftFraction, fmi3UInt64, fmi3UInt64)
UNSUPPORTED_CLOCK1(fmi3SetIntervalDecimal, const fmi3Float64)
UNSUPPORTED_CLOCK2(fmi3SetIntervalFraction, const fmi3UInt64, const fmi3UInt64)
UNSUPPORTED_CLOCK1(fmi3SetShiftDecimal, const fmi3Float64)
UNSUPPORTED_CLOCK2(fmi3SetShiftFraction, const fmi3UInt64, const fmi3UInt64)

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3EnterConfigurationMode");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3ExitConfigurationMode");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    UNSUPPORTED("fmi3EvaluateDiscreteStates");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    CHECK("fmi3UpdateDiscreteStates", UWC_EVENT);
    *discreteStatesNeedUpdate = fmi3False;
    *terminateSimulation = fmi3False;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = fmi3False;
    *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0.0;
    return fmi3OK;
}

/* ---- model exchange ----------------------------------------------------------------- */

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    if (instance == NULL) return fmi3Error;
    *nEventIndicators = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    if (instance == NULL) return fmi3Error;
    *nContinuousStates = UWC_NX;
    return fmi3OK;
}

/* ---- co-simulation ------------------------------------------------------------------ */

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    CHECK("fmi3EnterStepMode", UWC_EVENT);
    if (!M->is_cs) return (fmi3Status)uwc_unsupported(M, "fmi3EnterStepMode (model exchange)");
    M->mode = UWC_STEP;
    return fmi3OK;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance,
                                    const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[],
                                    fmi3Float64 values[], size_t nValues) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)orders;
    (void)values;
    (void)nValues;
    UNSUPPORTED("fmi3GetOutputDerivatives");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    int status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (instance == NULL) return fmi3Error;
    status = uwc_do_step(M, currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) {
        *lastSuccessfulTime = status == UWC_OK
                                  ? currentCommunicationPoint + communicationStepSize
                                  : currentCommunicationPoint;
    }
    return (fmi3Status)status;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference;
    (void)activationTime;
    UNSUPPORTED("fmi3ActivateModelPartition");
}
