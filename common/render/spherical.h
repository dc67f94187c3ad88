/* spherical.h - sampling a triangle uniformly by the solid angle it
 * subtends from a point (Arvo 1995, "Stratified sampling of spherical
 * triangles", in the form of pbrt-v4), for light sampling: the density is
 * then constant over the directions that reach the light,
 *   pdf(w) = 1 / Omega   (solid-angle measure),
 * instead of area sampling's d^2 / (|cos_l| A), which spikes near the light
 * and at grazing angles.
 *
 * Arvo's map loses precision in single precision when the triangle subtends
 * almost nothing or almost a hemisphere, so a light uses it only when
 * SPHERICAL_MIN_SOLID_ANGLE <= Omega <= SPHERICAL_MAX_SOLID_ANGLE and area
 * sampling otherwise. The choice depends on the geometry only (the same
 * Omega computed the same way), so light sampling and the MIS density agree
 * on it and every worker makes the same choice. */
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

/* 1 when triangle v0 v1 v2 is sampled by solid angle from p (its solid
 * angle omega, returned in *omega, is within the bounds above), 0 when by
 * area. */
int spherical_triangle_use(vec3 v0, vec3 v1, vec3 v2, vec3 p, float *omega);

/* A direction from p uniform over the triangle's solid angle, given as the
 * barycentrics (b1, b2) of v1 and v2 of the point it reaches (clamped into
 * the triangle). pdf = 1 / omega. Returns 0 (and nothing usable) when the
 * view is degenerate. */
int spherical_triangle_sample(vec3 v0, vec3 v1, vec3 v2, vec3 p, float u1, float u2, float *b1, float *b2);

#endif
