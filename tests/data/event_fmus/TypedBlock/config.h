/* TypedBlock: inputs and outputs of every FMI type, a discrete Float64 input, one state. */
#ifndef EVFMU_CONFIG_H
#define EVFMU_CONFIG_H

#define MODEL_NAME "TypedBlock"
#define TOKEN2 "{e51d7a93-2c6f-4b08-8f3e-7a9c0d4b2404}"
#define TOKEN3 "{e51d7a93-2c6f-4b08-8f3e-7a9c0d4b2404}"
#define NX 1
#define NZ 0
#define CS_STEP 0.01 /* internal RK4 step of co-simulation (exact: der(y) is piecewise constant) */

/* FMI 3 has the sized types; FMI 2 stores them as Real (double) and Integer (int32) */
#if FMI_VERSION == 3
typedef float f32_t;
typedef int8_t i8_t;
typedef uint16_t u16_t;
typedef int64_t i64_t;
typedef uint64_t u64_t;
#define VT_F32_ VT_F32
#define VT_I8_ VT_I8
#define VT_U16_ VT_U16
#define VT_I64_ VT_I64
#define VT_U64_ VT_U64
#else
typedef double f32_t;
typedef int32_t i8_t;
typedef int32_t u16_t;
typedef int32_t i64_t;
typedef int32_t u64_t;
#define VT_F32_ VT_F64
#define VT_I8_ VT_I32
#define VT_U16_ VT_I32
#define VT_I64_ VT_I32
#define VT_U64_ VT_I32
#endif

typedef struct {
    f32_t f32_in, f32_out;
    i8_t i8_in, i8_out;
    u16_t u16_in, u16_out;
    int32_t i32_in, i32_out;
    i64_t i64_in, i64_out;
    u64_t u64_in, u64_out;
    bool b_in, b_out;
    int64_t mode_in, mode_out; /* enumeration Mode: off = 1, slow = 2, fast = 3 */
    double d_in, d_out;        /* discrete input, discrete output latched at events */
    double y, der_y;           /* the state: der(y) = d_in */
    char label[STR_LEN];
    int32_t label_len;
    double gains[3], gain_sum;
    double y_wrap;  /* > 0: y wraps around to y - y_wrap at a step event once y >= y_wrap */
    int32_t wraps;  /* number of wrap-arounds */
} ModelData;

#endif
