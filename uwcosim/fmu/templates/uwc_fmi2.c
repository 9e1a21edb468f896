/* uwc_fmi2.c - FMI 2.0 API (model exchange and co-simulation) over the uwc_model core. */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "uwc_model.h"

#define M ((uwc_inst *)instance)
#define CHECK(fn, modes) \
    if (instance == NULL || !uwc_allowed(M, fn, modes)) return fmi2Error

/* for uwc_fmi_common.h: the functions FMI 2.0 and 3.0 share */
#define FMI(name) fmi2##name
#define FMI_INSTANCE fmi2Component
#define FMI_FLOAT fmi2Real
#define FMI_FMUSTATE fmi2FMUstate
#define FMI_GET_FMUSTATE fmi2GetFMUstate
#define FMI_SET_FMUSTATE fmi2SetFMUstate
#define FMI_FREE_FMUSTATE fmi2FreeFMUstate
#define FMI_SERIALIZED_FMUSTATE_SIZE fmi2SerializedFMUstateSize
#define FMI_SERIALIZE_FMUSTATE fmi2SerializeFMUstate
#define FMI_DESERIALIZE_FMUSTATE fmi2DeSerializeFMUstate
#define FMI_GET_DERIVATIVES fmi2GetDerivatives
#include "uwc_fmi_common.h"

static void log_fmi2(uwc_inst *m, int status, const char *category, const char *message) {
    const fmi2CallbackFunctions *cb = (const fmi2CallbackFunctions *)m->callbacks;
    char buf[4096];
    size_t i, k = 0;
    if (cb == NULL || cb->logger == NULL) return;
    /* the FMI 2.0 logger takes a printf format: escape '%' */
    for (i = 0; message[i] && k + 2 < sizeof(buf); i++) {
        if (message[i] == '%') buf[k++] = '%';
        buf[k++] = message[i];
    }
    buf[k] = '\0';
    cb->logger(cb->componentEnvironment, m->name, (fmi2Status)status, category, buf);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    char path[4096];
    const char *resources = NULL;
    fmi2CallbackFunctions *cb = NULL;
    uwc_inst *m;
    (void)visible;
    if (functions != NULL) {
        cb = (fmi2CallbackFunctions *)malloc(sizeof(*cb));
        if (cb == NULL) return NULL;
        *cb = *functions;
    }
    if (fmuResourceLocation != NULL &&
        uwc_uri_to_path(fmuResourceLocation, path, sizeof(path)) == 0) {
        resources = path;
    }
    m = uwc_new(instanceName, fmuGUID, resources, fmuType == fmi2CoSimulation, loggingOn,
                log_fmi2, cb ? cb->componentEnvironment : NULL, cb);
    if (m == NULL) {
        free(cb);
        return NULL;
    }
    if (fmuType != fmi2CoSimulation && fmuType != fmi2ModelExchange) {
        uwc_log(m, UWC_ERROR, "%s: unknown fmuType %d", m->name, (int)fmuType);
        uwc_free(m);
        free(cb);
        return NULL;
    }
    return m;
}

fmi2Status fmi2SetupExperiment(fmi2Component instance, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    CHECK("fmi2SetupExperiment", UWC_INSTANTIATED);
    M->r[0] = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component instance) {
    if (instance == NULL) return fmi2Error;
    return (fmi2Status)uwc_enter_init(M, M->r[0]);
}

/* ---- getters and setters: each written once, instantiated per type ---------------- */

/* types this FMU has variables of: forward to the core */
#define FORWARD(fn, ctype, qual, impl)                                                       \
    fmi2Status fn(fmi2Component instance, const fmi2ValueReference vr[], size_t nvr,        \
                  qual ctype value[]) {                                                      \
        if (instance == NULL) return fmi2Error;                                              \
        return (fmi2Status)impl(M, vr, nvr, value);                                          \
    }

/* types this FMU has no variables of */
#define NO_VARIABLES(fn, ctype, qual)                                                        \
    fmi2Status fn(fmi2Component instance, const fmi2ValueReference vr[], size_t nvr,        \
                  qual ctype value[]) {                                                      \
        (void)vr;                                                                            \
        (void)value;                                                                         \
        return instance == NULL ? fmi2Error : (fmi2Status)uwc_no_variables(M, #fn, nvr);     \
    }

FORWARD(fmi2GetReal, fmi2Real, , uwc_get_real)
FORWARD(fmi2GetString, fmi2String, , uwc_get_string)
FORWARD(fmi2SetReal, fmi2Real, const, uwc_set_real)
FORWARD(fmi2SetString, fmi2String, const, uwc_set_string)
NO_VARIABLES(fmi2GetInteger, fmi2Integer, )
NO_VARIABLES(fmi2GetBoolean, fmi2Boolean, )
NO_VARIABLES(fmi2SetInteger, fmi2Integer, const)
NO_VARIABLES(fmi2SetBoolean, fmi2Boolean, const)

fmi2Status fmi2GetDirectionalDerivative(fmi2Component instance,
                                        const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return instance == NULL ? fmi2Error
                            : (fmi2Status)uwc_unsupported(M, "fmi2GetDirectionalDerivative");
}

/* ---- model exchange ----------------------------------------------------------------- */

fmi2Status fmi2NewDiscreteStates(fmi2Component instance, fmi2EventInfo *eventInfo) {
    CHECK("fmi2NewDiscreteStates", UWC_EVENT);
    eventInfo->newDiscreteStatesNeeded = fmi2False;
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = fmi2False;
    eventInfo->nextEventTimeDefined = fmi2False;
    eventInfo->nextEventTime = 0.0;
    return fmi2OK;
}

/* ---- co-simulation ------------------------------------------------------------------ */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component instance, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return instance == NULL ? fmi2Error
                            : (fmi2Status)uwc_unsupported(M, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component instance, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return instance == NULL ? fmi2Error
                            : (fmi2Status)uwc_unsupported(M, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2DoStep(fmi2Component instance, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentCommunicationPoint) {
    (void)noSetFMUStatePriorToCurrentCommunicationPoint;
    if (instance == NULL) return fmi2Error;
    return (fmi2Status)uwc_do_step(M, currentCommunicationPoint, communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component instance) {
    return instance == NULL ? fmi2Error : (fmi2Status)uwc_unsupported(M, "fmi2CancelStep");
}

fmi2Status fmi2GetStatus(fmi2Component instance, const fmi2StatusKind s, fmi2Status *value) {
    if (instance == NULL || s != fmi2DoStepStatus) return fmi2Discard;
    *value = M->mode == UWC_FAILED ? fmi2Error : fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component instance, const fmi2StatusKind s, fmi2Real *value) {
    if (instance == NULL || s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = M->r[0];
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component instance, const fmi2StatusKind s,
                                fmi2Integer *value) {
    (void)instance;
    (void)s;
    (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component instance, const fmi2StatusKind s,
                                fmi2Boolean *value) {
    if (instance == NULL || s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component instance, const fmi2StatusKind s, fmi2String *value) {
    (void)instance;
    (void)s;
    (void)value;
    return fmi2Discard;
}
