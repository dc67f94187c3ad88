/* shading.h - what a hit on an imported triangle looks like: texture
 * coordinates, textures folded into the material, normal map, alpha cutout
 * (glTF alphaMode MASK). The interpolated shading normal is not here: every
 * triangle with vertex normals gets it from shading_normal.h. The
 * integrator calls these only for scenes that have per-corner uvs
 * (scene.corner_uvs). */
#ifndef TESSERA_SHADING_H
#define TESSERA_SHADING_H

#include "intersect.h"
#include "scene.h"

/* Resolve material m at hit h on a triangle, where n is the normal the
 * integrator shades with (facing wo for opaque materials; the interpolated
 * vertex normal, shading_normal.h, where the triangle has them). Returns m,
 * or scratch filled with m's textures applied, and sets *ns to n bent by
 * m's normal map, or to n itself (no map, glass, or a bent normal that
 * would put wo below its horizon); sets *bent to 1 when it bent n (so that
 * the leak guard applies), else leaves it alone. Returns NULL when the
 * surface is cut out here: the ray should pass through. Can't fail. */
const material *shading_resolve(const scene *s, const hit *h, const material *m, vec3 n, vec3 wo,
                                 material *scratch, vec3 *ns, int *bent);

/* 1 when the material of triangle prim is cut out at barycentrics (b1, b2). */
int shading_cut_out(const scene *s, uint32_t prim, float b1, float b2);

/* accel_occluded, but rays pass through cut-out surfaces (at most 64 of
 * them; more count as occluded). */
int shading_occluded(const scene *s, const ray *r, float tmax);

#endif
