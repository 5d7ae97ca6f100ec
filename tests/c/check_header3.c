/*
 * Compile-time and link-time check of the FMU's FMI 3.0 C interface.
 *
 * Includes the standard fmi3Functions.h (as shipped with fmpy) together
 * with the cbindgen header include/beamstop_fmi3.h: any declaration that
 * disagrees with the standard is a "conflicting types" error under
 * -Werror. Every function of fmi3Functions.h is then assigned to a
 * variable of its standard pointer type, so a missing or differently
 * typed export fails to compile or to link.
 *
 * Built by tests/python/test_c_header.py:
 *   gcc -std=c99 -Wall -Wextra -Werror -I<fmpy>/c-code -Iinclude tests/c/check_header3.c
 *       -Ltarget/release -lbeamstop_fmu -Wl,-rpath,target/release
 *
 * Run without arguments: prints fmi3GetVersion() and the number of
 * functions. Run with <resource path> <instantiation token> <vr of w_stop>
 * <vr of lambda>: also instantiates the FMU (no event mode, no early
 * return: the FMI 2.0 FMU's steps), steps the default scene to t = 1 and
 * prints w_stop, lambda and time (value references come from
 * modelDescription.xml; "time" is the last one).
 */

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "beamstop_fmi3.h"

static fmi3GetVersionTYPE *p_GetVersion = fmi3GetVersion;
static fmi3SetDebugLoggingTYPE *p_SetDebugLogging = fmi3SetDebugLogging;
static fmi3InstantiateModelExchangeTYPE *p_InstantiateModelExchange = fmi3InstantiateModelExchange;
static fmi3InstantiateCoSimulationTYPE *p_InstantiateCoSimulation = fmi3InstantiateCoSimulation;
static fmi3InstantiateScheduledExecutionTYPE *p_InstantiateScheduledExecution = fmi3InstantiateScheduledExecution;
static fmi3FreeInstanceTYPE *p_FreeInstance = fmi3FreeInstance;
static fmi3EnterInitializationModeTYPE *p_EnterInitializationMode = fmi3EnterInitializationMode;
static fmi3ExitInitializationModeTYPE *p_ExitInitializationMode = fmi3ExitInitializationMode;
static fmi3EnterEventModeTYPE *p_EnterEventMode = fmi3EnterEventMode;
static fmi3TerminateTYPE *p_Terminate = fmi3Terminate;
static fmi3ResetTYPE *p_Reset = fmi3Reset;
static fmi3GetFloat32TYPE *p_GetFloat32 = fmi3GetFloat32;
static fmi3GetFloat64TYPE *p_GetFloat64 = fmi3GetFloat64;
static fmi3GetInt8TYPE *p_GetInt8 = fmi3GetInt8;
static fmi3GetUInt8TYPE *p_GetUInt8 = fmi3GetUInt8;
static fmi3GetInt16TYPE *p_GetInt16 = fmi3GetInt16;
static fmi3GetUInt16TYPE *p_GetUInt16 = fmi3GetUInt16;
static fmi3GetInt32TYPE *p_GetInt32 = fmi3GetInt32;
static fmi3GetUInt32TYPE *p_GetUInt32 = fmi3GetUInt32;
static fmi3GetInt64TYPE *p_GetInt64 = fmi3GetInt64;
static fmi3GetUInt64TYPE *p_GetUInt64 = fmi3GetUInt64;
static fmi3GetBooleanTYPE *p_GetBoolean = fmi3GetBoolean;
static fmi3GetStringTYPE *p_GetString = fmi3GetString;
static fmi3GetBinaryTYPE *p_GetBinary = fmi3GetBinary;
static fmi3GetClockTYPE *p_GetClock = fmi3GetClock;
static fmi3SetFloat32TYPE *p_SetFloat32 = fmi3SetFloat32;
static fmi3SetFloat64TYPE *p_SetFloat64 = fmi3SetFloat64;
static fmi3SetInt8TYPE *p_SetInt8 = fmi3SetInt8;
static fmi3SetUInt8TYPE *p_SetUInt8 = fmi3SetUInt8;
static fmi3SetInt16TYPE *p_SetInt16 = fmi3SetInt16;
static fmi3SetUInt16TYPE *p_SetUInt16 = fmi3SetUInt16;
static fmi3SetInt32TYPE *p_SetInt32 = fmi3SetInt32;
static fmi3SetUInt32TYPE *p_SetUInt32 = fmi3SetUInt32;
static fmi3SetInt64TYPE *p_SetInt64 = fmi3SetInt64;
static fmi3SetUInt64TYPE *p_SetUInt64 = fmi3SetUInt64;
static fmi3SetBooleanTYPE *p_SetBoolean = fmi3SetBoolean;
static fmi3SetStringTYPE *p_SetString = fmi3SetString;
static fmi3SetBinaryTYPE *p_SetBinary = fmi3SetBinary;
static fmi3SetClockTYPE *p_SetClock = fmi3SetClock;
static fmi3GetNumberOfVariableDependenciesTYPE *p_GetNumberOfVariableDependencies = fmi3GetNumberOfVariableDependencies;
static fmi3GetVariableDependenciesTYPE *p_GetVariableDependencies = fmi3GetVariableDependencies;
static fmi3GetFMUStateTYPE *p_GetFMUState = fmi3GetFMUState;
static fmi3SetFMUStateTYPE *p_SetFMUState = fmi3SetFMUState;
static fmi3FreeFMUStateTYPE *p_FreeFMUState = fmi3FreeFMUState;
static fmi3SerializedFMUStateSizeTYPE *p_SerializedFMUStateSize = fmi3SerializedFMUStateSize;
static fmi3SerializeFMUStateTYPE *p_SerializeFMUState = fmi3SerializeFMUState;
static fmi3DeserializeFMUStateTYPE *p_DeserializeFMUState = fmi3DeserializeFMUState;
static fmi3GetDirectionalDerivativeTYPE *p_GetDirectionalDerivative = fmi3GetDirectionalDerivative;
static fmi3GetAdjointDerivativeTYPE *p_GetAdjointDerivative = fmi3GetAdjointDerivative;
static fmi3EnterConfigurationModeTYPE *p_EnterConfigurationMode = fmi3EnterConfigurationMode;
static fmi3ExitConfigurationModeTYPE *p_ExitConfigurationMode = fmi3ExitConfigurationMode;
static fmi3GetIntervalDecimalTYPE *p_GetIntervalDecimal = fmi3GetIntervalDecimal;
static fmi3GetIntervalFractionTYPE *p_GetIntervalFraction = fmi3GetIntervalFraction;
static fmi3GetShiftDecimalTYPE *p_GetShiftDecimal = fmi3GetShiftDecimal;
static fmi3GetShiftFractionTYPE *p_GetShiftFraction = fmi3GetShiftFraction;
static fmi3SetIntervalDecimalTYPE *p_SetIntervalDecimal = fmi3SetIntervalDecimal;
static fmi3SetIntervalFractionTYPE *p_SetIntervalFraction = fmi3SetIntervalFraction;
static fmi3SetShiftDecimalTYPE *p_SetShiftDecimal = fmi3SetShiftDecimal;
static fmi3SetShiftFractionTYPE *p_SetShiftFraction = fmi3SetShiftFraction;
static fmi3EvaluateDiscreteStatesTYPE *p_EvaluateDiscreteStates = fmi3EvaluateDiscreteStates;
static fmi3UpdateDiscreteStatesTYPE *p_UpdateDiscreteStates = fmi3UpdateDiscreteStates;
static fmi3EnterContinuousTimeModeTYPE *p_EnterContinuousTimeMode = fmi3EnterContinuousTimeMode;
static fmi3CompletedIntegratorStepTYPE *p_CompletedIntegratorStep = fmi3CompletedIntegratorStep;
static fmi3SetTimeTYPE *p_SetTime = fmi3SetTime;
static fmi3SetContinuousStatesTYPE *p_SetContinuousStates = fmi3SetContinuousStates;
static fmi3GetContinuousStateDerivativesTYPE *p_GetContinuousStateDerivatives = fmi3GetContinuousStateDerivatives;
static fmi3GetEventIndicatorsTYPE *p_GetEventIndicators = fmi3GetEventIndicators;
static fmi3GetContinuousStatesTYPE *p_GetContinuousStates = fmi3GetContinuousStates;
static fmi3GetNominalsOfContinuousStatesTYPE *p_GetNominalsOfContinuousStates = fmi3GetNominalsOfContinuousStates;
static fmi3GetNumberOfEventIndicatorsTYPE *p_GetNumberOfEventIndicators = fmi3GetNumberOfEventIndicators;
static fmi3GetNumberOfContinuousStatesTYPE *p_GetNumberOfContinuousStates = fmi3GetNumberOfContinuousStates;
static fmi3EnterStepModeTYPE *p_EnterStepMode = fmi3EnterStepMode;
static fmi3GetOutputDerivativesTYPE *p_GetOutputDerivatives = fmi3GetOutputDerivatives;
static fmi3DoStepTYPE *p_DoStep = fmi3DoStep;
static fmi3ActivateModelPartitionTYPE *p_ActivateModelPartition = fmi3ActivateModelPartition;

