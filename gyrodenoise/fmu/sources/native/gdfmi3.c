/*
 * gdfmi3.c -- the FMI 3.0 entry points (fmi3*) of the native FMUs: thin wrappers over the
 * shared layer gdfmi.c (which includes this file when GD_FMI_VERSION is 3). Co-Simulation
 * only, without event mode, clocks or intermediate updates: a call of another interface
 * type answers fmi3Error with the reason logged (instantiation: NULL).
 * The state machine is the layer's: instantiated -> initialization mode -> step mode
 * (the layer's stepComplete) -> terminated; error state as in FMI 2.0.
 */

/* ------------------------------------------------------------ general API */
const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    void *comp = instance;
    BEGIN("fmi3SetDebugLogging", MASK_SET_DEBUG_LOGGING);
    return (fmi3Status)gdl_set_debug_logging(c, "fmi3SetDebugLogging", loggingOn, nCategories, categories);
}

static fmi3Instance no_instance(fmi3String instanceName, fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                const char *fn) {
    gdfmi_inst_t tmp;
    int k;
    memset(&tmp, 0, sizeof tmp);
    tmp.cb.env = env;
    tmp.cb.logger = log;
    tmp.name = (char *)(instanceName ? instanceName : "");
    tmp.logging_on = 1;
    for (k = 0; k < N_CATS; k++) tmp.cat_on[k] = 1;
    gdfmi_log(&tmp, GD_ERROR, "%s: %s supports co-simulation only (fmi3InstantiateCoSimulation)", fn,
              GDM->identifier);
    return NULL;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    return no_instance(instanceName, instanceEnvironment, logMessage, "fmi3InstantiateModelExchange");
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible,
                                               fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    return no_instance(instanceName, instanceEnvironment, logMessage, "fmi3InstantiateScheduledExecution");
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    gdfmi_inst_t tmp;
    int k;
    (void)visible; (void)earlyReturnAllowed; (void)requiredIntermediateVariables; (void)intermediateUpdate;
    memset(&tmp, 0, sizeof tmp);
    tmp.cb.env = instanceEnvironment;
    tmp.cb.logger = logMessage;
    tmp.name = (char *)(instanceName ? instanceName : "");
    tmp.logging_on = 1;
    for (k = 0; k < N_CATS; k++) tmp.cat_on[k] = 1;
    if (eventModeUsed) { /* hasEventMode="false": the importer must not ask for it */
        gdfmi_log(&tmp, GD_ERROR, "fmi3InstantiateCoSimulation: eventModeUsed = true, but %s has no event "
                  "mode (hasEventMode=\"false\")", GDM->identifier);
        return NULL;
    }
    if (nRequiredIntermediateVariables > 0) {
        gdfmi_log(&tmp, GD_ERROR, "fmi3InstantiateCoSimulation: %lu required intermediate variable(s): %s "
                  "provides none (providesIntermediateUpdate=\"false\")",
                  (unsigned long)nRequiredIntermediateVariables, GDM->identifier);
        return NULL;
    }
    return gdl_instantiate(&tmp, instanceName, instantiationToken, resourcePath, loggingOn);
}

void fmi3FreeInstance(fmi3Instance instance) { gdl_free_instance(instance); }

/* FMI 3.0 gives the experiment's times here (FMI 2.0: fmi2SetupExperiment) */
fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    void *comp = instance;
    gd_status_t st;
    BEGIN("fmi3EnterInitializationMode", MASK_ENTER_INIT);
    (void)toleranceDefined;
    (void)tolerance;
    st = gdl_setup_experiment(c, "fmi3EnterInitializationMode", startTime, stopTimeDefined, stopTime);
    if (st != GD_OK) return (fmi3Status)st;
    c->k.phase = ST_INIT;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    void *comp = instance;
    BEGIN("fmi3ExitInitializationMode", MASK_EXIT_INIT);
    return (fmi3Status)gdl_exit_initialization_mode(c);
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    void *comp = instance;
    BEGIN("fmi3Terminate", MASK_TERMINATE);
    return (fmi3Status)gdl_terminate(c);
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    void *comp = instance;
    BEGIN("fmi3Reset", MASK_RESET);
    return (fmi3Status)gdl_reset(c);
}

