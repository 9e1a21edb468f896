/* FeetVehicle.c - a hand-written FMI 3.0 co-simulation vehicle for the uwcosim tests.
 *
 * The kinematics of Chen et al. (eq. 54) in other conventions than uwcosim's: positions in
 * feet, surge/sway speeds in km/h (unit "kmph", defined only through the model description's
 * UnitDefinitions), yaw in radians counter-clockwise from north (uwcosim's psi is measured
 * from east), acceleration in ft/s2 and process-noise inputs in ft/s and m/s2. States are
 * outputs with initial="exact"; one RK4 step per doStep (exact for held inputs).
 *
 * Built with CMake against the FMI 3.0 headers that fmpy ships (fmpy/c-code).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define TOKEN "{5d0b7c1e-3f0a-4a7e-9d55-fe3e7e1c0a03}"

enum { VR_TIME, VR_EAST, VR_NORTH, VR_SURGE, VR_SWAY, VR_YAW, VR_ACCEL,
       VR_W_EAST, VR_W_NORTH, VR_W_SURGE, VR_W_SWAY, N_VR };

static const double FT = 0.3048;          /* m per ft */
static const double KMPH = 1.0 / 3.6;     /* m/s per km/h */

typedef struct {
    double r[N_VR];
    char *name;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Vehicle;

static void say(Vehicle *v, fmi3Status status, const char *text) {
    char buf[256];
    if (v == NULL || v->log == NULL) return;
    snprintf(buf, sizeof buf, "%s: %s", v->name, text);
    v->log(v->env, status, status == fmi3OK ? "logAll" : "logStatusError", buf);
}

static fmi3Status unsupported(fmi3Instance instance, const char *function) {
    char buf[128];
    snprintf(buf, sizeof buf, "%s is not supported by FeetVehicle", function);
    say((Vehicle *)instance, fmi3Error, buf);
    return fmi3Error;
}

/* d/dt [east_ft, north_ft, surge_kmph, sway_kmph] for the held inputs */
static void rates(const Vehicle *v, const double s[4], double d[4]) {
    const double *r = v->r;
    double c = cos(r[VR_YAW]), sn = sin(r[VR_YAW]);
    double a = r[VR_ACCEL] * FT; /* m/s2 */
    double u = s[2] * KMPH, w = s[3] * KMPH; /* m/s */
    d[0] = (-u * sn - w * c) / FT + r[VR_W_EAST];
    d[1] = (u * c - w * sn) / FT + r[VR_W_NORTH];
    d[2] = (-a * sn + r[VR_W_SURGE]) / KMPH;
    d[3] = (a * c + r[VR_W_SWAY]) / KMPH;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)instance; (void)loggingOn; (void)nCategories; (void)categories;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    Vehicle *v;
    (void)resourcePath; (void)visible; (void)loggingOn; (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (instantiationToken == NULL || strcmp(instantiationToken, TOKEN) != 0 || eventModeUsed)
        return NULL;
    v = (Vehicle *)calloc(1, sizeof(Vehicle));
    if (v == NULL) return NULL;
    v->name = strdup(instanceName ? instanceName : "FeetVehicle");
    v->env = instanceEnvironment;
    v->log = logMessage;
    return v;
}

fmi3Instance fmi3InstantiateModelExchange(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn; (void)instanceEnvironment; (void)logMessage;
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn; (void)instanceEnvironment; (void)logMessage; (void)clockUpdate;
    (void)lockPreemption; (void)unlockPreemption;
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Vehicle *v = (Vehicle *)instance;
    if (v == NULL) return;
    free(v->name);
    free(v);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    ((Vehicle *)instance)->r[VR_TIME] = startTime;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3EnterStepMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3Reset(fmi3Instance instance) {
    Vehicle *v = (Vehicle *)instance;
    memset(v->r, 0, sizeof v->r);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    Vehicle *v = (Vehicle *)instance;
    size_t i;
    if (nValues != nValueReferences) return unsupported(instance, "fmi3GetFloat64 (arrays)");
    for (i = 0; i < nValueReferences; i++) {
        if (valueReferences[i] >= N_VR) return unsupported(instance, "fmi3GetFloat64 (bad vr)");
        values[i] = v->r[valueReferences[i]];
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    Vehicle *v = (Vehicle *)instance;
    size_t i;
    if (nValues != nValueReferences) return unsupported(instance, "fmi3SetFloat64 (arrays)");
    for (i = 0; i < nValueReferences; i++) {
        if (valueReferences[i] == VR_TIME || valueReferences[i] >= N_VR)
            return unsupported(instance, "fmi3SetFloat64 (bad vr)");
        v->r[valueReferences[i]] = values[i];
    }
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    Vehicle *v = (Vehicle *)instance;
    double h = communicationStepSize, s[4], k1[4], k2[4], k3[4], k4[4], t[4];
    int i;
    (void)noSetFMUStatePriorToCurrentPoint;
    for (i = 0; i < 4; i++) s[i] = v->r[VR_EAST + i];
    rates(v, s, k1);
    for (i = 0; i < 4; i++) t[i] = s[i] + h / 2 * k1[i];
    rates(v, t, k2);
    for (i = 0; i < 4; i++) t[i] = s[i] + h / 2 * k2[i];
    rates(v, t, k3);
    for (i = 0; i < 4; i++) t[i] = s[i] + h * k3[i];
    rates(v, t, k4);
    for (i = 0; i < 4; i++)
        v->r[VR_EAST + i] = s[i] + h / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    v->r[VR_TIME] = currentCommunicationPoint + h;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = v->r[VR_TIME];
    return fmi3OK;
}

/* Every FMI 3.0 function must be exported; those this vehicle does not support fail. */
#define UNSUPPORTED(name, params) fmi3Status name params { return unsupported(instance, #name); }

UNSUPPORTED(fmi3EnterEventMode, (fmi3Instance instance))
UNSUPPORTED(fmi3GetFloat32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Float32 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t
            nValueReferences, fmi3Int8 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt8 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Int16 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt16 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Int32 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt32 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Int64 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt64 values[], size_t nValues))
UNSUPPORTED(fmi3GetBoolean, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Boolean values[], size_t nValues))
UNSUPPORTED(fmi3GetString, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3String values[], size_t nValues))
UNSUPPORTED(fmi3GetBinary, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues))
UNSUPPORTED(fmi3GetClock, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Clock values[]))
UNSUPPORTED(fmi3SetFloat32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Float32 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t
            nValueReferences, const fmi3Int8 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt8 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int16 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt16 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int32 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt32 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int64 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt64 values[], size_t nValues))
