/*
 * The FMI 3.0 sibling of drive_fmu.c: a realistic and a hostile session
 * against one FMI 3.0 FMU, for memory checkers (scripts/memcheck3 runs it
 * under valgrind for every FMU in target/fmu3):
 * instantiate with eventModeUsed and earlyReturnAllowed (and an
 * intermediate-update callback that asks for some early returns and calls
 * back into the running instance, which must be refused), initialise,
 * step about 600 times through 600 default steps or a tenth of the
 * default experiment, whichever is longer, with early returns and
 * event-mode updates reading every variable, FMU states got, set,
 * serialized, corrupted and deserialized, bad arguments of every kind,
 * reset, a second (shorter) run, free.
 *
 *   drive_fmu3 <binary.so> <resource path> <instantiation token> <number of variables> <step> <stop time>
 *
 * Exits 0 when the session ran (FMI errors are expected on the bad calls
 * and are not failures here); 1 when a good call failed.
 */

#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env; (void)status; (void)category; (void)message;
}

/* What the intermediate-update callback sees: the instance (set after
 * instantiation) and a getter to call back into it with. */
typedef struct {
    fmi3Instance instance;
    fmi3GetFloat64TYPE *get;
    unsigned calls;
    unsigned reentered_ok; /* call-backs that were (wrongly) accepted */
} Env;

static void intermediate(fmi3InstanceEnvironment environment, fmi3Float64 time, fmi3Boolean setRequested,
                         fmi3Boolean getAllowed, fmi3Boolean stepFinished, fmi3Boolean canReturnEarly,
                         fmi3Boolean *earlyReturnRequested, fmi3Float64 *earlyReturnTime) {
    Env *env = (Env *)environment;
    (void)setRequested; (void)getAllowed; (void)stepFinished;
    env->calls++;
    if (env->instance && env->calls % 7 == 0) {
        fmi3ValueReference vr = 0;
        fmi3Float64 value = 0.0;
        if (env->get(env->instance, &vr, 1, &value, 1) == fmi3OK) env->reentered_ok++;
    }
    *earlyReturnRequested = canReturnEarly && env->calls % 3 == 0;
    *earlyReturnTime = time;
}

#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(lib, #name); if (!name) { fprintf(stderr, "missing " #name "\n"); return 1; }
#define MUST(call) do { if ((call) > fmi3Warning) { fprintf(stderr, "failed: " #call "\n"); return 1; } } while (0)

