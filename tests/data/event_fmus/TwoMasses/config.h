/* TwoMasses: the two SpringMass masses and their coupling spring in one FMU (the single-solver
 * reference of benchmarks/bench_master.py). */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "TwoMasses"
#define TOKEN2 "{3c5d7f49-6e8a-4b62-9d14-2a3b4c5d0905}"
#define TOKEN3 "{3c5d7f49-6e8a-4b62-9d14-2a3b4c5d0905}"
#define NX 4
#define NZ 0
#define CS_STEP 0.001 /* internal RK4 step of co-simulation */

typedef struct {
    double x1, der_x1, v1, der_v1, x2, der_x2, v2, der_v2;
    double m1, m2, c, c1, c2, d1, d2;
} ModelData;

#endif
