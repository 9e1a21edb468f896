/* Lag: a first-order plant with a feed-through output, y = x + D u, der(x) = (K u - x)/T. */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "Lag"
#define TOKEN2 "{5e1a3c27-8b4d-4f19-9c6e-7d8e9f0a0703}"
#define TOKEN3 "{5e1a3c27-8b4d-4f19-9c6e-7d8e9f0a0703}"
#define NX 1
#define NZ 0
#define CS_STEP 0.001 /* internal RK4 step of co-simulation */

typedef struct {
    double u, y, x, der_x, T, K, D;
} ModelData;

#endif
