/*
 * A realistic and a hostile session against one FMU, for memory checkers
 * (scripts/memcheck runs it under valgrind for every FMU):
 * instantiate, set up, initialise, 300 steps reading every variable,
 * FMU states got, set, serialized, corrupted and deserialized, bad
 * arguments of every kind, reset, a second run, free.
 *
 *   drive_fmu <binary.so> <resource URI> <GUID> <number of variables> <step>
 *
 * Exits 0 when the session ran (FMI errors are expected on the bad calls
 * and are not failures here); 1 when a good call failed.
 */

#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env; (void)name; (void)status; (void)category; (void)message;
}

#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(lib, #name); if (!name) { fprintf(stderr, "missing " #name "\n"); return 1; }
#define MUST(call) do { if ((call) > fmi2Warning) { fprintf(stderr, "failed: " #call "\n"); return 1; } } while (0)

int main(int argc, char **argv) {
    if (argc != 6) {
        fprintf(stderr, "usage: drive_fmu <so> <resource URI> <GUID> <n variables> <step>\n");
        return 2;
    }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 1; }
    LOAD(fmi2Instantiate) LOAD(fmi2FreeInstance) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode) LOAD(fmi2DoStep) LOAD(fmi2GetReal) LOAD(fmi2SetReal) LOAD(fmi2GetInteger)
    LOAD(fmi2GetBoolean) LOAD(fmi2GetFMUstate) LOAD(fmi2SetFMUstate) LOAD(fmi2FreeFMUstate)
    LOAD(fmi2SerializedFMUstateSize) LOAD(fmi2SerializeFMUstate) LOAD(fmi2DeSerializeFMUstate) LOAD(fmi2Reset)
    LOAD(fmi2Terminate) LOAD(fmi2GetRealStatus) LOAD(fmi2SetDebugLogging) LOAD(fmi2CancelStep)

    const fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    unsigned n = (unsigned)atoi(argv[4]);
    double h = atof(argv[5]);
    fmi2ValueReference *vr = malloc(sizeof *vr * (n + 2));
    double *values = malloc(sizeof *values * (n + 2));
    for (unsigned i = 0; i < n + 2; i++) vr[i] = i; /* the last two do not exist */

    fmi2Component c = fmi2Instantiate("drive", fmi2CoSimulation, argv[3], argv[2], &cb, fmi2False, fmi2True);
    if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 1; }
    /* refused before anything exists */
    fmi2Instantiate("bad", fmi2ModelExchange, argv[3], argv[2], &cb, fmi2False, fmi2False);
    fmi2Instantiate("bad", fmi2CoSimulation, "not-the-guid", argv[2], &cb, fmi2False, fmi2False);
    fmi2DoStep(c, 0.0, h, fmi2True);
    const char *cats[] = {"logEvents", "logAll", "nonsense"};
    fmi2SetDebugLogging(c, fmi2True, 3, cats);
    MUST(fmi2SetDebugLogging(c, fmi2True, 2, cats));

    for (int run = 0; run < 2; run++) {
        MUST(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
        MUST(fmi2EnterInitializationMode(c));
        double nan = NAN, huge = 1e308;
        fmi2SetReal(c, vr, 1, &nan);
        fmi2SetReal(c, vr, 1, &huge);
        fmi2SetReal(c, vr + n, 1, &huge);
        MUST(fmi2ExitInitializationMode(c));
        double t = 0.0;
        fmi2FMUstate saved = NULL;
        for (int k = 0; k < 300; k++) {
            MUST(fmi2DoStep(c, t, h, fmi2True));
            t += h;
            for (unsigned i = 0; i < n; i++) fmi2GetReal(c, vr + i, 1, values + i);
            if (k == 100) MUST(fmi2GetFMUstate(c, &saved));
        }
        /* bad steps and values: refused, the instance goes on */
        fmi2DoStep(c, t, -1.0, fmi2True);
        fmi2DoStep(c, t, NAN, fmi2True);
        fmi2DoStep(c, t + 5.0, h, fmi2True);
        fmi2DoStep(c, t, 1e-300, fmi2True);
        fmi2GetReal(c, vr + n, 2, values);
        fmi2CancelStep(c);
        /* states: get into an existing one, set, serialize, corrupt, deserialize */
        MUST(fmi2GetFMUstate(c, &saved));
        MUST(fmi2SetFMUstate(c, saved));
        size_t size = 0;
        MUST(fmi2SerializedFMUstateSize(c, saved, &size));
        char *bytes = malloc(size);
        MUST(fmi2SerializeFMUstate(c, saved, bytes, size));
        fmi2FMUstate copy = NULL;
        MUST(fmi2DeSerializeFMUstate(c, bytes, size, &copy));
        MUST(fmi2SetFMUstate(c, copy));
        for (size_t at = 0; at + 8 <= size; at += 8) {
            char *bad = malloc(size);
            memcpy(bad, bytes, size);
            double poison = at % 16 ? NAN : -1e300;
            memcpy(bad + at, &poison, 8);
            fmi2FMUstate s = NULL;
            if (fmi2DeSerializeFMUstate(c, bad, size, &s) == fmi2OK) fmi2FreeFMUstate(c, &s);
            fmi2DeSerializeFMUstate(c, bad, at, &s); /* truncated */
            free(bad);
        }
        MUST(fmi2DoStep(c, t, h, fmi2True));
        fmi2FreeFMUstate(c, &copy);
        fmi2FreeFMUstate(c, &saved);
        free(bytes);
        double last = 0.0;
        MUST(fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &last));
        MUST(fmi2Terminate(c));
        MUST(fmi2Reset(c));
    }
    /* A state the importer leaves to fmi2FreeInstance, which frees it. */
    fmi2FMUstate kept = NULL;
    MUST(fmi2GetFMUstate(c, &kept));
    fmi2FreeInstance(c);
    free(vr);
    free(values);
    dlclose(lib);
    return 0;
}
