/* camera.h - primary rays for the perspective and environment cameras.
 *
 * Pixel (x, y) with jitter (u, v) in [0,1)^2 covers the film point
 * (x + u, y + v); row 0 is the top of the image. Directions are in the
 * scene's internal frame (see scene.h), which only translates and scales
 * the world, so world-space formulas apply unchanged. */
#ifndef TESSERA_CAMERA_H
#define TESSERA_CAMERA_H

#include "scene.h"

/* Unit direction of the ray through film point (x + u, y + v) of a width x
 * height image. Perspective: vertical field of view, square pixels.
 * Environment (equirectangular, 360 x 180 degrees):
 *   theta = pi (y + v) / H, phi = 2 pi (x + u) / W,
 *   dir = (sin theta cos phi, cos theta, sin theta sin phi).
 * Can't fail. */
vec3 camera_direction(const camera *c, int width, int height, int x, int y, float u, float v);

/* What camera_direction computes once per image size: the perspective
 * camera's film-to-screen factors (2 / W, 2 / H, tan(fov / 2) with and
 * without the aspect ratio), so that a ray costs no division but its
 * normalisation. Plain struct, filled by camera_raster_init. */
typedef struct {
    const camera *c;
    int width, height;
    float two_over_w, two_over_h, tan_x, tan_y;
} camera_raster;

/* Fill r for c (not copied: it must outlive r) at width x height. Can't fail. */
void camera_raster_init(camera_raster *r, const camera *c, int width, int height);

/* camera_direction(r->c, r->width, r->height, x, y, u, v), bit for bit. */
vec3 camera_raster_direction(const camera_raster *r, int x, int y, float u, float v);

#endif
