/* uwc_fmi2.c - FMI 2.0 API (model exchange and co-simulation) over the uwc_model core. */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "uwc_model.h"

#define M ((uwc_inst *)c)
#define CHECK(fn, modes) \
    if (c == NULL || !uwc_allowed(M, fn, modes)) return fmi2Error

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

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)nCategories;
    (void)categories;
    if (c == NULL) return fmi2Error;
    M->logging_on = loggingOn ? 1 : 0;
    return fmi2OK;
}

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

void fmi2FreeInstance(fmi2Component c) {
    void *cb;
    if (c == NULL) return;
    cb = (void *)M->callbacks;
    uwc_free(M);
    free(cb);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
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

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_enter_init(M, M->r[0]);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_exit_init(M);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_terminate(M);
}

fmi2Status fmi2Reset(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_reset(M);
}

/* ---- getters and setters: each written once, instantiated per type ---------------- */

/* types this FMU has variables of: forward to the core */
#define FORWARD(fn, ctype, qual, impl)                                                       \
    fmi2Status fn(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,               \
                  qual ctype value[]) {                                                      \
        if (c == NULL) return fmi2Error;                                                     \
        return (fmi2Status)impl(M, vr, nvr, value);                                          \
    }

/* types this FMU has no variables of */
#define NO_VARIABLES(fn, ctype, qual)                                                        \
    fmi2Status fn(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,               \
                  qual ctype value[]) {                                                      \
        (void)vr;                                                                            \
        (void)value;                                                                         \
        return c == NULL ? fmi2Error : (fmi2Status)uwc_no_variables(M, #fn, nvr);            \
    }

FORWARD(fmi2GetReal, fmi2Real, , uwc_get_real)
FORWARD(fmi2GetString, fmi2String, , uwc_get_string)
FORWARD(fmi2SetReal, fmi2Real, const, uwc_set_real)
FORWARD(fmi2SetString, fmi2String, const, uwc_set_string)
NO_VARIABLES(fmi2GetInteger, fmi2Integer, )
NO_VARIABLES(fmi2GetBoolean, fmi2Boolean, )
NO_VARIABLES(fmi2SetInteger, fmi2Integer, const)
NO_VARIABLES(fmi2SetBoolean, fmi2Boolean, const)

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_state_get(M, FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_state_set(M, FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_state_free(M, FMUstate);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate;
    if (c == NULL) return fmi2Error;
    *size = uwc_state_size();
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serialized[],
                                 size_t size) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_state_serialize(M, FMUstate, (unsigned char *)serialized, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serialized[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_state_deserialize(M, (const unsigned char *)serialized, size,
                                             FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return c == NULL ? fmi2Error : (fmi2Status)uwc_unsupported(M, "fmi2GetDirectionalDerivative");
}

/* ---- model exchange ----------------------------------------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    CHECK("fmi2EnterEventMode", UWC_EVENT | UWC_CONT);
    M->mode = UWC_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    CHECK("fmi2NewDiscreteStates", UWC_EVENT);
    eventInfo->newDiscreteStatesNeeded = fmi2False;
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = fmi2False;
    eventInfo->nextEventTimeDefined = fmi2False;
    eventInfo->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    CHECK("fmi2EnterContinuousTimeMode", UWC_EVENT);
    M->mode = UWC_CONT;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c,
                                       fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK("fmi2CompletedIntegratorStep", UWC_CONT);
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_set_time(M, time);
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_set_states(M, x, nx);
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_get_derivatives(M, derivatives, nx);
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    (void)eventIndicators;
    return c == NULL ? fmi2Error : (fmi2Status)uwc_no_variables(M, "fmi2GetEventIndicators", ni);
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_get_states(M, x, nx);
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_get_nominals(M, x_nominal, nx);
}

/* ---- co-simulation ------------------------------------------------------------------ */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return c == NULL ? fmi2Error : (fmi2Status)uwc_unsupported(M, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return c == NULL ? fmi2Error
                     : (fmi2Status)uwc_unsupported(M, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentCommunicationPoint) {
    (void)noSetFMUStatePriorToCurrentCommunicationPoint;
    if (c == NULL) return fmi2Error;
    return (fmi2Status)uwc_do_step(M, currentCommunicationPoint, communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return c == NULL ? fmi2Error : (fmi2Status)uwc_unsupported(M, "fmi2CancelStep");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    if (c == NULL || s != fmi2DoStepStatus) return fmi2Discard;
    *value = M->mode == UWC_FAILED ? fmi2Error : fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (c == NULL || s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = M->r[0];
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (c == NULL || s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}
