/* uwc_fmi_common.h - the FMI functions whose 2.0 and 3.0 forms differ only in the prefix and
 * the type names, written once. Included at the end of uwc_fmi2.c and uwc_fmi3.c, which define
 * FMI(name) (the prefixed name: fmi2##name or fmi3##name), FMI_INSTANCE, FMI_FLOAT (fmi2Real or
 * fmi3Float64), FMI_FMUSTATE, the names of the FMU-state functions (FMI_GET_FMUSTATE, ...,
 * spelt differently in the two standards) and of FMI_GET_DERIVATIVES, M and CHECK.
 */
#ifndef UWC_FMI_COMMON_H
#define UWC_FMI_COMMON_H

#define FMI_STR_(x) #x
#define FMI_STR(x) FMI_STR_(x)

/* ---- life cycle ----------------------------------------------------------------------- */

FMI(Status) FMI(SetDebugLogging)(FMI_INSTANCE instance, FMI(Boolean) loggingOn,
                                 size_t nCategories, const FMI(String) categories[]) {
    (void)nCategories;
    (void)categories;
    if (instance == NULL) return FMI(Error);
    M->logging_on = loggingOn ? 1 : 0;
    return FMI(OK);
}

void FMI(FreeInstance)(FMI_INSTANCE instance) {
    void *cb;
    if (instance == NULL) return;
    cb = (void *)M->callbacks;
    uwc_free(M);
    free(cb);
}

FMI(Status) FMI(ExitInitializationMode)(FMI_INSTANCE instance) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_exit_init(M);
}

FMI(Status) FMI(Terminate)(FMI_INSTANCE instance) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_terminate(M);
}

FMI(Status) FMI(Reset)(FMI_INSTANCE instance) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_reset(M);
}

/* ---- FMU state ------------------------------------------------------------------------ */

FMI(Status) FMI_GET_FMUSTATE(FMI_INSTANCE instance, FMI_FMUSTATE *FMUState) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_state_get(M, FMUState);
}

FMI(Status) FMI_SET_FMUSTATE(FMI_INSTANCE instance, FMI_FMUSTATE FMUState) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_state_set(M, FMUState);
}

FMI(Status) FMI_FREE_FMUSTATE(FMI_INSTANCE instance, FMI_FMUSTATE *FMUState) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_state_free(M, FMUState);
}

FMI(Status) FMI_SERIALIZED_FMUSTATE_SIZE(FMI_INSTANCE instance, FMI_FMUSTATE FMUState,
                                         size_t *size) {
    (void)FMUState;
    if (instance == NULL) return FMI(Error);
    *size = uwc_state_size();
    return FMI(OK);
}

FMI(Status) FMI_SERIALIZE_FMUSTATE(FMI_INSTANCE instance, FMI_FMUSTATE FMUState,
                                   FMI(Byte) serializedState[], size_t size) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_state_serialize(M, FMUState, (unsigned char *)serializedState, size);
}

FMI(Status) FMI_DESERIALIZE_FMUSTATE(FMI_INSTANCE instance, const FMI(Byte) serializedState[],
                                     size_t size, FMI_FMUSTATE *FMUState) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_state_deserialize(M, (const unsigned char *)serializedState, size,
                                              FMUState);
}

/* ---- model exchange ------------------------------------------------------------------- */

FMI(Status) FMI(EnterEventMode)(FMI_INSTANCE instance) {
    CHECK(FMI_STR(FMI(EnterEventMode)), UWC_EVENT | UWC_CONT);
    M->mode = UWC_EVENT;
    return FMI(OK);
}

FMI(Status) FMI(EnterContinuousTimeMode)(FMI_INSTANCE instance) {
    CHECK(FMI_STR(FMI(EnterContinuousTimeMode)), UWC_EVENT);
    M->mode = UWC_CONT;
    return FMI(OK);
}

FMI(Status) FMI(CompletedIntegratorStep)(FMI_INSTANCE instance,
                                         FMI(Boolean) noSetFMUStatePriorToCurrentPoint,
                                         FMI(Boolean) *enterEventMode,
                                         FMI(Boolean) *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK(FMI_STR(FMI(CompletedIntegratorStep)), UWC_CONT);
    *enterEventMode = FMI(False);
    *terminateSimulation = FMI(False);
    return FMI(OK);
}

FMI(Status) FMI(SetTime)(FMI_INSTANCE instance, FMI_FLOAT time) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_set_time(M, time);
}

FMI(Status) FMI(SetContinuousStates)(FMI_INSTANCE instance, const FMI_FLOAT x[], size_t nx) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_set_states(M, x, nx);
}

FMI(Status) FMI_GET_DERIVATIVES(FMI_INSTANCE instance, FMI_FLOAT derivatives[], size_t nx) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_get_derivatives(M, derivatives, nx);
}

FMI(Status) FMI(GetEventIndicators)(FMI_INSTANCE instance, FMI_FLOAT eventIndicators[],
                                    size_t ni) {
    (void)eventIndicators;
    return instance == NULL
               ? FMI(Error)
               : (FMI(Status))uwc_no_variables(M, FMI_STR(FMI(GetEventIndicators)), ni);
}

FMI(Status) FMI(GetContinuousStates)(FMI_INSTANCE instance, FMI_FLOAT x[], size_t nx) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_get_states(M, x, nx);
}

FMI(Status) FMI(GetNominalsOfContinuousStates)(FMI_INSTANCE instance, FMI_FLOAT nominals[],
                                               size_t nx) {
    if (instance == NULL) return FMI(Error);
    return (FMI(Status))uwc_get_nominals(M, nominals, nx);
}

#endif
