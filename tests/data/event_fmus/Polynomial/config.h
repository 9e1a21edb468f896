/* Polynomial: y = c0 + c1 u + c2 u^2 (direct feed-through, directional derivatives). */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "Polynomial"
#define TOKEN2 "{8d2f4a61-93c5-4b7e-a1d0-5e6f7a8b0501}"
#define TOKEN3 "{8d2f4a61-93c5-4b7e-a1d0-5e6f7a8b0501}"
#define NX 0
#define NZ 0
#define CS_STEP 1.0 /* no continuous states: the internal step does not matter */
#define MODEL_DIRECTIONAL 1

typedef struct {
    double u, y, c0, c1, c2;
} ModelData;

#endif
