/* spherical.h - sampling a triangle uniformly by the solid angle it
 * subtends from a point (Arvo 1995, "Stratified sampling of spherical
 * triangles", in the form of pbrt-v4), for light sampling: the density is
 * then constant over the directions that reach the light,
 *   pdf(w) = 1 / Omega   (solid-angle measure),
 * instead of area sampling's d^2 / (|cos_l| A), which spikes near the light
 * and at grazing angles.
 *
 * It costs trigonometry, and far from a triangle (farther from its plane
 * than its longest edge, Cycles' rule) area sampling's density is nearly
 * uniform in solid angle anyway; Arvo's map also loses precision in single
 * precision when the triangle subtends almost nothing or almost a
 * hemisphere. So it is meant only for points nearer the plane than the
 * longest edge where SPHERICAL_MIN_SOLID_ANGLE <= Omega <=
 * SPHERICAL_MAX_SOLID_ANGLE (spherical_triangle_use: geometry only, so a
 * light sampler and its MIS density would agree, and so would every worker),
 * area sampling otherwise.
 *
 * NOT USED by lights.c: measured on the Cornell box and spheres (64 spp,
 * docs/performance.md) it lowered the image's variance by 0.5-2% and cost
 * 18-54% more CPU time. Kept, with its test, for scenes with large lights
 * close to what they light. */
#ifndef TESSERA_SPHERICAL_H
#define TESSERA_SPHERICAL_H

#include "vec.h"

#define SPHERICAL_MIN_SOLID_ANGLE 3e-4f /* pbrt-v4's bounds */
#define SPHERICAL_MAX_SOLID_ANGLE 6.22f

/* Solid angle (steradians) of triangle v0 v1 v2 seen from p (Van Oosterom
 * and Strackee 1983): 2 atan2(|a.(b x c)|, 1 + a.b + b.c + c.a) with a, b, c
 * the unit directions to the vertices. 0 for a degenerate view (p on the
 * triangle's plane or a vertex). */
float spherical_triangle_solid_angle(vec3 v0, vec3 v1, vec3 v2, vec3 p);

/* 1 when triangle v0 v1 v2 is sampled by solid angle from p (the rule
 * above; its solid angle in *omega), 0 when by area (*omega then 0 or the
 * solid angle). */
int spherical_triangle_use(vec3 v0, vec3 v1, vec3 v2, vec3 p, float *omega);

/* A direction from p uniform over the triangle's solid angle, given as the
 * barycentrics (b1, b2) of v1 and v2 of the point it reaches (clamped into
 * the triangle). pdf = 1 / omega. Returns 0 (and nothing usable) when the
 * view is degenerate. */
int spherical_triangle_sample(vec3 v0, vec3 v1, vec3 v2, vec3 p, float u1, float u2, float *b1, float *b2);

#endif
