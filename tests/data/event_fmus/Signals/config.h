/* Signals: an FMI 3 array block, 64-bit integers passed through, a narrow integer with a
 * declared range, locals and a state that are not outputs, a structural parameter. */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "Signals"
#define TOKEN2 "{5d1f0c2a-9b7e-4e61-a3c8-6f2e1b9d0505}"
#define TOKEN3 "{5d1f0c2a-9b7e-4e61-a3c8-6f2e1b9d0505}"
#define NX 1
#define NZ 0
#define CS_STEP 0.01 /* internal RK4 step of co-simulation (exact: der(x) is constant in a step) */

/* FMI 3 has the sized types; FMI 2 stores them as Integer (int32) */
#if FMI_VERSION == 3
typedef int64_t i64_t;
typedef uint64_t u64_t;
typedef int8_t i8_t;
#define VT_I64_ VT_I64
#define VT_U64_ VT_U64
#define VT_I8_ VT_I8
#define K_SPARAM_ K_SPARAM
#else
typedef int32_t i64_t;
typedef int32_t u64_t;
typedef int32_t i8_t;
#define VT_I64_ VT_I32
#define VT_U64_ VT_I32
#define VT_I8_ VT_I32
#define K_SPARAM_ K_PARAM
#endif

typedef struct {
    double u[3], y[3], M[6]; /* M[2][3] row-major: row 0 = u, row 1 = y */
    double k;                /* gain: a structural parameter in FMI 3 */
    double ysum, energy, x, der_x;
    i64_t i64_in, i64_out, small;
    u64_t u64_in, u64_out;
    i8_t i8_in, i8_out;
} ModelData;

#endif
