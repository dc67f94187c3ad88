/* lights.h - sampling the scene's lights from a shading point (next-event
 * estimation), and the matching densities for multiple importance sampling.
 *
 * A light is picked with probability select_pdf (proportional to power, see
 * scene_load.c), then a point on it:
 *   triangle: uniform by area,     pdf = select * d^2 / (|cos_l| A)
 *   sphere, from outside: uniform in the subtended cone,
 *                                  pdf = select / (2 pi (1 - cos_max))
 *   sphere, from inside: uniform by area, as a triangle
 *   point: the point itself (a delta), pdf = select. */
#ifndef TESSERA_LIGHTS_H
#define TESSERA_LIGHTS_H

#include "scene.h"

typedef struct {
    vec3 p;        /* point on the light */
    vec3 n;        /* unit normal there, facing the shading point (area lights) */
    vec3 wi;       /* unit direction from the shading point to p */
    float dist;    /* distance to p */
    vec3 radiance; /* area: emitted radiance toward the shading point;
                      point: intensity / dist^2 (incident radiance-like) */
    float pdf;     /* solid-angle density including selection; for a point light
                      the selection probability */
    int is_delta;  /* point light: no MIS */
    uint32_t prim; /* emitter's primitive id (PRIM_NONE for point lights) */
} light_sample;

/* Pick a light with u1 and a point on it with (u1', u2), where u1' is u1
 * rescaled within the picked light's slice of the selection CDF (uniform
 * again, given the pick), as seen from `ref`. Reusing u1 this way carries the
 * 2D stratification of (u1, u2) over onto every light. Returns 1 and fills
 * *out when the sample can carry light, 0 when it cannot (no lights, back of
 * a one-sided emitter, degenerate geometry). */
int lights_sample(const scene *s, vec3 ref, float u1, float u2, light_sample *out);

/* Radiance leaving light l at a point with unit geometric normal n toward
 * direction w (unit, pointing away from the light). Zero behind a one-sided
 * emitter. */
vec3 lights_emitted(const light *l, vec3 n, vec3 w);

/* The density lights_sample would have given to reaching point p (normal n,
 * at distance dist from ref) on light l. */
float lights_pdf(const scene *s, const light *l, vec3 ref, vec3 p, vec3 n, float dist);

#endif