static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    fprintf(stderr, "[%d|%s] %s\n", (int)status, category ? category : "?", message ? message : "");
}

static int run_scene(const char *resources, const char *token, fmi3ValueReference vr_w, fmi3ValueReference vr_lambda,
                     fmi3ValueReference vr_time) {
    fmi3Instance c = p_InstantiateCoSimulation("c_check3", token, resources, fmi3False, fmi3False, fmi3False, fmi3False,
                                               NULL, 0, NULL, logger, NULL);
    fmi3ValueReference vr[3];
    fmi3Float64 values[3];
    fmi3Float64 t = 0.0;
    int k;
    vr[0] = vr_w;
    vr[1] = vr_lambda;
    vr[2] = vr_time;
    if (c == NULL) {
        fprintf(stderr, "fmi3InstantiateCoSimulation returned NULL\n");
        return 2;
    }
    if (p_EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0) != fmi3OK ||
        p_ExitInitializationMode(c) != fmi3OK) {
        fprintf(stderr, "initialization failed\n");
        p_FreeInstance(c);
        return 3;
    }
    for (k = 1; k <= 10; k++) {
        fmi3Float64 next = k * 0.1;
        fmi3Boolean event = fmi3True, terminate = fmi3True, early = fmi3True;
        fmi3Float64 last = -1.0;
        if (p_DoStep(c, t, next - t, fmi3True, &event, &terminate, &early, &last) != fmi3OK || event || terminate ||
            early || last != next) {
            fprintf(stderr, "fmi3DoStep failed at t = %g\n", t);
            p_FreeInstance(c);
            return 4;
        }
        t = next;
    }
    if (p_GetFloat64(c, vr, 3, values, 3) != fmi3OK) {
        p_FreeInstance(c);
        return 5;
    }
    printf("w_stop=%.17g\nlambda=%.17g\ntime=%.17g\n", values[0], values[1], values[2]);
    if (p_SetTime(c, 1.0) != fmi3Error) { /* Model Exchange: refused */
        p_FreeInstance(c);
        return 6;
    }
    if (p_GetFloat64(c, vr, 3, values, 2) != fmi3Error) { /* nValues != nValueReferences: refused */
        p_FreeInstance(c);
        return 7;
    }
    p_Terminate(c);
    p_FreeInstance(c);
    return 0;
}

