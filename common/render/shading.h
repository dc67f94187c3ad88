/* shading.h - what a hit on an imported triangle looks like: interpolated
 * shading normal, texture coordinates, textures folded into the material,
 * normal map, alpha cutout (glTF alphaMode MASK). The integrator calls these
 * only for scenes that have per-corner data (scene.corner_normals). */
#ifndef TESSERA_SHADING_H
#define TESSERA_SHADING_H

#include "intersect.h"
#include "scene.h"

/* Resolve material m at hit h on a triangle (geometric normal n, already
 * facing wo). Returns m, or scratch filled with m's textures applied, and
 * sets *ns to the shading normal (facing wo; n itself when the shading
 * normal would put wo below its horizon, or for glass, or for a triangle
 * with vertex normals of its own: then n is already its smooth normal,
 * shading_normal.h's). Returns NULL when
 * the surface is cut out here: the ray should pass through. Can't fail. */
const material *shading_resolve(const scene *s, const hit *h, const material *m, vec3 n, vec3 wo,
                                 material *scratch, vec3 *ns);

/* 1 when the material of triangle prim is cut out at barycentrics (b1, b2). */
int shading_cut_out(const scene *s, uint32_t prim, float b1, float b2);

/* accel_occluded, but rays pass through cut-out surfaces (at most 64 of
 * them; more count as occluded). */
int shading_occluded(const scene *s, const ray *r, float tmax);

#endif
