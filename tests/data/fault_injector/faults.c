/* faults.c - hooks of the test model FaultInjector (tests/fault_injector.py): y = u, and at
 * given times calls fail, outputs turn NaN or doStep hangs. Compiled with the uwcosim C
 * template (uwc_model.h, UWC_HOOKS = 1); the shipped FMUs have no hooks.
 *
 * A threshold is reached when time >= threshold - 1e-9 max(1, |threshold|).
 */
#if !defined(_WIN32) && !defined(_POSIX_C_SOURCE)
#define _POSIX_C_SOURCE 200809L
#endif
#include "uwc_model.h"

#include <errno.h>
#include <math.h>
#ifdef _WIN32
#include <windows.h>
#else
#include <time.h>
#endif

static int reached(double t, double threshold) {
    return t >= threshold - 1e-9 * fmax(1.0, fabs(threshold));
}

static void sleep_seconds(double s) {
#ifdef _WIN32
    while (s > 0) {
        double chunk = s > 1000.0 ? 1000.0 : s;
        Sleep((DWORD)(chunk * 1000.0));
        s -= chunk;
    }
#else
    struct timespec req, rem;
    if (!(s > 0)) return;
    req.tv_sec = (time_t)s;
    req.tv_nsec = (long)((s - (double)req.tv_sec) * 1e9);
    while (nanosleep(&req, &rem) != 0 && errno == EINTR) req = rem;
#endif
}

static int faults(uwc_inst *m, double t, int may_hang) {
    const double *p = m->r + UWC_OFF_P;
    if (reached(t, p[UWC_P_FAIL_TIME])) {
        uwc_log(m, UWC_ERROR, "%s: injected failure at time t = %.15g (fail_time = %.15g)",
                m->name, t, p[UWC_P_FAIL_TIME]);
        return UWC_ERROR;
    }
    if (may_hang && reached(t, p[UWC_P_HANG_TIME])) {
        uwc_log(m, UWC_WARNING, "%s: injected hang of %g s at time t = %.15g", m->name,
                p[UWC_P_HANG_SECONDS], t);
        sleep_seconds(p[UWC_P_HANG_SECONDS]);
    }
    return UWC_OK;
}

int uwc_hook_eval(uwc_inst *m) { return faults(m, m->r[0], !m->is_cs); }

int uwc_hook_step(uwc_inst *m, double t) { return faults(m, t, 1); }

void uwc_hook_outputs(uwc_inst *m) {
    int k;
    if (reached(m->r[0], m->r[UWC_OFF_P + UWC_P_NAN_TIME])) {
        for (k = 0; k < UWC_NY; k++) m->r[UWC_OFF_Y + k] = NAN;
    }
}
