/* punctual.h - the delta lights: point, KHR_lights_punctual spot and
 * directional (lights.c calls these).
 *
 * Point: intensity I in every direction, radiance-like term I / d^2,
 *   pdf = the selection probability.
 * Spot: intensity I at the apex, attenuated by the glTF spec's smooth cone
 *   a = clamp((cos - cos_outer) / (cos_inner - cos_outer), 0, 1)^2,
 * radiance-like term I a / d^2, pdf = the selection probability.
 * Directional: irradiance E along `direction` from infinitely far away
 * (the shadow ray runs PUNCTUAL_FAR internal units), pdf = selection. */
#ifndef TESSERA_PUNCTUAL_H
#define TESSERA_PUNCTUAL_H

#include "lights.h"

#define PUNCTUAL_FAR 1.0e4f /* the scene spans about [-1, 1]^3 internally */

/* Fill *out for light l (LIGHT_SPOT or LIGHT_DIRECTIONAL) seen from ref.
 * Returns 1 when the light can reach ref, else 0. */
int punctual_sample(const light *l, vec3 ref, light_sample *out);

#endif
