/* spherical.c - uniform sampling of a triangle's solid angle (Arvo 1995,
 * after pbrt-v4's SampleSphericalTriangle) and of a rectangle's (Urena et
 * al. 2013, after pbrt-v4's SampleSphericalRectangle). See spherical.h. */
#include "spherical.h"

static float clamp_f(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }
static float safe_asin(float x) { return asinf(clamp_f(x, -1.0f, 1.0f)); }

/* The angle between unit vectors, accurate near 0 and pi too. */
static float angle_between(vec3 a, vec3 b) {
    if (vec3_dot(a, b) < 0.0f) return TS_PI - 2.0f * safe_asin(vec3_length(vec3_add(a, b)) * 0.5f);
    return 2.0f * safe_asin(vec3_length(vec3_sub(b, a)) * 0.5f);
}

/* v minus its component along unit w. */
static vec3 gram_schmidt(vec3 v, vec3 w) { return vec3_sub(v, vec3_scale(w, vec3_dot(v, w))); }

float spherical_triangle_solid_angle(vec3 v0, vec3 v1, vec3 v2, vec3 p) {
    vec3 a = vec3_sub(v0, p), b = vec3_sub(v1, p), c = vec3_sub(v2, p);
    float la = vec3_length(a), lb = vec3_length(b), lc = vec3_length(c);
    if (!(la > 0.0f && lb > 0.0f && lc > 0.0f)) return 0.0f;
    a = vec3_scale(a, 1.0f / la), b = vec3_scale(b, 1.0f / lb), c = vec3_scale(c, 1.0f / lc);
    float num = fabsf(vec3_dot(a, vec3_cross(b, c)));
    float den = 1.0f + vec3_dot(a, b) + vec3_dot(b, c) + vec3_dot(c, a);
    float omega = 2.0f * atan2f(num, den);
    return isfinite(omega) ? fabsf(omega) : 0.0f;
}

int spherical_triangle_use(vec3 v0, vec3 v1, vec3 v2, vec3 p, float *omega) {
    /* Cheap test first (Cycles' rule): only a point closer to the
     * triangle's plane than its longest edge is long sees the area pdf
     * d^2 / (|cos_l| A) vary enough to be worth the trigonometry. */
    vec3 e0 = vec3_sub(v1, v0), e1 = vec3_sub(v2, v1), e2 = vec3_sub(v0, v2);
    float longest2 = max_f(vec3_dot(e0, e0), max_f(vec3_dot(e1, e1), vec3_dot(e2, e2)));
    vec3 n = vec3_cross(e0, vec3_neg(e2));
    float h = vec3_dot(vec3_sub(p, v0), n); /* distance to the plane times |n| */
    *omega = 0.0f;
    if (!(longest2 * vec3_dot(n, n) > h * h)) return 0;
    *omega = spherical_triangle_solid_angle(v0, v1, v2, p);
    return *omega >= SPHERICAL_MIN_SOLID_ANGLE && *omega <= SPHERICAL_MAX_SOLID_ANGLE;
}

int spherical_triangle_sample(vec3 v0, vec3 v1, vec3 v2, vec3 p, float u1, float u2, float *b1_out,
                              float *b2_out) {
    vec3 a = vec3_sub(v0, p), b = vec3_sub(v1, p), c = vec3_sub(v2, p);
    if (!(vec3_length(a) > 0.0f && vec3_length(b) > 0.0f && vec3_length(c) > 0.0f)) return 0;
    a = vec3_normalize(a), b = vec3_normalize(b), c = vec3_normalize(c);
    /* Unit normals of the great circles through each pair of vertices. */
    vec3 n_ab = vec3_cross(a, b), n_bc = vec3_cross(b, c), n_ca = vec3_cross(c, a);
    if (!(vec3_length(n_ab) > 0.0f && vec3_length(n_bc) > 0.0f && vec3_length(n_ca) > 0.0f)) return 0;
    n_ab = vec3_normalize(n_ab), n_bc = vec3_normalize(n_bc), n_ca = vec3_normalize(n_ca);
    /* The spherical triangle's inner angles; its area is their sum - pi. */
    float alpha = angle_between(n_ab, vec3_neg(n_ca));
    float beta = angle_between(n_bc, vec3_neg(n_ab));
    float gamma = angle_between(n_ca, vec3_neg(n_bc));
    float area_pi = alpha + beta + gamma;
    if (!(area_pi > TS_PI)) return 0;
    /* u1 picks the sub-triangle a b c' of area A' = u1 A: find c' on the
     * arc from a to c. */
    float ap_pi = TS_PI + u1 * (area_pi - TS_PI);
    float cos_alpha = cosf(alpha), sin_alpha = sinf(alpha);
    float sin_ap = sinf(ap_pi), cos_ap = cosf(ap_pi);
    float sin_phi = sin_ap * cos_alpha - cos_ap * sin_alpha;
    float cos_phi = cos_ap * cos_alpha + sin_ap * sin_alpha;
    float k1 = cos_phi + cos_alpha;
    float k2 = sin_phi - sin_alpha * vec3_dot(a, b);
    float cos_bp = (k2 + (k2 * cos_phi - k1 * sin_phi) * cos_alpha) / ((k2 * sin_phi + k1 * cos_phi) * sin_alpha);
    cos_bp = clamp_f(isfinite(cos_bp) ? cos_bp : 1.0f, -1.0f, 1.0f);
    float sin_bp = sqrt_clamped(1.0f - cos_bp * cos_bp);
    vec3 c_perp = gram_schmidt(c, a);
    if (!(vec3_length(c_perp) > 0.0f)) return 0;
    vec3 cp = vec3_add(vec3_scale(a, cos_bp), vec3_scale(vec3_normalize(c_perp), sin_bp));
    /* u2 picks the direction on the arc from b to c', with the density
     * that makes the whole map uniform in solid angle. */
    float cos_t = 1.0f - u2 * (1.0f - vec3_dot(cp, b));
    float sin_t = sqrt_clamped(1.0f - cos_t * cos_t);
    vec3 cp_perp = gram_schmidt(cp, b);
    vec3 w = vec3_scale(b, cos_t);
    if (vec3_length(cp_perp) > 0.0f) w = vec3_add(w, vec3_scale(vec3_normalize(cp_perp), sin_t));
    /* Where w meets the triangle's plane (Moller-Trumbore), as barycentrics. */
    vec3 e1 = vec3_sub(v1, v0), e2 = vec3_sub(v2, v0);
    vec3 s1 = vec3_cross(w, e2);
    float divisor = vec3_dot(s1, e1);
    if (!(divisor != 0.0f) || !isfinite(divisor)) return 0;
    float inv = 1.0f / divisor;
    vec3 s = vec3_sub(p, v0);
    float b1 = clamp_f(vec3_dot(s, s1) * inv, 0.0f, 1.0f);
    float b2 = clamp_f(vec3_dot(w, vec3_cross(s, e1)) * inv, 0.0f, 1.0f);
    if (b1 + b2 > 1.0f) {
        float sum = b1 + b2;
        b1 /= sum, b2 /= sum;
    }
    if (!isfinite(b1) || !isfinite(b2)) return 0;
    *b1_out = b1, *b2_out = b2;
    return 1;
}

