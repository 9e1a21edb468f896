/* uwc_map.c - bicubic B-spline terrain-depth kernel (see uwc_map.h). */
#include "uwc_map.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int host_is_little_endian(void) {
    const uint16_t one = 1;
    return *(const unsigned char *)&one == 1;
}

void uwc_map_free(uwc_map *m) {
    if (m == NULL) return;
    free(m->c);
    memset(m, 0, sizeof(*m));
}

int uwc_map_load(uwc_map *m, const char *path, char *err, size_t errlen) {
    unsigned char header[48];
    int32_t nx, ny;
    double g[4];
    size_t count, got;
    FILE *f;

    memset(m, 0, sizeof(*m));
    if (!host_is_little_endian()) {
        snprintf(err, errlen, "map file '%s': big-endian hosts are not supported", path);
        return -1;
    }
    f = fopen(path, "rb");
    if (f == NULL) {
        snprintf(err, errlen, "map file '%s' cannot be opened (%s)", path, strerror(errno));
        return -1;
    }
    if (fread(header, 1, sizeof(header), f) != sizeof(header)) {
        fclose(f);
        snprintf(err, errlen, "map file '%s' is truncated (incomplete header)", path);
        return -1;
    }
    if (memcmp(header, "UWCBATH1", 8) != 0) {
        fclose(f);
        snprintf(err, errlen, "map file '%s' is not a UWCBATH1 coefficient file", path);
        return -1;
    }
    memcpy(&nx, header + 8, 4);
    memcpy(&ny, header + 12, 4);
    memcpy(g, header + 16, sizeof(g));
    if (nx < 4 || ny < 4 || nx > UWC_MAP_MAX_NODES || ny > UWC_MAP_MAX_NODES) {
        fclose(f);
        snprintf(err, errlen, "map file '%s': invalid grid size %d x %d", path, (int)nx, (int)ny);
        return -1;
    }
    if (!(isfinite(g[0]) && isfinite(g[1]) && g[2] > 0 && g[3] > 0 && isfinite(g[2])
          && isfinite(g[3]))) {
        fclose(f);
        snprintf(err, errlen, "map file '%s': invalid origin or spacing", path);
        return -1;
    }
    count = (size_t)(nx + 2 * UWC_MAP_PAD) * (size_t)(ny + 2 * UWC_MAP_PAD);
    m->c = (double *)malloc(count * sizeof(double));
    if (m->c == NULL) {
        fclose(f);
        snprintf(err, errlen, "map file '%s': out of memory for %d x %d grid", path, (int)nx,
                 (int)ny);
        return -1;
    }
    got = fread(m->c, sizeof(double), count, f);
    fclose(f);
    if (got != count) {
        uwc_map_free(m);
        snprintf(err, errlen, "map file '%s' is truncated (%lu of %lu coefficients)", path,
                 (unsigned long)got, (unsigned long)count);
        return -1;
    }
    m->nx = nx;
    m->ny = ny;
    m->x0 = g[0];
    m->y0 = g[1];
    m->dx = g[2];
    m->dy = g[3];
    return 0;
}

void uwc_map_extent(const uwc_map *m, double ext[4]) {
    ext[0] = m->x0;
    ext[1] = m->x0 + (m->nx - 1) * m->dx;
    ext[2] = m->y0;
    ext[3] = m->y0 + (m->ny - 1) * m->dy;
}

int uwc_map_inside(const uwc_map *m, double x, double y) {
    double ext[4];
    uwc_map_extent(m, ext);
    return x >= ext[0] && x <= ext[1] && y >= ext[2] && y <= ext[3];
}

/* Cubic B-spline weights at fraction f (same formulas as uwcosim.bspline.basis;
   tests/test_bathymetry_kernel.py checks this kernel against it). */
static void basis(double f, double w[4]) {
    const double g = 1.0 - f, f2 = f * f, f3 = f * f * f;
    w[0] = g * g * g / 6.0;
    w[1] = (3 * f3 - 6 * f2 + 4) / 6.0;
    w[2] = (-3 * f3 + 3 * f2 + 3 * f + 1) / 6.0;
    w[3] = f3 / 6.0;
}

/* Cell index and fraction along one axis (same clamping as uwcosim.bspline.cell). */
static int cell(double s, double s0, double ds, int n, double *frac) {
    double u = (s - s0) / ds;
    int i;
    if (!(u >= 0.0)) u = 0.0;  /* also maps NaN to the first cell */
    if (u > n - 1.0) u = n - 1.0;
    i = (int)floor(u);
    if (i > n - 2) i = n - 2;
    *frac = u - i;
    return i;
}

double uwc_map_depth(const uwc_map *m, double x, double y) {
    double fu, fv, wu[4], wv[4], val = 0.0;
    const int iu = cell(x, m->x0, m->dx, m->nx, &fu);
    const int iv = cell(y, m->y0, m->dy, m->ny, &fv);
    const size_t stride = (size_t)m->nx + 2 * UWC_MAP_PAD;
    int a, b;
    basis(fu, wu);
    basis(fv, wv);
    /* coefficient of grid node j sits at padded index j + PAD; the stencil is j-1..j+2 */
    for (b = 0; b < 4; b++) {
        const double *row = m->c + (size_t)(iv + b - 1 + UWC_MAP_PAD) * stride;
        for (a = 0; a < 4; a++) {
            val += wu[a] * wv[b] * row[iu + a - 1 + UWC_MAP_PAD];
        }
    }
    return val;
}
