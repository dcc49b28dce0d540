/* A small FMI 2.0 host for valgrind (tests/python/test_valgrind.py): loads an FMU's
 * library, runs `cycles` instantiate / initialize / step / get, serialize, deserialize,
 * set state / free cycles, and does it over `reloads` dlopen/dlclose reloads. Plain C so
 * that valgrind sees only the library and libc, not an interpreter.
 *
 *   driver LIB GUID RESOURCE_URI RELOADS CYCLES
 *
 * Exit status 0 when every call answered as expected. */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>

typedef void *C;
typedef int (*setup_t)(C, int, double, double, int, double);
typedef int (*unary_t)(C);
typedef int (*step_t)(C, double, double, int);
typedef int (*state_t)(C, void **);
typedef int (*setstate_t)(C, void *);
typedef int (*size_t_fn)(C, void *, size_t *);
typedef int (*ser_t)(C, void *, char *, size_t);
typedef int (*deser_t)(C, const char *, size_t, void **);
typedef int (*getreal_t)(C, const unsigned *, size_t, double *);
typedef C (*inst_t)(const char *, int, const char *, const char *, const void *, int, int);
typedef void (*free_t)(C);

#define SYM(T, name) T name = (T)dlsym(h, #name); if (!name) { fprintf(stderr, "no %s\n", #name); return 2; }
#define EXPECT(x) if ((x) != 0) { fprintf(stderr, "failed: %s\n", #x); return 3; }

static int run(const char *lib, const char *guid, const char *res, int cycles) {
    void *h = dlopen(lib, RTLD_NOW | RTLD_LOCAL);
    if (!h) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    SYM(inst_t, fmi2Instantiate) SYM(free_t, fmi2FreeInstance)
    SYM(setup_t, fmi2SetupExperiment) SYM(unary_t, fmi2EnterInitializationMode)
    SYM(unary_t, fmi2ExitInitializationMode) SYM(step_t, fmi2DoStep)
    SYM(state_t, fmi2GetFMUstate) SYM(setstate_t, fmi2SetFMUstate) SYM(state_t, fmi2FreeFMUstate)
    SYM(size_t_fn, fmi2SerializedFMUstateSize) SYM(ser_t, fmi2SerializeFMUstate)
    SYM(deser_t, fmi2DeSerializeFMUstate) SYM(getreal_t, fmi2GetReal)
    for (int k = 0; k < cycles; k++) {
        C c = fmi2Instantiate("valgrind", 1, guid, res, NULL, 0, 0);
        if (!c) { fprintf(stderr, "instantiation failed\n"); return 3; }
        EXPECT(fmi2SetupExperiment(c, 1, 1e-6, 0.0, 0, 0.0))
        EXPECT(fmi2EnterInitializationMode(c))
        EXPECT(fmi2ExitInitializationMode(c))
        double t = 0.0, out[4];
        unsigned vr[4] = {0, 1, 2, 3};
        for (int i = 0; i < 5; i++, t += 1e-3) EXPECT(fmi2DoStep(c, t, 1e-3, 1))
        /* value references 0-3 may be any type: only the call's safety matters here */
        fmi2GetReal(c, vr, 4, out);
        void *s = NULL, *back = NULL;
        size_t n = 0;
        EXPECT(fmi2GetFMUstate(c, &s))
        EXPECT(fmi2SerializedFMUstateSize(c, s, &n))
        char *buf = malloc(n);
        EXPECT(fmi2SerializeFMUstate(c, s, buf, n))
        EXPECT(fmi2DeSerializeFMUstate(c, buf, n, &back))
        EXPECT(fmi2DeSerializeFMUstate(c, buf, n, &back)) /* into the occupied slot */
        buf[n / 2] ^= 0x55; /* a corrupted state is refused */
        if (fmi2DeSerializeFMUstate(c, buf, n, &s) == 0) { fprintf(stderr, "corruption accepted\n"); return 3; }
        free(buf);
        EXPECT(fmi2SetFMUstate(c, back))
        EXPECT(fmi2DoStep(c, t, 1e-3, 1))
        EXPECT(fmi2FreeFMUstate(c, &s))
        EXPECT(fmi2FreeFMUstate(c, &back))
        fmi2FreeInstance(c);
    }
    dlclose(h);
    return 0;
}

int main(int argc, char **argv) {
    if (argc != 6) { fprintf(stderr, "usage: driver LIB GUID RESOURCE_URI RELOADS CYCLES\n"); return 2; }
    int reloads = atoi(argv[4]), cycles = atoi(argv[5]);
    for (int r = 0; r < reloads; r++) {
        int e = run(argv[1], argv[2], argv[3], cycles);
        if (e) return e;
    }
    return 0;
}
