/* BouncingBall: a ball dropped on a floor (state event z = h, reset v := -e v). */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "BouncingBall"
#define TOKEN2 "{4b1f9d2e-6a3c-4e57-8d10-b0a1c2e3f401}"
#define TOKEN3 "{4b1f9d2e-6a3c-4e57-8d10-b0a1c2e3f401}"
#define NX 2
#define NZ 1
#define CS_STEP 0.01 /* internal RK4 step of co-simulation (exact here: h is quadratic in t) */

typedef struct {
    double h, der_h, v, der_v; /* states and derivatives */
    double g, e, v_min;        /* parameters */
    int32_t bounces;
    double z;                  /* the event indicator */
    bool resting;
} ModelData;

#endif
