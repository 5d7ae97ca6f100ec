/*
 * Compile-time and link-time check of the FMU's C interface.
 *
 * Includes the standard fmi2Functions.h (as shipped with fmpy) together
 * with the cbindgen header include/beamstop_fmi2.h: any declaration that
 * disagrees with the standard is a "conflicting types" error under
 * -Werror. Every function of fmi2Functions.h is then assigned to a
 * variable of its standard pointer type, so a missing or differently
 * typed export fails to compile or to link.
 *
 * Built by tests/python/test_c_header.py:
 *   gcc -std=c99 -Wall -Werror -I<fmpy>/c-code -Iinclude tests/c/check_header.c
 *       -Ltarget/release -lbeamstop_fmu -Wl,-rpath,target/release
 *
 * Run without arguments: prints fmi2GetVersion() and fmi2GetTypesPlatform().
 * Run with <resource URI> <GUID> <vr of w_stop> <vr of lambda>: also
 * instantiates the FMU, steps the default scene to t = 1 and prints
 * w_stop and lambda (value references come from modelDescription.xml).
 */

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "beamstop_fmi2.h"

/* Common functions */
static fmi2GetTypesPlatformTYPE *p_GetTypesPlatform = fmi2GetTypesPlatform;
static fmi2GetVersionTYPE *p_GetVersion = fmi2GetVersion;
static fmi2SetDebugLoggingTYPE *p_SetDebugLogging = fmi2SetDebugLogging;
static fmi2InstantiateTYPE *p_Instantiate = fmi2Instantiate;
static fmi2FreeInstanceTYPE *p_FreeInstance = fmi2FreeInstance;
static fmi2SetupExperimentTYPE *p_SetupExperiment = fmi2SetupExperiment;
static fmi2EnterInitializationModeTYPE *p_EnterInitializationMode = fmi2EnterInitializationMode;
static fmi2ExitInitializationModeTYPE *p_ExitInitializationMode = fmi2ExitInitializationMode;
static fmi2TerminateTYPE *p_Terminate = fmi2Terminate;
static fmi2ResetTYPE *p_Reset = fmi2Reset;
static fmi2GetRealTYPE *p_GetReal = fmi2GetReal;
static fmi2GetIntegerTYPE *p_GetInteger = fmi2GetInteger;
static fmi2GetBooleanTYPE *p_GetBoolean = fmi2GetBoolean;
static fmi2GetStringTYPE *p_GetString = fmi2GetString;
static fmi2SetRealTYPE *p_SetReal = fmi2SetReal;
static fmi2SetIntegerTYPE *p_SetInteger = fmi2SetInteger;
static fmi2SetBooleanTYPE *p_SetBoolean = fmi2SetBoolean;
static fmi2SetStringTYPE *p_SetString = fmi2SetString;
static fmi2GetFMUstateTYPE *p_GetFMUstate = fmi2GetFMUstate;
static fmi2SetFMUstateTYPE *p_SetFMUstate = fmi2SetFMUstate;
static fmi2FreeFMUstateTYPE *p_FreeFMUstate = fmi2FreeFMUstate;
static fmi2SerializedFMUstateSizeTYPE *p_SerializedFMUstateSize = fmi2SerializedFMUstateSize;
static fmi2SerializeFMUstateTYPE *p_SerializeFMUstate = fmi2SerializeFMUstate;
static fmi2DeSerializeFMUstateTYPE *p_DeSerializeFMUstate = fmi2DeSerializeFMUstate;
static fmi2GetDirectionalDerivativeTYPE *p_GetDirectionalDerivative = fmi2GetDirectionalDerivative;

/* Model Exchange */
static fmi2EnterEventModeTYPE *p_EnterEventMode = fmi2EnterEventMode;
static fmi2NewDiscreteStatesTYPE *p_NewDiscreteStates = fmi2NewDiscreteStates;
static fmi2EnterContinuousTimeModeTYPE *p_EnterContinuousTimeMode = fmi2EnterContinuousTimeMode;
static fmi2CompletedIntegratorStepTYPE *p_CompletedIntegratorStep = fmi2CompletedIntegratorStep;
static fmi2SetTimeTYPE *p_SetTime = fmi2SetTime;
static fmi2SetContinuousStatesTYPE *p_SetContinuousStates = fmi2SetContinuousStates;
static fmi2GetDerivativesTYPE *p_GetDerivatives = fmi2GetDerivatives;
static fmi2GetEventIndicatorsTYPE *p_GetEventIndicators = fmi2GetEventIndicators;
static fmi2GetContinuousStatesTYPE *p_GetContinuousStates = fmi2GetContinuousStates;
static fmi2GetNominalsOfContinuousStatesTYPE *p_GetNominalsOfContinuousStates = fmi2GetNominalsOfContinuousStates;

/* Co-Simulation */
static fmi2SetRealInputDerivativesTYPE *p_SetRealInputDerivatives = fmi2SetRealInputDerivatives;
static fmi2GetRealOutputDerivativesTYPE *p_GetRealOutputDerivatives = fmi2GetRealOutputDerivatives;
static fmi2DoStepTYPE *p_DoStep = fmi2DoStep;
static fmi2CancelStepTYPE *p_CancelStep = fmi2CancelStep;
static fmi2GetStatusTYPE *p_GetStatus = fmi2GetStatus;
static fmi2GetRealStatusTYPE *p_GetRealStatus = fmi2GetRealStatus;
static fmi2GetIntegerStatusTYPE *p_GetIntegerStatus = fmi2GetIntegerStatus;
static fmi2GetBooleanStatusTYPE *p_GetBooleanStatus = fmi2GetBooleanStatus;
static fmi2GetStringStatusTYPE *p_GetStringStatus = fmi2GetStringStatus;