UNSUPPORTED(fmi3SetBoolean, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Boolean values[], size_t nValues))
UNSUPPORTED(fmi3SetString, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3String values[], size_t nValues))
UNSUPPORTED(fmi3SetBinary, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[], size_t
            nValues))
UNSUPPORTED(fmi3SetClock, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Clock values[]))
UNSUPPORTED(fmi3GetNumberOfVariableDependencies, (fmi3Instance instance, fmi3ValueReference
            valueReference, size_t* nDependencies))
UNSUPPORTED(fmi3GetVariableDependencies, (fmi3Instance instance, fmi3ValueReference dependent,
            size_t elementIndicesOfDependent[], fmi3ValueReference independents[], size_t
            elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[], size_t
            nDependencies))
UNSUPPORTED(fmi3GetFMUState, (fmi3Instance instance, fmi3FMUState* FMUState))
UNSUPPORTED(fmi3SetFMUState, (fmi3Instance instance, fmi3FMUState FMUState))
UNSUPPORTED(fmi3FreeFMUState, (fmi3Instance instance, fmi3FMUState* FMUState))
UNSUPPORTED(fmi3SerializedFMUStateSize, (fmi3Instance instance, fmi3FMUState FMUState, size_t*
            size))
UNSUPPORTED(fmi3SerializeFMUState, (fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte
            serializedState[], size_t size))