int main(int argc, char **argv) {
    if (argc != 7) {
        fprintf(stderr, "usage: drive_fmu3 <so> <resource path> <instantiation token> <n variables> <step> <stop>\n");
        return 2;
    }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 1; }
    LOAD(fmi3InstantiateCoSimulation) LOAD(fmi3InstantiateModelExchange) LOAD(fmi3FreeInstance)
    LOAD(fmi3EnterInitializationMode) LOAD(fmi3ExitInitializationMode) LOAD(fmi3EnterEventMode)
    LOAD(fmi3UpdateDiscreteStates) LOAD(fmi3EnterStepMode) LOAD(fmi3DoStep) LOAD(fmi3GetFloat64)
    LOAD(fmi3SetFloat64) LOAD(fmi3GetInt32) LOAD(fmi3SetInt32) LOAD(fmi3GetBoolean) LOAD(fmi3SetBoolean)
    LOAD(fmi3GetFMUState) LOAD(fmi3SetFMUState) LOAD(fmi3FreeFMUState) LOAD(fmi3SerializedFMUStateSize)
    LOAD(fmi3SerializeFMUState) LOAD(fmi3DeserializeFMUState) LOAD(fmi3Reset) LOAD(fmi3Terminate)
    LOAD(fmi3SetDebugLogging) LOAD(fmi3SetTime) LOAD(fmi3GetClock) LOAD(fmi3EnterConfigurationMode)
    LOAD(fmi3GetDirectionalDerivative)

    const char *resources = argv[2], *token = argv[3];
    unsigned n = (unsigned)atoi(argv[4]);
    /* 600 default steps or a tenth of the default experiment, whichever
       is longer (every scene meets its first events), in about 600 steps */
    double step = atof(argv[5]), stop = atof(argv[6]);
    double horizon = fmin(stop, fmax(600 * step, stop / 10)), h = fmax(step, horizon / 600);
    fmi3ValueReference *vr = malloc(sizeof *vr * (n + 2));
    double *values = malloc(sizeof *values * (n + 2));
    fmi3Int32 ints[2];
    fmi3Boolean bools[2];
    for (unsigned i = 0; i < n + 2; i++) vr[i] = i; /* the last two do not exist ("time" is n - 1) */

    Env env = {NULL, fmi3GetFloat64, 0, 0};
    fmi3ValueReference required = 0;
    /* refused before anything exists */
    fmi3InstantiateModelExchange("bad", token, resources, fmi3False, fmi3False, NULL, logger);
    fmi3InstantiateCoSimulation("bad", "not-the-token", resources, fmi3False, fmi3False, fmi3True, fmi3True, NULL, 0,
                                &env, logger, intermediate);
    fmi3InstantiateCoSimulation("bad", token, resources, fmi3False, fmi3False, fmi3True, fmi3True, &required, 1,
                                &env, logger, intermediate);
    fmi3InstantiateCoSimulation(NULL, token, "relative/resources", fmi3False, fmi3False, fmi3True, fmi3True, NULL, 0,
                                &env, logger, intermediate);
    fmi3Instance c = fmi3InstantiateCoSimulation("drive3", token, resources, fmi3False, fmi3True, fmi3True, fmi3True,
                                                 NULL, 0, &env, logger, intermediate);
    if (!c) { fprintf(stderr, "fmi3InstantiateCoSimulation failed\n"); return 1; }
    env.instance = c;

    fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
    fmi3Float64 last = 0.0;
    fmi3DoStep(c, 0.0, h, fmi3True, &event, &terminate, &early, &last); /* before initialisation: refused */
    const char *cats[] = {"logEvents", "logAll", "nonsense"};
    fmi3SetDebugLogging(c, fmi3True, 3, cats);
    MUST(fmi3SetDebugLogging(c, fmi3True, 2, cats));

    for (int run = 0; run < 2; run++) {
        /* the horizon, then a shorter run */
        double end = run == 0 ? horizon : fmin(stop, 300 * h);
        MUST(fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3True, end));
        double nan = NAN, huge = 1e308;
        fmi3SetFloat64(c, vr, 1, &nan, 1);
        fmi3SetFloat64(c, vr, 1, &huge, 1);
        fmi3SetFloat64(c, vr + n, 1, &huge, 1);
        fmi3SetFloat64(c, vr + n - 1, 1, &huge, 1); /* time */
        fmi3SetFloat64(c, vr, 1, &huge, 2);          /* nValues != nValueReferences */
        ints[0] = 1;
        bools[0] = fmi3True;
        fmi3SetInt32(c, vr, 1, ints, 1);
        fmi3SetBoolean(c, vr, 1, bools, 1);
        for (unsigned i = 0; i < n; i++) fmi3GetFloat64(c, vr + i, 1, values + i, 1); /* provisional outputs */
        MUST(fmi3ExitInitializationMode(c)); /* to event mode */
        fmi3Boolean need = fmi3True, term = fmi3False, nominals = fmi3False, changed = fmi3False, defined = fmi3False;
        fmi3Float64 next = 0.0;
        MUST(fmi3UpdateDiscreteStates(c, &need, &term, &nominals, &changed, &defined, &next));
        MUST(fmi3EnterStepMode(c));
        double t = 0.0;
        fmi3FMUState saved = NULL;
        unsigned steps = 0, early_returns = 0, events = 0;
        while (t < end) {
            double step = fmin(h, end - t);
            if (step <= 0.0 || ++steps > 200000) { fprintf(stderr, "no progress at t = %g\n", t); return 1; }
            MUST(fmi3DoStep(c, t, step, fmi3True, &event, &terminate, &early, &last));
            if (early) {
                early_returns++;
                if (!(last >= t && last < t + step)) { fprintf(stderr, "early return at %g outside [%g, %g)\n", last, t, t + step); return 1; }
                t = last;
            } else {
                t = t + step >= end ? end : t + step;
            }
            for (unsigned i = 0; i < n; i++) fmi3GetFloat64(c, vr + i, 1, values + i, 1);
            for (unsigned i = 0; i < n; i += 5) {
                fmi3GetInt32(c, vr + i, 1, ints, 1);
                fmi3GetBoolean(c, vr + i, 1, bools, 1);
            }
            if (event) {
                events++;
                MUST(fmi3EnterEventMode(c));
                for (int k = 0; k < 10; k++) {
                    MUST(fmi3UpdateDiscreteStates(c, &need, &term, &nominals, &changed, &defined, &next));
                    if (!need) break;
                }
                MUST(fmi3EnterStepMode(c));
            }
            if (steps == 100) MUST(fmi3GetFMUState(c, &saved));
        }
        /* bad steps and values: refused, the instance goes on */
        fmi3DoStep(c, t, -1.0, fmi3True, &event, &terminate, &early, &last);
        fmi3DoStep(c, t, NAN, fmi3True, &event, &terminate, &early, &last);
        fmi3DoStep(c, t + 5.0, h, fmi3True, &event, &terminate, &early, &last);
        fmi3DoStep(c, t, 1e-300, fmi3True, &event, &terminate, &early, &last);
        fmi3DoStep(c, t, h, fmi3True, NULL, &terminate, &early, &last);
        fmi3DoStep(c, t, h, fmi3True, &event, &terminate, &early, &last); /* past the stop time */
        fmi3GetFloat64(c, vr + n, 2, values, 2);
        fmi3GetFloat64(c, vr, 2, values, 1);
        fmi3GetFloat64(c, NULL, 2, values, 2);
        fmi3UpdateDiscreteStates(c, &need, &term, &nominals, &changed, &defined, &next); /* step mode: refused */
        fmi3SetTime(c, 1.0);
        fmi3GetClock(c, vr, 1, bools);
        fmi3EnterConfigurationMode(c);
        fmi3GetDirectionalDerivative(c, vr, 1, vr, 1, values, 1, values, 1);
        /* states: get into an existing one, set, serialize, corrupt, deserialize */
        MUST(fmi3GetFMUState(c, &saved));
        MUST(fmi3SetFMUState(c, saved));
        size_t size = 0;
        MUST(fmi3SerializedFMUStateSize(c, saved, &size));
        fmi3Byte *bytes = malloc(size);
        MUST(fmi3SerializeFMUState(c, saved, bytes, size));
        fmi3SerializeFMUState(c, saved, bytes, size - 1); /* too small: refused */
        fmi3FMUState copy = NULL;
        MUST(fmi3DeserializeFMUState(c, bytes, size, &copy));
        MUST(fmi3SetFMUState(c, copy));
        for (size_t at = 0; at + 8 <= size; at += 8) {
            fmi3Byte *bad = malloc(size);
            memcpy(bad, bytes, size);
            double poison = at % 16 ? NAN : -1e300;
            memcpy(bad + at, &poison, 8);
            fmi3FMUState s = NULL;
            if (fmi3DeserializeFMUState(c, bad, size, &s) == fmi3OK) fmi3FreeFMUState(c, &s);
            fmi3DeserializeFMUState(c, bad, at, &s); /* truncated */
            free(bad);
        }
        MUST(fmi3SetFMUState(c, copy));
        fmi3FreeFMUState(c, &copy);
        fmi3FreeFMUState(c, &saved);
        free(bytes);
        /* the end of the run: event mode, terminate */
        MUST(fmi3EnterEventMode(c));
        MUST(fmi3Terminate(c));
        for (unsigned i = 0; i < n; i++) fmi3GetFloat64(c, vr + i, 1, values + i, 1);
        MUST(fmi3Reset(c));
        if (run == 0 && (steps < 2 || env.reentered_ok)) {
            fprintf(stderr, "steps %u, call-backs accepted %u\n", steps, env.reentered_ok);
            return 1;
        }
        printf("run %d: %u steps, %u early returns, %u events, %u intermediate updates\n", run, steps, early_returns,
               events, env.calls);
    }
    /* States the importer leaves to fmi3FreeInstance, which frees them
       (got, and deserialized): valgrind's leak check sees any it does not. */
    fmi3FMUState kept = NULL, kept_copy = NULL;
    MUST(fmi3GetFMUState(c, &kept));
    size_t kept_size = 0;
    MUST(fmi3SerializedFMUStateSize(c, kept, &kept_size));
    fmi3Byte *kept_bytes = malloc(kept_size);
    MUST(fmi3SerializeFMUState(c, kept, kept_bytes, kept_size));
    MUST(fmi3DeserializeFMUState(c, kept_bytes, kept_size, &kept_copy));
    free(kept_bytes);
    fmi3FreeInstance(c);
    free(vr);
    free(values);
    dlclose(lib);
    return 0;
}