static void logger(fmi2ComponentEnvironment env, fmi2String instanceName, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    va_list args;
    (void)env;
    va_start(args, message);
    fprintf(stderr, "[%s|%d|%s] ", instanceName ? instanceName : "?", (int)status, category ? category : "?");
    vfprintf(stderr, message, args);
    fputc('\n', stderr);
    va_end(args);
}

static int run_scene(const char *resources, const char *guid, fmi2ValueReference vr_w, fmi2ValueReference vr_lambda) {
    fmi2CallbackFunctions cb = {logger, NULL, NULL, NULL, NULL};
    fmi2Component c = p_Instantiate("c_check", fmi2CoSimulation, guid, resources, &cb, fmi2False, fmi2False);
    fmi2ValueReference vr[2];
    fmi2Real values[2];
    fmi2Real t = 0.0;
    int k;
    vr[0] = vr_w;
    vr[1] = vr_lambda;
    if (c == NULL) {
        fprintf(stderr, "fmi2Instantiate returned NULL\n");
        return 2;
    }
    if (p_SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK ||
        p_EnterInitializationMode(c) != fmi2OK || p_ExitInitializationMode(c) != fmi2OK) {
        fprintf(stderr, "initialization failed\n");
        p_FreeInstance(c);
        return 3;
    }
    for (k = 1; k <= 10; k++) {
        fmi2Real next = k * 0.1;
        if (p_DoStep(c, t, next - t, fmi2True) != fmi2OK) {
            fprintf(stderr, "fmi2DoStep failed at t = %g\n", t);
            p_FreeInstance(c);
            return 4;
        }
        t = next;
    }
    if (p_GetReal(c, vr, 2, values) != fmi2OK) {
        p_FreeInstance(c);
        return 5;
    }
    printf("w_stop=%.17g\nlambda=%.17g\n", values[0], values[1]);
    if (p_SetTime(c, 1.0) != fmi2Error) { /* Model Exchange: refused */
        p_FreeInstance(c);
        return 6;
    }
    p_Terminate(c);
    p_FreeInstance(c);
    return 0;
}

int main(int argc, char **argv) {
    /* Every pointer, so that none is unused and none is NULL. */
    void (*all_functions[])(void) = {
        (void (*)(void))p_GetTypesPlatform, (void (*)(void))p_GetVersion,
        (void (*)(void))p_SetDebugLogging, (void (*)(void))p_Instantiate,
        (void (*)(void))p_FreeInstance, (void (*)(void))p_SetupExperiment,
        (void (*)(void))p_EnterInitializationMode, (void (*)(void))p_ExitInitializationMode,
        (void (*)(void))p_Terminate, (void (*)(void))p_Reset,
        (void (*)(void))p_GetReal, (void (*)(void))p_GetInteger,
        (void (*)(void))p_GetBoolean, (void (*)(void))p_GetString,
        (void (*)(void))p_SetReal, (void (*)(void))p_SetInteger,
        (void (*)(void))p_SetBoolean, (void (*)(void))p_SetString,
        (void (*)(void))p_GetFMUstate, (void (*)(void))p_SetFMUstate,
        (void (*)(void))p_FreeFMUstate, (void (*)(void))p_SerializedFMUstateSize,
        (void (*)(void))p_SerializeFMUstate, (void (*)(void))p_DeSerializeFMUstate,
        (void (*)(void))p_GetDirectionalDerivative,
        (void (*)(void))p_EnterEventMode, (void (*)(void))p_NewDiscreteStates,
        (void (*)(void))p_EnterContinuousTimeMode, (void (*)(void))p_CompletedIntegratorStep,
        (void (*)(void))p_SetTime, (void (*)(void))p_SetContinuousStates,
        (void (*)(void))p_GetDerivatives, (void (*)(void))p_GetEventIndicators,
        (void (*)(void))p_GetContinuousStates, (void (*)(void))p_GetNominalsOfContinuousStates,
        (void (*)(void))p_SetRealInputDerivatives, (void (*)(void))p_GetRealOutputDerivatives,
        (void (*)(void))p_DoStep, (void (*)(void))p_CancelStep,
        (void (*)(void))p_GetStatus, (void (*)(void))p_GetRealStatus,
        (void (*)(void))p_GetIntegerStatus, (void (*)(void))p_GetBooleanStatus,
        (void (*)(void))p_GetStringStatus,
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
    printf("typesPlatform=%s\n", p_GetTypesPlatform());
    if (strcmp(p_GetVersion(), fmi2Version) != 0 || strcmp(p_GetTypesPlatform(), fmi2TypesPlatform) != 0) {
        return 1;
    }
    /* NULL callbacks: no instance, no crash. */
    if (p_Instantiate("x", fmi2CoSimulation, "{}", "file:///", NULL, fmi2False, fmi2False) != NULL) {
        return 1;
    }
    if (argc >= 5) {
        return run_scene(argv[1], argv[2], (fmi2ValueReference)strtoul(argv[3], NULL, 10),
                         (fmi2ValueReference)strtoul(argv[4], NULL, 10));
    }
    return 0;
}
