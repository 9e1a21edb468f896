/* uwc_map.h - bicubic B-spline terrain-depth kernel of the DepthSounder FMU.
 *
 * Reads the UWCBATH1 coefficient files written by
 * uwcosim.models.terrain.Bathymetry.write_coefficients (little-endian):
 *   char magic[8] = "UWCBATH1"; int32 nx, ny; float64 x0, y0, dx, dy;
 *   float64 c[(ny + 6) * (nx + 6)]   (x fastest, 3 mirrored padding nodes on each side)
 * and evaluates the same spline as Bathymetry.depth (numpy reference algorithm).
 */
#ifndef UWC_MAP_H
#define UWC_MAP_H

#include <stddef.h>

#define UWC_MAP_PAD 3
#define UWC_MAP_MAX_NODES 100000  /* per axis */

typedef struct {
    int nx, ny;               /* grid nodes along x and y */
    double x0, y0, dx, dy;    /* origin and spacing (m) */
    double *c;                /* padded coefficients, (ny + 6) rows of (nx + 6) */
} uwc_map;

/* Load a coefficient file into m (malloc'd). Returns 0 on success; otherwise -1 with a
 * one-line message naming the file in err. m is left empty on failure. */
int uwc_map_load(uwc_map *m, const char *path, char *err, size_t errlen);

/* Release the coefficients (safe on an empty map). */
void uwc_map_free(uwc_map *m);

/* Grid extent: ext = {xmin, xmax, ymin, ymax}. */
void uwc_map_extent(const uwc_map *m, double ext[4]);

/* 1 when (x, y) lies inside the grid extent (edges included), 0 otherwise (also for NaN). */
int uwc_map_inside(const uwc_map *m, double x, double y);

/* Spline depth at (x, y); points outside the grid take the value at the nearest edge. */
double uwc_map_depth(const uwc_map *m, double x, double y);

#endif
