/* Stair: an Integer counter incremented by time events; asks to terminate at t_terminate. */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "Stair"
#define TOKEN2 "{9e27c5a0-1d4b-4f3c-a6e8-51b7d3c2f402}"
#define TOKEN3 "{9e27c5a0-1d4b-4f3c-a6e8-51b7d3c2f402}"
#define NX 0
#define NZ 0
#define CS_STEP 1.0 /* no continuous states: the internal step does not matter */

typedef struct {
    int32_t counter;
    bool even; /* counter is even: follows the counter one discrete-update pass later */
    double period, t_terminate;
    int64_t k; /* index of the next tick, at k * period */
} ModelData;

#endif
