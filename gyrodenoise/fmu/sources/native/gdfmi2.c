/*
 * gdfmi2.c -- the FMI 2.0 entry points (fmi2*) of the native FMUs: thin wrappers over the
 * shared layer gdfmi.c (which includes this file when GD_FMI_VERSION is 2).
 */

/* ------------------------------------------------------------ general API */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    BEGIN("fmi2SetDebugLogging", MASK_SET_DEBUG_LOGGING);
    return (fmi2Status)gdl_set_debug_logging(c, "fmi2SetDebugLogging", loggingOn, nCategories, categories);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    gdfmi_inst_t tmp;
    int k;
    (void)visible;
    memset(&tmp, 0, sizeof tmp);
    if (functions) tmp.cb = *functions;
    tmp.name = (char *)(instanceName ? instanceName : "");
    tmp.logging_on = 1;
    for (k = 0; k < N_CATS; k++) tmp.cat_on[k] = 1;
    if (!functions) return NULL; /* nowhere to report to */
    if ((functions->allocateMemory == NULL) != (functions->freeMemory == NULL)) {
        gdfmi_log(&tmp, GD_ERROR, "fmi2Instantiate: allocateMemory and freeMemory must both be given");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation && instanceName && instanceName[0]) {
        gdfmi_log(&tmp, GD_ERROR, "fmi2Instantiate: %s supports co-simulation only (fmuType %d)",
                  GDM->identifier, (int)fmuType);
        return NULL;
    }
    return gdl_instantiate(&tmp, instanceName, fmuGUID, fmuResourceLocation, loggingOn);
}

void fmi2FreeInstance(fmi2Component comp) { gdl_free_instance(comp); }

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN("fmi2SetupExperiment", MASK_SETUP_EXPERIMENT);
    (void)toleranceDefined;
    (void)tolerance;
    return (fmi2Status)gdl_setup_experiment(c, "fmi2SetupExperiment", startTime, stopTimeDefined, stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    BEGIN("fmi2EnterInitializationMode", MASK_ENTER_INIT);
    c->k.phase = ST_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    BEGIN("fmi2ExitInitializationMode", MASK_EXIT_INIT);
    return (fmi2Status)gdl_exit_initialization_mode(c);
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    BEGIN("fmi2Terminate", MASK_TERMINATE);
    return (fmi2Status)gdl_terminate(c);
}

fmi2Status fmi2Reset(fmi2Component comp) {
    BEGIN("fmi2Reset", MASK_RESET);
    return (fmi2Status)gdl_reset(c);
}

/* -------------------------------------------------------- getters/setters */
fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    BEGIN("fmi2GetReal", MASK_GET);
    return (fmi2Status)gdl_get_real(c, "fmi2GetReal", vr, nvr, value, nvr);
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    BEGIN("fmi2SetReal", MASK_SET);
    return (fmi2Status)gdl_set_real(c, "fmi2SetReal", vr, nvr, value, nvr);
}