int main(int argc, char **argv) {
    /* Every pointer, so that none is unused and none is NULL. */
    void (*all_functions[])(void) = {
        (void (*)(void))p_GetVersion,
        (void (*)(void))p_SetDebugLogging,
        (void (*)(void))p_InstantiateModelExchange,
        (void (*)(void))p_InstantiateCoSimulation,
        (void (*)(void))p_InstantiateScheduledExecution,
        (void (*)(void))p_FreeInstance,
        (void (*)(void))p_EnterInitializationMode,
        (void (*)(void))p_ExitInitializationMode,
        (void (*)(void))p_EnterEventMode,
        (void (*)(void))p_Terminate,
        (void (*)(void))p_Reset,
        (void (*)(void))p_GetFloat32,
        (void (*)(void))p_GetFloat64,
        (void (*)(void))p_GetInt8,
        (void (*)(void))p_GetUInt8,
        (void (*)(void))p_GetInt16,
        (void (*)(void))p_GetUInt16,
        (void (*)(void))p_GetInt32,
        (void (*)(void))p_GetUInt32,
        (void (*)(void))p_GetInt64,
        (void (*)(void))p_GetUInt64,
        (void (*)(void))p_GetBoolean,
        (void (*)(void))p_GetString,
        (void (*)(void))p_GetBinary,
        (void (*)(void))p_GetClock,
        (void (*)(void))p_SetFloat32,
        (void (*)(void))p_SetFloat64,
        (void (*)(void))p_SetInt8,
        (void (*)(void))p_SetUInt8,
        (void (*)(void))p_SetInt16,
        (void (*)(void))p_SetUInt16,
        (void (*)(void))p_SetInt32,
        (void (*)(void))p_SetUInt32,
        (void (*)(void))p_SetInt64,
        (void (*)(void))p_SetUInt64,
        (void (*)(void))p_SetBoolean,
        (void (*)(void))p_SetString,
        (void (*)(void))p_SetBinary,
        (void (*)(void))p_SetClock,
        (void (*)(void))p_GetNumberOfVariableDependencies,
        (void (*)(void))p_GetVariableDependencies,
        (void (*)(void))p_GetFMUState,
        (void (*)(void))p_SetFMUState,
        (void (*)(void))p_FreeFMUState,
        (void (*)(void))p_SerializedFMUStateSize,
        (void (*)(void))p_SerializeFMUState,
        (void (*)(void))p_DeserializeFMUState,
        (void (*)(void))p_GetDirectionalDerivative,
        (void (*)(void))p_GetAdjointDerivative,
        (void (*)(void))p_EnterConfigurationMode,
        (void (*)(void))p_ExitConfigurationMode,
        (void (*)(void))p_GetIntervalDecimal,
        (void (*)(void))p_GetIntervalFraction,
        (void (*)(void))p_GetShiftDecimal,
        (void (*)(void))p_GetShiftFraction,
        (void (*)(void))p_SetIntervalDecimal,
        (void (*)(void))p_SetIntervalFraction,
        (void (*)(void))p_SetShiftDecimal,
        (void (*)(void))p_SetShiftFraction,
        (void (*)(void))p_EvaluateDiscreteStates,
        (void (*)(void))p_UpdateDiscreteStates,
        (void (*)(void))p_EnterContinuousTimeMode,
        (void (*)(void))p_CompletedIntegratorStep,
        (void (*)(void))p_SetTime,
        (void (*)(void))p_SetContinuousStates,
        (void (*)(void))p_GetContinuousStateDerivatives,
        (void (*)(void))p_GetEventIndicators,
        (void (*)(void))p_GetContinuousStates,
        (void (*)(void))p_GetNominalsOfContinuousStates,
        (void (*)(void))p_GetNumberOfEventIndicators,
        (void (*)(void))p_GetNumberOfContinuousStates,
        (void (*)(void))p_EnterStepMode,
        (void (*)(void))p_GetOutputDerivatives,
        (void (*)(void))p_DoStep,
        (void (*)(void))p_ActivateModelPartition,
    };
    size_t i;
    for (i = 0; i < sizeof all_functions / sizeof all_functions[0]; i++) {
        if (all_functions[i] == NULL) {
            fprintf(stderr, "function %u is NULL\n", (unsigned)i);
            return 1;
        }
    }
    printf("functions=%u\n", (unsigned)(sizeof all_functions / sizeof all_functions[0]));
    printf("version=%s\n", p_GetVersion());
    if (strcmp(p_GetVersion(), fmi3Version) != 0) {
        return 1;
    }
    /* Model Exchange and Scheduled Execution: no instance, no crash. */
    if (p_InstantiateModelExchange("x", "{}", "/", fmi3False, fmi3False, NULL, NULL) != NULL ||
        p_InstantiateScheduledExecution("x", "{}", "/", fmi3False, fmi3False, NULL, NULL, NULL, NULL, NULL) != NULL) {
        return 1;
    }
    if (argc >= 6) {
        return run_scene(argv[1], argv[2], (fmi3ValueReference)strtoul(argv[3], NULL, 10),
                         (fmi3ValueReference)strtoul(argv[4], NULL, 10), (fmi3ValueReference)strtoul(argv[5], NULL, 10));
    }
    return 0;
}
