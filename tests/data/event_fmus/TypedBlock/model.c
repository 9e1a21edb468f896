/* model.c - TypedBlock equations (no events of its own; discrete inputs change at events):
 *
 *   f32_out = 2 f32_in + 0.5      (FMI 3: Float32 arithmetic)
 *   i8_out = i8_in,  u16_out = (u16_in + 1) mod 65536,  i32_out = i32_in + 1,
 *   i64_out = 2 i64_in,  u64_out = u64_in + 1   (two's complement wrap-around in FMI 3),
 *   b_out = not b_in,  mode_out = mode_in,
 *   d_out = d_in, taken at the discrete update (event mode; co-simulation: step start),
 *   der(y) = d_in (y = integral of the discrete input, the only state),
 *   label_len = length of the String parameter label,  gain_sum = gains[1]+gains[2]+gains[3],
 *   if y_wrap > 0: a step event (completedIntegratorStep asks for event mode; co-simulation:
 *   after an internal step) once y >= y_wrap, where y := y - y_wrap and wraps := wraps + 1,
 *   so that y + wraps * y_wrap is the integral of d_in.
 *
 * In FMI 2 the Float32 and Int8..UInt64 variables are Real and Integer (32 bits), the array
 * parameter gains is three scalars gains[1], gains[2], gains[3].
 */
#include <math.h>
#include <string.h>

#include "core.h"

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {1, "f32_in", VT_F32_, K_INPUT, VAR_OFFSET(f32_in), 1},
    {2, "f32_out", VT_F32_, K_CALC, VAR_OFFSET(f32_out), 1},
    {3, "i8_in", VT_I8_, K_DINPUT, VAR_OFFSET(i8_in), 1},
    {4, "i8_out", VT_I8_, K_CALC, VAR_OFFSET(i8_out), 1},
    {5, "u16_in", VT_U16_, K_DINPUT, VAR_OFFSET(u16_in), 1},
    {6, "u16_out", VT_U16_, K_CALC, VAR_OFFSET(u16_out), 1},
    {7, "i32_in", VT_I32, K_DINPUT, VAR_OFFSET(i32_in), 1},
    {8, "i32_out", VT_I32, K_CALC, VAR_OFFSET(i32_out), 1},
    {9, "i64_in", VT_I64_, K_DINPUT, VAR_OFFSET(i64_in), 1},
    {10, "i64_out", VT_I64_, K_CALC, VAR_OFFSET(i64_out), 1},
    {11, "u64_in", VT_U64_, K_DINPUT, VAR_OFFSET(u64_in), 1},
    {12, "u64_out", VT_U64_, K_CALC, VAR_OFFSET(u64_out), 1},
    {13, "b_in", VT_BOOL, K_DINPUT, VAR_OFFSET(b_in), 1},
    {14, "b_out", VT_BOOL, K_CALC, VAR_OFFSET(b_out), 1},
    {15, "mode_in", VT_ENUM, K_DINPUT, VAR_OFFSET(mode_in), 1},
    {16, "mode_out", VT_ENUM, K_CALC, VAR_OFFSET(mode_out), 1},
    {17, "d_in", VT_F64, K_DINPUT, VAR_OFFSET(d_in), 1},
    {18, "d_out", VT_F64, K_CALC, VAR_OFFSET(d_out), 1},
    {19, "y", VT_F64, K_START, VAR_OFFSET(y), 1},
    {20, "der(y)", VT_F64, K_CALC, VAR_OFFSET(der_y), 1},
    {21, "label", VT_STR, K_PARAM, VAR_OFFSET(label), 1},
    {22, "label_len", VT_I32, K_CALC, VAR_OFFSET(label_len), 1},
    {23, "gain_sum", VT_F64, K_CALC, VAR_OFFSET(gain_sum), 1},
    {27, "y_wrap", VT_F64, K_PARAM, VAR_OFFSET(y_wrap), 1},
    {28, "wraps", VT_I32, K_START, VAR_OFFSET(wraps), 1},
#if FMI_VERSION == 3
    {24, "gains", VT_F64, K_PARAM, VAR_OFFSET(gains), 3},
#else
    {24, "gains[1]", VT_F64, K_PARAM, VAR_OFFSET(gains[0]), 1},
    {25, "gains[2]", VT_F64, K_PARAM, VAR_OFFSET(gains[1]), 1},
    {26, "gains[3]", VT_F64, K_PARAM, VAR_OFFSET(gains[2]), 1},
#endif
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    ModelData *m = &c->m;
    m->f32_in = (f32_t)1.5;
    m->i8_in = -3;
    m->u16_in = 7;
    m->i32_in = 41;
#if FMI_VERSION == 3
    m->i64_in = -5000000000LL;          /* beyond 32 bits */
    m->u64_in = 9007199254740993ULL;    /* 2^53 + 1: not a double */
#else
    m->i64_in = -5;
    m->u64_in = 123;
#endif
    m->b_in = false;
    m->mode_in = 2;
    m->d_in = 0.5;
    m->y = 0.0;
    strcpy(m->label, "hello");
    m->gains[0] = 1.0;
    m->gains[1] = 2.0;
    m->gains[2] = 3.0;
    m->y_wrap = 0.0;
    m->wraps = 0;
}

void model_calc(Instance *c) {
    ModelData *m = &c->m;
    m->f32_out = (f32_t)2 * m->f32_in + (f32_t)0.5;
    m->i8_out = m->i8_in;
    m->u16_out = (u16_t)(((uint32_t)m->u16_in + 1u) & 0xFFFFu);
    m->i32_out = (int32_t)((uint32_t)m->i32_in + 1u);
#if FMI_VERSION == 3
    m->i64_out = (int64_t)((uint64_t)m->i64_in * 2u);
    m->u64_out = m->u64_in + 1u;
#else
    m->i64_out = (int32_t)((uint32_t)m->i64_in * 2u);
    m->u64_out = (int32_t)((uint32_t)m->u64_in + 1u);
#endif
    m->b_out = !m->b_in;
    m->mode_out = m->mode_in;
    if (c->mode == M_INSTANTIATED || c->mode == M_INIT) m->d_out = m->d_in;
    m->der_y = m->d_in;
    m->label_len = (int32_t)strlen(m->label);
    m->gain_sum = m->gains[0] + m->gains[1] + m->gains[2];
}

void model_initialize(Instance *c) {
    c->m.d_out = c->m.d_in;
    c->next_defined = false;
}

bool model_step_event(Instance *c) { return c->m.y_wrap > 0.0 && c->m.y >= c->m.y_wrap; }

void model_update(Instance *c) {
    ModelData *m = &c->m;
    m->d_out = m->d_in;
    if (model_step_event(c)) {
        double n = floor(m->y / m->y_wrap);
        m->y -= n * m->y_wrap;
        m->wraps += (int32_t)n;
        c->values_changed = true;
    }
}

void model_get_x(Instance *c, double x[]) { x[0] = c->m.y; }
void model_set_x(Instance *c, const double x[]) { c->m.y = x[0]; }
void model_der(Instance *c, double dx[]) { dx[0] = c->m.d_in; }
void model_nominals(Instance *c, double nominal[]) { (void)c; nominal[0] = 1.0; }
void model_indicators(Instance *c, double z[]) { (void)c; (void)z; }
