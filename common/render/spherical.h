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
 * 18-54% more CPU time; the rectangle sampler below, used for the box's
 * quad light near the light (Cycles' rule), by 0.4% for 27% more CPU. Kept,
 * with their tests, for scenes with large lights close to what they
 * light. */
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

/* A rectangle seen from a point, ready for sampling its solid angle (Urena,
 * Fajardo and King 2013, "An area-preserving parametrization for spherical
 * rectangles", in the form of pbrt-v4's SampleSphericalRectangle): the
 * rectangle's local frame, its corners' coordinates from p, and its solid
 * angle. Plain struct, on the caller's stack. */
typedef struct {
    vec3 p, x, y, z;      /* the point; unit edge directions; z points from p's side towards the plane */
    float x0, x1, y0, y1; /* the rectangle's extent in the frame, from p */
    float z0;             /* distance from p to the plane, negated (<= 0) */
    float b0, b1, k;      /* Urena's b0, b1 and k = 2 pi - g2 - g3 */
    float omega;          /* solid angle, steradians */
} spherical_rect;

/* Prepare rectangle corner + a ex + b ey (a, b in [0, 1]; ex and ey at right
 * angles) seen from p. Returns 1 when its solid angle is within
 * [SPHERICAL_MIN_SOLID_ANGLE, SPHERICAL_MAX_SOLID_ANGLE] and p is off its
 * plane (sampling is then well conditioned), 0 otherwise (r->omega then
 * holds whatever was computed, possibly 0). Geometry only. */
int spherical_rect_init(spherical_rect *r, vec3 corner, vec3 ex, vec3 ey, vec3 p);

/* The point of the rectangle reached by a direction from r->p uniform over
 * its solid angle: pdf = 1 / r->omega (solid-angle measure). u1 picks the
 * position along ex, u2 along ey, each monotonically, so stratified (u1, u2)
 * give stratified directions. Needs spherical_rect_init to have returned 1;
 * can't fail then (results are clamped into the rectangle). */
vec3 spherical_rect_sample(const spherical_rect *r, float u1, float u2);

#endif
