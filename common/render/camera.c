/* camera.c - primary ray directions. */
#include "camera.h"

static vec3 perspective_direction(const camera *c, int width, int height, float fx, float fy) {
    float aspect = (float)width / (float)height;
    float sx = (2.0f * fx / (float)width - 1.0f) * c->tan_half_fov * aspect;
    float sy = (1.0f - 2.0f * fy / (float)height) * c->tan_half_fov;
    vec3 d = vec3_add(c->forward, vec3_add(vec3_scale(c->right, sx), vec3_scale(c->up, sy)));
    return vec3_normalize(d);
}

static vec3 environment_direction(int width, int height, float fx, float fy) {
    float theta = TS_PI * fy / (float)height;
    float phi = 2.0f * TS_PI * fx / (float)width;
    float st = sinf(theta);
    return vec3_make(st * cosf(phi), cosf(theta), st * sinf(phi));
}

vec3 camera_direction(const camera *c, int width, int height, int x, int y, float u, float v) {
    float fx = (float)x + u, fy = (float)y + v;
    if (c->kind == CAMERA_ENVIRONMENT) return environment_direction(width, height, fx, fy);
    return perspective_direction(c, width, height, fx, fy);
}
