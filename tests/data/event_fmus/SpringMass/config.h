/* SpringMass: a mass on a wall spring and damper, coupled by a spring to another mass whose
 * position is the input x_other (no direct feed-through). */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "SpringMass"
#define TOKEN2 "{9a4b6d38-2c7e-4a51-8f03-1b2c3d4e0804}"
#define TOKEN3 "{9a4b6d38-2c7e-4a51-8f03-1b2c3d4e0804}"
#define NX 2
#define NZ 0
#define CS_STEP 0.001 /* internal RK4 step of co-simulation */

typedef struct {
    double x_other, x, der_x, v, der_v, m, c, c_wall, d;
} ModelData;

#endif