/* -------------------------------------------------------- getters/setters */
fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues) {
    void *comp = instance;
    BEGIN("fmi3GetFloat64", MASK_GET);
    return (fmi3Status)gdl_get_real(c, "fmi3GetFloat64", vr, nvr, values, nValues);
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues) {
    void *comp = instance;
    BEGIN("fmi3SetFloat64", MASK_SET);
    return (fmi3Status)gdl_set_real(c, "fmi3SetFloat64", vr, nvr, values, nValues);
}

#define GDFMI3_GETTER(fn, ctype, type, expr)                                                       \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, ctype values[], \
                  size_t nValues) {                                                                \
        void *comp = instance;                                                                     \
        size_t i;                                                                                  \
        gdfmi_inst_t tmp, *src;                                                                    \
        BEGIN(#fn, MASK_GET);                                                                      \
        if (gdl_check_get(c, #fn, vr, nvr, values, nValues, type) != GD_OK) return fmi3Error;      \
        src = read_source(c, vr, nvr, &tmp); /* in initialisation mode: the first sample's */      \
        for (i = 0; i < nvr; i++) values[i] = expr;                                                \
        if (src != c) drop_scratch(&tmp);                                                          \
        return fmi3OK;                                                                             \
    }
GDFMI3_GETTER(fmi3GetInt32, fmi3Int32, T_INTEGER, GDM->get_integer(src, vr[i]))
GDFMI3_GETTER(fmi3GetBoolean, fmi3Boolean, T_BOOLEAN, GDM->get_boolean(src, vr[i]) ? fmi3True : fmi3False)
GDFMI3_GETTER(fmi3GetString, fmi3String, T_STRING, GDM->get_string(src, vr[i]))
#undef GDFMI3_GETTER

#define GDFMI3_SETTER(fn, ctype, type, store)                                                            \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const ctype values[], \
                  size_t nValues) {                                                                      \
        void *comp = instance;                                                                           \
        size_t i;                                                                                        \
        BEGIN(#fn, MASK_SET);                                                                            \
        if (gdl_check_set(c, #fn, vr, nvr, values, nValues, type) != GD_OK) return fmi3Error;            \
        for (i = 0; i < nvr; i++) store;                                                                 \
        return fmi3OK;                                                                                   \
    }
GDFMI3_SETTER(fmi3SetInt32, fmi3Int32, T_INTEGER, *GDM->int_ref(c->m, vr[i]) = values[i])
GDFMI3_SETTER(fmi3SetBoolean, fmi3Boolean, T_BOOLEAN, *GDM->int_ref(c->m, vr[i]) = values[i] ? 1 : 0)
#undef GDFMI3_SETTER

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const fmi3String values[], size_t nValues) {
    void *comp = instance;
    BEGIN("fmi3SetString", MASK_SET);
    return (fmi3Status)gdl_set_string(c, "fmi3SetString", vr, nvr, values, nValues);
}

/* a type these FMUs declare no variable of: any value reference is unknown */
#define GDFMI3_NO_TYPE(fn, ctype, mask)                                                         \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, ctype values[], \
                  size_t nValues) {                                                             \
        void *comp = instance;                                                                  \
        BEGIN(#fn, mask);                                                                       \
        (void)values; (void)nValues;                                                            \
        if (nvr == 0) return fmi3OK;                                                            \
        return (fmi3Status)gdfmi_fail(c, "%s: value reference %u: %s declares no variable of this type", \
                                      #fn, vr ? (unsigned)vr[0] : 0u, GDM->identifier);         \
    }
GDFMI3_NO_TYPE(fmi3GetFloat32, fmi3Float32, MASK_GET)
GDFMI3_NO_TYPE(fmi3GetInt8, fmi3Int8, MASK_GET)
GDFMI3_NO_TYPE(fmi3GetUInt8, fmi3UInt8, MASK_GET)
GDFMI3_NO_TYPE(fmi3GetInt16, fmi3Int16, MASK_GET)
GDFMI3_NO_TYPE(fmi3GetUInt16, fmi3UInt16, MASK_GET)
GDFMI3_NO_TYPE(fmi3GetUInt32, fmi3UInt32, MASK_GET)
GDFMI3_NO_TYPE(fmi3GetInt64, fmi3Int64, MASK_GET)
GDFMI3_NO_TYPE(fmi3GetUInt64, fmi3UInt64, MASK_GET)
GDFMI3_NO_TYPE(fmi3SetFloat32, const fmi3Float32, MASK_SET)
GDFMI3_NO_TYPE(fmi3SetInt8, const fmi3Int8, MASK_SET)
GDFMI3_NO_TYPE(fmi3SetUInt8, const fmi3UInt8, MASK_SET)
GDFMI3_NO_TYPE(fmi3SetInt16, const fmi3Int16, MASK_SET)
GDFMI3_NO_TYPE(fmi3SetUInt16, const fmi3UInt16, MASK_SET)
GDFMI3_NO_TYPE(fmi3SetUInt32, const fmi3UInt32, MASK_SET)
GDFMI3_NO_TYPE(fmi3SetInt64, const fmi3Int64, MASK_SET)
GDFMI3_NO_TYPE(fmi3SetUInt64, const fmi3UInt64, MASK_SET)
#undef GDFMI3_NO_TYPE

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    void *comp = instance;
    BEGIN("fmi3GetBinary", MASK_GET);
    (void)vr; (void)valueSizes; (void)values; (void)nValues;
    if (nvr == 0) return fmi3OK;
    return (fmi3Status)gdfmi_fail(c, "fmi3GetBinary: %s declares no Binary variable", GDM->identifier);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    void *comp = instance;
    BEGIN("fmi3SetBinary", MASK_SET);
    (void)vr; (void)valueSizes; (void)values; (void)nValues;
    if (nvr == 0) return fmi3OK;
    return (fmi3Status)gdfmi_fail(c, "fmi3SetBinary: %s declares no Binary variable", GDM->identifier);
}

/* --------------------------------------------------------------- FMU state */
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    return (fmi3Status)gdl_get_fmu_state(instance, FMUState);
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    return (fmi3Status)gdl_set_fmu_state(instance, FMUState);
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    return (fmi3Status)gdl_free_fmu_state(instance, FMUState);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    return (fmi3Status)gdl_serialized_size(instance, FMUState, size);
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    return (fmi3Status)gdl_serialize(instance, FMUState, (unsigned char *)serializedState, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    return (fmi3Status)gdl_deserialize(instance, (const unsigned char *)serializedState, size, FMUState);
}

/* --------------------------------------------------------------- stepping */
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    void *comp = instance;
    gd_status_t st;
    BEGIN("fmi3DoStep", MASK_DO_STEP);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime)
        return (fmi3Status)gdfmi_fail(c, "fmi3DoStep: eventHandlingNeeded, terminateSimulation, earlyReturn "
                                      "and lastSuccessfulTime must not be NULL");
    st = gdl_do_step(c, currentCommunicationPoint, communicationStepSize);
    *eventHandlingNeeded = fmi3False; /* no events */
    *terminateSimulation = fmi3False; /* the FMU never asks to end the simulation */
    *earlyReturn = fmi3False;         /* one step = one sample: never returns early */
    *lastSuccessfulTime = c->k.time;  /* the end of the step, or its start if it was refused */
    return (fmi3Status)st;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    void *comp = instance;
    BEGIN("fmi3EnterStepMode", 0); /* only from event mode, which these FMUs do not have */
    return fmi3Error;
}

/* ------------------------------------------------- not provided by these FMUs */
static fmi3Status not_provided(fmi3Instance instance, const char *fn, const char *why) {
    gdfmi_inst_t *c = inst_of(instance);
    if (!c) return fmi3Error;
    return (fmi3Status)gdfmi_fail(c, "%s: not provided (%s)", fn, why);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    return not_provided(instance, "fmi3EnterEventMode", "hasEventMode=\"false\"");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    (void)vr; (void)nvr; (void)values;
    return not_provided(instance, "fmi3GetClock", "no clocks");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    (void)vr; (void)nvr; (void)values;
    return not_provided(instance, "fmi3SetClock", "no clocks");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr, size_t *n) {
    (void)vr; (void)n;
    return not_provided(instance, "fmi3GetNumberOfVariableDependencies", "dependencies are in modelDescription.xml");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesIndependents;
    (void)dependencyKinds; (void)nDependencies;
    return not_provided(instance, "fmi3GetVariableDependencies", "dependencies are in modelDescription.xml");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed;
    (void)sensitivity; (void)nSensitivity;
    return not_provided(instance, "fmi3GetDirectionalDerivative", "providesDirectionalDerivatives=\"false\"");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed;
    (void)sensitivity; (void)nSensitivity;
    return not_provided(instance, "fmi3GetAdjointDerivative", "providesAdjointDerivatives=\"false\"");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    return not_provided(instance, "fmi3EnterConfigurationMode", "no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    return not_provided(instance, "fmi3ExitConfigurationMode", "no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)intervals; (void)qualifiers;
    return not_provided(instance, "fmi3GetIntervalDecimal", "no clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions; (void)qualifiers;
    return not_provided(instance, "fmi3GetIntervalFraction", "no clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    return not_provided(instance, "fmi3GetShiftDecimal", "no clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    return not_provided(instance, "fmi3GetShiftFraction", "no clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    (void)vr; (void)nvr; (void)intervals;
    return not_provided(instance, "fmi3SetIntervalDecimal", "no clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    return not_provided(instance, "fmi3SetIntervalFraction", "no clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    return not_provided(instance, "fmi3SetShiftDecimal", "no clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    return not_provided(instance, "fmi3SetShiftFraction", "no clocks");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    return not_provided(instance, "fmi3EvaluateDiscreteStates", "no event mode");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    (void)discreteStatesNeedUpdate; (void)terminateSimulation; (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged; (void)nextEventTimeDefined; (void)nextEventTime;
    return not_provided(instance, "fmi3UpdateDiscreteStates", "no event mode");
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    return not_provided(instance, "fmi3EnterContinuousTimeMode", "co-simulation only");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint; (void)enterEventMode; (void)terminateSimulation;
    return not_provided(instance, "fmi3CompletedIntegratorStep", "co-simulation only");
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    return not_provided(instance, "fmi3SetTime", "co-simulation only");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    return not_provided(instance, "fmi3SetContinuousStates", "co-simulation only");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives; (void)nContinuousStates;
    return not_provided(instance, "fmi3GetContinuousStateDerivatives", "co-simulation only");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    (void)eventIndicators; (void)nEventIndicators;
    return not_provided(instance, "fmi3GetEventIndicators", "co-simulation only");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    return not_provided(instance, "fmi3GetContinuousStates", "co-simulation only");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals; (void)nContinuousStates;
    return not_provided(instance, "fmi3GetNominalsOfContinuousStates", "co-simulation only");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    (void)nEventIndicators;
    return not_provided(instance, "fmi3GetNumberOfEventIndicators", "co-simulation only");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    (void)nContinuousStates;
    return not_provided(instance, "fmi3GetNumberOfContinuousStates", "co-simulation only");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)nValues;
    return not_provided(instance, "fmi3GetOutputDerivatives", "maxOutputDerivativeOrder=\"0\"");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    return not_provided(instance, "fmi3ActivateModelPartition", "co-simulation only");
}