UNSUPPORTED(fmi3DeserializeFMUState, (fmi3Instance instance, const fmi3Byte serializedState[],
            size_t size, fmi3FMUState* FMUState))
UNSUPPORTED(fmi3GetDirectionalDerivative, (fmi3Instance instance, const fmi3ValueReference
            unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const
            fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity))
UNSUPPORTED(fmi3GetAdjointDerivative, (fmi3Instance instance, const fmi3ValueReference unknowns[],
            size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64
            seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity))
UNSUPPORTED(fmi3EnterConfigurationMode, (fmi3Instance instance))
UNSUPPORTED(fmi3ExitConfigurationMode, (fmi3Instance instance))
UNSUPPORTED(fmi3GetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference
            valueReferences[], size_t nValueReferences, fmi3Float64 intervals[],
            fmi3IntervalQualifier qualifiers[]))
UNSUPPORTED(fmi3GetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference
            valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64
            resolutions[], fmi3IntervalQualifier qualifiers[]))
UNSUPPORTED(fmi3GetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference
            valueReferences[], size_t nValueReferences, fmi3Float64 shifts[]))
UNSUPPORTED(fmi3GetShiftFraction, (fmi3Instance instance, const fmi3ValueReference
            valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64
            resolutions[]))
UNSUPPORTED(fmi3SetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference
            valueReferences[], size_t nValueReferences, const fmi3Float64 intervals[]))
UNSUPPORTED(fmi3SetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference
            valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const
            fmi3UInt64 resolutions[]))
UNSUPPORTED(fmi3SetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference
            valueReferences[], size_t nValueReferences, const fmi3Float64 shifts[]))
UNSUPPORTED(fmi3SetShiftFraction, (fmi3Instance instance, const fmi3ValueReference
            valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const
            fmi3UInt64 resolutions[]))
UNSUPPORTED(fmi3EvaluateDiscreteStates, (fmi3Instance instance))
UNSUPPORTED(fmi3UpdateDiscreteStates, (fmi3Instance instance, fmi3Boolean*
            discreteStatesNeedUpdate, fmi3Boolean* terminateSimulation, fmi3Boolean*
            nominalsOfContinuousStatesChanged, fmi3Boolean* valuesOfContinuousStatesChanged,
            fmi3Boolean* nextEventTimeDefined, fmi3Float64* nextEventTime))
UNSUPPORTED(fmi3EnterContinuousTimeMode, (fmi3Instance instance))
UNSUPPORTED(fmi3CompletedIntegratorStep, (fmi3Instance instance, fmi3Boolean
            noSetFMUStatePriorToCurrentPoint, fmi3Boolean* enterEventMode, fmi3Boolean*
            terminateSimulation))
UNSUPPORTED(fmi3SetTime, (fmi3Instance instance, fmi3Float64 time))
UNSUPPORTED(fmi3SetContinuousStates, (fmi3Instance instance, const fmi3Float64 continuousStates[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetContinuousStateDerivatives, (fmi3Instance instance, fmi3Float64 derivatives[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetEventIndicators, (fmi3Instance instance, fmi3Float64 eventIndicators[], size_t
            nEventIndicators))
UNSUPPORTED(fmi3GetContinuousStates, (fmi3Instance instance, fmi3Float64 continuousStates[], size_t
            nContinuousStates))
UNSUPPORTED(fmi3GetNominalsOfContinuousStates, (fmi3Instance instance, fmi3Float64 nominals[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetNumberOfEventIndicators, (fmi3Instance instance, size_t* nEventIndicators))
UNSUPPORTED(fmi3GetNumberOfContinuousStates, (fmi3Instance instance, size_t* nContinuousStates))
UNSUPPORTED(fmi3GetOutputDerivatives, (fmi3Instance instance, const fmi3ValueReference
            valueReferences[], size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64
            values[], size_t nValues))
UNSUPPORTED(fmi3ActivateModelPartition, (fmi3Instance instance, fmi3ValueReference clockReference,
            fmi3Float64 activationTime))