int spherical_rect_init(spherical_rect *r, vec3 corner, vec3 ex, vec3 ey, vec3 p) {
    float exl = vec3_length(ex), eyl = vec3_length(ey);
    r->omega = 0.0f;
    if (!(exl > 0.0f && eyl > 0.0f)) return 0;
    r->p = p;
    r->x = vec3_scale(ex, 1.0f / exl), r->y = vec3_scale(ey, 1.0f / eyl);
    r->z = vec3_cross(r->x, r->y);
    vec3 d = vec3_sub(corner, p);
    r->z0 = vec3_dot(d, r->z);
    if (r->z0 > 0.0f) r->z = vec3_neg(r->z), r->z0 = -r->z0;
    if (!(r->z0 < 0.0f)) return 0; /* on the plane */
    r->x0 = vec3_dot(d, r->x), r->y0 = vec3_dot(d, r->y);
    r->x1 = r->x0 + exl, r->y1 = r->y0 + eyl;
    /* Normals of the planes through p and each edge, and the spherical
     * rectangle's inner angles g0..g3; its area is their sum - 2 pi. */
    vec3 v00 = vec3_make(r->x0, r->y0, r->z0), v01 = vec3_make(r->x0, r->y1, r->z0);
    vec3 v10 = vec3_make(r->x1, r->y0, r->z0), v11 = vec3_make(r->x1, r->y1, r->z0);
    vec3 n0 = vec3_normalize(vec3_cross(v00, v10)), n1 = vec3_normalize(vec3_cross(v10, v11));
    vec3 n2 = vec3_normalize(vec3_cross(v11, v01)), n3 = vec3_normalize(vec3_cross(v01, v00));
    float g0 = angle_between(vec3_neg(n0), n1), g1 = angle_between(vec3_neg(n1), n2);
    float g2 = angle_between(vec3_neg(n2), n3), g3 = angle_between(vec3_neg(n3), n0);
    r->b0 = n0.z, r->b1 = n2.z;
    r->k = 2.0f * TS_PI - g2 - g3;
    r->omega = g0 + g1 - r->k;
    if (!isfinite(r->omega)) r->omega = 0.0f;
    return r->omega >= SPHERICAL_MIN_SOLID_ANGLE && r->omega <= SPHERICAL_MAX_SOLID_ANGLE;
}

vec3 spherical_rect_sample(const spherical_rect *r, float u1, float u2) {
    /* u1: the sub-rectangle [x0, xu] of solid angle u1 omega. */
    float au = u1 * r->omega + r->k;
    float fu = (cosf(au) * r->b0 - r->b1) / sinf(au);
    float cu = 1.0f / sqrtf(fu * fu + r->b0 * r->b0);
    if (!(fu > 0.0f)) cu = -cu;
    cu = clamp_f(isfinite(cu) ? cu : 0.0f, -0x1.fffffep-1f, 0x1.fffffep-1f);
    float xu = clamp_f(-(cu * r->z0) / sqrt_clamped(1.0f - cu * cu), r->x0, r->x1);
    /* u2: along y at xu, uniform in the solid angle's measure there. */
    float dd = sqrtf(xu * xu + r->z0 * r->z0);
    float h0 = r->y0 / sqrtf(dd * dd + r->y0 * r->y0), h1 = r->y1 / sqrtf(dd * dd + r->y1 * r->y1);
    float hv = h0 + u2 * (h1 - h0), hv2 = hv * hv;
    float yv = hv2 < 1.0f - 1e-6f ? hv * dd / sqrtf(1.0f - hv2) : r->y1;
    yv = clamp_f(yv, r->y0, r->y1);
    return vec3_add(r->p, vec3_add(vec3_add(vec3_scale(r->x, xu), vec3_scale(r->y, yv)), vec3_scale(r->z, r->z0)));
}