/* fmi2Get<Type> / fmi2Set<Type> of Integer, Boolean, String: the layer checks, then each value */
#define GDFMI2_GETTER(fn, ctype, type, expr)                                                     \
    fmi2Status fn(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, ctype value[]) { \
        size_t i;                                                                                \
        gdfmi_inst_t tmp, *src;                                                                  \
        BEGIN(#fn, MASK_GET);                                                                    \
        if (gdl_check_get(c, #fn, vr, nvr, value, nvr, type) != GD_OK) return fmi2Error;         \
        src = read_source(c, vr, nvr, &tmp); /* in initialisation mode: the first sample's */    \
        for (i = 0; i < nvr; i++) value[i] = expr;                                               \
        if (src != c) drop_scratch(&tmp);                                                        \
        return fmi2OK;                                                                           \
    }
GDFMI2_GETTER(fmi2GetInteger, fmi2Integer, T_INTEGER, GDM->get_integer(src, vr[i]))
GDFMI2_GETTER(fmi2GetBoolean, fmi2Boolean, T_BOOLEAN, GDM->get_boolean(src, vr[i]) ? fmi2True : fmi2False)
GDFMI2_GETTER(fmi2GetString, fmi2String, T_STRING, GDM->get_string(src, vr[i]))
#undef GDFMI2_GETTER

#define GDFMI2_SETTER(fn, ctype, type, store)                                                          \
    fmi2Status fn(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const ctype value[]) { \
        size_t i;                                                                                      \
        BEGIN(#fn, MASK_SET);                                                                          \
        if (gdl_check_set(c, #fn, vr, nvr, value, nvr, type) != GD_OK) return fmi2Error;               \
        for (i = 0; i < nvr; i++) store;                                                               \
        return fmi2OK;                                                                                 \
    }
GDFMI2_SETTER(fmi2SetInteger, fmi2Integer, T_INTEGER, *GDM->int_ref(c->m, vr[i]) = value[i])
GDFMI2_SETTER(fmi2SetBoolean, fmi2Boolean, T_BOOLEAN, *GDM->int_ref(c->m, vr[i]) = value[i] ? 1 : 0)
#undef GDFMI2_SETTER

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    BEGIN("fmi2SetString", MASK_SET);
    return (fmi2Status)gdl_set_string(c, "fmi2SetString", vr, nvr, value, nvr);
}

/* --------------------------------------------------------------- FMU state */
fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    return (fmi2Status)gdl_get_fmu_state(comp, FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate) {
    return (fmi2Status)gdl_set_fmu_state(comp, FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    return (fmi2Status)gdl_free_fmu_state(comp, FMUstate);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate, size_t *size) {
    return (fmi2Status)gdl_serialized_size(comp, FMUstate, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    return (fmi2Status)gdl_serialize(comp, FMUstate, (unsigned char *)serializedState, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    return (fmi2Status)gdl_deserialize(comp, (const unsigned char *)serializedState, size, FMUstate);
}

/* ------------------------------------------------- not provided by these FMUs */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    gdfmi_inst_t *c = inst_of(comp);
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    if (!c) return fmi2Error;
    return (fmi2Status)gdfmi_fail(c, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=false)");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    gdfmi_inst_t *c = inst_of(comp);
    (void)vr; (void)nvr; (void)order; (void)value;
    if (!c) return fmi2Error;
    return (fmi2Status)gdfmi_fail(c, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    gdfmi_inst_t *c = inst_of(comp);
    (void)vr; (void)nvr; (void)order; (void)value;
    if (!c) return fmi2Error;
    return (fmi2Status)gdfmi_fail(c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder=0)");
}

/* --------------------------------------------------------------- stepping */
fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    BEGIN("fmi2DoStep", MASK_DO_STEP);
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)gdl_do_step(c, currentCommunicationPoint, communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component comp) {
    gdfmi_inst_t *c = inst_of(comp);
    if (!c) return fmi2Error;
    return (fmi2Status)gdfmi_fail(c, "fmi2CancelStep: no asynchronous step to cancel (fmi2DoStep never returns fmi2Pending)");
}

/* a status kind this FMU does not provide: fmi2Discard, the reason logged */
static fmi2Status no_status(const gdfmi_inst_t *c, const char *fn, int kind, const char *why) {
    gdfmi_log(c, GD_DISCARD, "%s: status kind %d not available%s", fn, kind, why);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value) {
    BEGIN("fmi2GetStatus", MASK_STATUS);
    (void)value;
    return no_status(c, "fmi2GetStatus", (int)s, " (no asynchronous steps)");
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    BEGIN("fmi2GetRealStatus", MASK_STATUS);
    if (s != fmi2LastSuccessfulTime || !value) return no_status(c, "fmi2GetRealStatus", (int)s, "");
    *value = c->k.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value) {
    BEGIN("fmi2GetIntegerStatus", MASK_STATUS);
    (void)value;
    return no_status(c, "fmi2GetIntegerStatus", (int)s, "");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value) {
    BEGIN("fmi2GetBooleanStatus", MASK_STATUS);
    if (s != fmi2Terminated || !value) return no_status(c, "fmi2GetBooleanStatus", (int)s, "");
    *value = fmi2False; /* the slave never asks to end the simulation */
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value) {
    BEGIN("fmi2GetStringStatus", MASK_STATUS);
    (void)value;
    return no_status(c, "fmi2GetStringStatus", (int)s, "");
}
