/* crash.c - hooks of the test model Crasher (tests/crasher.py): y = u, and at a given time the
 * FMU ends or stalls the process it runs in, as a faulty third-party FMU may. Compiled with the
 * uwcosim C template (uwc_model.h, UWC_HOOKS = 1); the shipped FMUs have no hooks.
 *
 * Parameters (reals): mode 0 nothing, 1 segmentation fault, 2 exit(exit_code), 3 abort(),
 * 4 spin (busy loop, forever), 5 sleep (an hour); where 1 doStep, 2 an output getter
 * (fmi2GetReal / fmi3GetFloat64: the evaluation it triggers), 3 initialization (the
 * first evaluation of the library's instance: the outputs read at the start time, right after
 * exitInitializationMode; the template has no hook inside it); crash_time: the fault happens once time >= crash_time
 * (doStep: its start time; getter: the time of the values read).
 *
 * At library load (before any parameter exists) the environment variable UWC_CRASHER_AT_LOAD
 * chooses: "segfault", "abort" or "exit:N".
 */
#if !defined(_WIN32) && !defined(_POSIX_C_SOURCE)
#define _POSIX_C_SOURCE 200809L
#endif
#include "uwc_model.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { NONE = 0, SEGFAULT = 1, EXIT = 2, ABORT = 3, SPIN = 4, SLEEP = 5 };
enum { AT_STEP = 1, AT_GET = 2, AT_INIT = 3 };

static void crash(int mode, int code) {
    volatile int *nowhere = NULL;
    volatile double spin = 0.0;
    struct timespec req = {3600, 0}, rem;
    switch (mode) {
    case SEGFAULT: *nowhere = 1; raise(SIGSEGV); break; /* raise: if the write was optimized */
    case EXIT: exit(code); break;
    case ABORT: abort(); break;
    case SPIN: for (;;) spin += 1.0; break;
    case SLEEP: while (nanosleep(&req, &rem) != 0 && errno == EINTR) req = rem; break;
    default: break;
    }
}

static void maybe_crash(uwc_inst *m, int where, double t) {
    const double *p = m->r + UWC_OFF_P;
    const double at = p[UWC_P_CRASH_TIME];
    if ((int)p[UWC_P_WHERE] != where || t < at - 1e-9 * fmax(1.0, fabs(at))) return;
    crash((int)p[UWC_P_MODE], (int)p[UWC_P_EXIT_CODE]);
}

#if defined(__GNUC__)
__attribute__((constructor)) static void at_load(void) {
    const char *what = getenv("UWC_CRASHER_AT_LOAD");
    if (what == NULL || !*what) return;
    if (strcmp(what, "segfault") == 0) crash(SEGFAULT, 0);
    if (strcmp(what, "abort") == 0) crash(ABORT, 0);
    if (strncmp(what, "exit:", 5) == 0) crash(EXIT, atoi(what + 5));
}
#endif

int uwc_hook_eval(uwc_inst *m) {
    static int evaluations = 0; /* of this library: one instance per process in the tests */
    if (evaluations++ == 0) maybe_crash(m, AT_INIT, m->r[0]);
    maybe_crash(m, AT_GET, m->r[0]);
    return UWC_OK;
}

int uwc_hook_step(uwc_inst *m, double t) {
    maybe_crash(m, AT_STEP, t);
    return UWC_OK;
}

void uwc_hook_outputs(uwc_inst *m) { (void)m; }
