/* PController: u = kp (r - y) (direct feed-through from both inputs). */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "PController"
#define TOKEN2 "{2b7c9e14-5f3a-4d86-b2e9-0c1d2e3f0602}"
#define TOKEN3 "{2b7c9e14-5f3a-4d86-b2e9-0c1d2e3f0602}"
#define NX 0
#define NZ 0
#define CS_STEP 1.0 /* no continuous states: the internal step does not matter */

typedef struct {
    double r, y, u, kp;
} ModelData;

#endif
