/* Feedthrough: outputs equal to the inputs (direct feed-through), no states. */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "Feedthrough"
#define TOKEN2 "{c3a8e6f1-7b2d-4d90-9e4a-2f6b8c1d0403}"
#define TOKEN3 "{c3a8e6f1-7b2d-4d90-9e4a-2f6b8c1d0403}"
#define NX 0
#define NZ 0
#define CS_STEP 1.0 /* no continuous states: the internal step does not matter */

typedef struct {
    double u, y, k, yk;
    int32_t iu, iy;
    bool bu, by;
} ModelData;

#endif
