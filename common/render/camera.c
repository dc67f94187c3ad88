/* camera.c - primary ray directions. */
#include "camera.h"

/* The film point (fx, fy) on the screen at distance 1: sx = (fx 2/W - 1)
 * tan(fov/2) aspect, sy = (1 - fy 2/H) tan(fov/2). */
static vec3 perspective_direction(const camera_raster *r, float fx, float fy) {
    const camera *c = r->c;
    float sx = (fx * r->two_over_w - 1.0f) * r->tan_x;
    float sy = (1.0f - fy * r->two_over_h) * r->tan_y;
    vec3 d = vec3_add(c->forward, vec3_add(vec3_scale(c->right, sx), vec3_scale(c->up, sy)));
    return vec3_normalize(d);
}

static vec3 environment_direction(int width, int height, float fx, float fy) {
    float theta = TS_PI * fy / (float)height;
    float phi = 2.0f * TS_PI * fx / (float)width;
    float st = sinf(theta);
    return vec3_make(st * cosf(phi), cosf(theta), st * sinf(phi));
}

void camera_raster_init(camera_raster *r, const camera *c, int width, int height) {
    r->c = c;
    r->width = width;
    r->height = height;
    r->two_over_w = 2.0f / (float)width;
    r->two_over_h = 2.0f / (float)height;
    r->tan_y = c->tan_half_fov;
    r->tan_x = c->tan_half_fov * ((float)width / (float)height);
}

vec3 camera_raster_direction(const camera_raster *r, int x, int y, float u, float v) {
    float fx = (float)x + u, fy = (float)y + v;
    if (r->c->kind == CAMERA_ENVIRONMENT) return environment_direction(r->width, r->height, fx, fy);
    return perspective_direction(r, fx, fy);
}

vec3 camera_direction(const camera *c, int width, int height, int x, int y, float u, float v) {
    camera_raster r;
    camera_raster_init(&r, c, width, height);
    return camera_raster_direction(&r, x, y, u, v);
}
