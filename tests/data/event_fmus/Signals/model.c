/* model.c - Signals equations (no events):
 *
 *   y = k u               (Float64 arrays of 3 in FMI 3: u[3] input, y[3] output; FMI 2:
 *                          scalars u[1], u[2], u[3], y[1], y[2], y[3])
 *   M = [u; y]            (Float64[2,3] output, row-major; FMI 3 only)
 *   ysum = y1 + y2 + y3   (output)
 *   energy = u . u        (local, not an output)
 *   der(x) = ysum         (x: a local continuous state, start 0)
 *   i64_out = i64_in,  u64_out = u64_in,  i8_out = i8_in   (passed through exactly)
 *   small = i64_in        (Int64 output declared min -100, max 100: the FMU does not keep to
 *                          its declared range when i64_in leaves it)
 *   k: structural parameter (FMI 3: settable in configuration mode only; FMI 2: parameter)
 */
#include "core.h"

const VarDef model_vars[] = {
    {0, "time", VT_F64, K_TIME, TIME_OFFSET, 1},
    {7, "k", VT_F64, K_SPARAM_, VAR_OFFSET(k), 1},
    {8, "ysum", VT_F64, K_CALC, VAR_OFFSET(ysum), 1},
    {9, "energy", VT_F64, K_CALC, VAR_OFFSET(energy), 1},
    {10, "x", VT_F64, K_START, VAR_OFFSET(x), 1},
    {11, "der(x)", VT_F64, K_CALC, VAR_OFFSET(der_x), 1},
    {12, "i64_in", VT_I64_, K_DINPUT, VAR_OFFSET(i64_in), 1},
    {13, "i64_out", VT_I64_, K_CALC, VAR_OFFSET(i64_out), 1},
    {14, "u64_in", VT_U64_, K_DINPUT, VAR_OFFSET(u64_in), 1},
    {15, "u64_out", VT_U64_, K_CALC, VAR_OFFSET(u64_out), 1},
    {16, "i8_in", VT_I8_, K_DINPUT, VAR_OFFSET(i8_in), 1},
    {17, "i8_out", VT_I8_, K_CALC, VAR_OFFSET(i8_out), 1},
    {18, "small", VT_I64_, K_CALC, VAR_OFFSET(small), 1},
#if FMI_VERSION == 3
    {1, "u", VT_F64, K_INPUT, VAR_OFFSET(u), 3},
    {2, "y", VT_F64, K_CALC, VAR_OFFSET(y), 3},
    {3, "M", VT_F64, K_CALC, VAR_OFFSET(M), 6},
#else
    {1, "u[1]", VT_F64, K_INPUT, VAR_OFFSET(u[0]), 1},
    {2, "u[2]", VT_F64, K_INPUT, VAR_OFFSET(u[1]), 1},
    {3, "u[3]", VT_F64, K_INPUT, VAR_OFFSET(u[2]), 1},
    {4, "y[1]", VT_F64, K_CALC, VAR_OFFSET(y[0]), 1},
    {5, "y[2]", VT_F64, K_CALC, VAR_OFFSET(y[1]), 1},
    {6, "y[3]", VT_F64, K_CALC, VAR_OFFSET(y[2]), 1},
#endif
};
const size_t model_nvars = sizeof model_vars / sizeof model_vars[0];

void model_start(Instance *c) {
    ModelData *m = &c->m;
    m->u[0] = 1.0;
    m->u[1] = 2.0;
    m->u[2] = 3.0;
    m->k = 2.0;
    m->x = 0.0;
    m->i64_in = 0;
    m->u64_in = 0;
    m->i8_in = 0;
}

void model_calc(Instance *c) {
    ModelData *m = &c->m;
    int i;
    m->ysum = 0.0;
    m->energy = 0.0;
    for (i = 0; i < 3; i++) {
        m->y[i] = m->k * m->u[i];
        m->M[i] = m->u[i];
        m->M[3 + i] = m->y[i];
        m->ysum += m->y[i];
        m->energy += m->u[i] * m->u[i];
    }
    m->der_x = m->ysum;
    m->i64_out = m->i64_in;
    m->u64_out = m->u64_in;
    m->i8_out = m->i8_in;
    m->small = m->i64_in;
}

void model_initialize(Instance *c) { c->next_defined = false; }
void model_update(Instance *c) { (void)c; }
void model_get_x(Instance *c, double x[]) { x[0] = c->m.x; }
void model_set_x(Instance *c, const double x[]) { c->m.x = x[0]; }
void model_der(Instance *c, double dx[]) {
    model_calc(c);
    dx[0] = c->m.der_x;
}
void model_nominals(Instance *c, double nominal[]) { (void)c; nominal[0] = 1.0; }
void model_indicators(Instance *c, double z[]) { (void)c; (void)z; }

bool model_step_event(Instance *c) {
    (void)c;
    return false;
}
