/* accel_embree.c - Embree 3 walks the tree, Tessera decides the hits
 * (accel_embree.h says what is guaranteed).
 *
 * All of a scene's primitives are one Embree user geometry: primitive i is
 * Tessera's primitive i (triangles, then spheres). Embree asks for boxes,
 * builds its BVH in parallel, and during traversal calls cb_intersect or
 * cb_occluded for each primitive of each leaf it reaches.
 *
 * Why the answer cannot depend on Embree. Embree skips a box when its own
 * slab test, in its own ISA's arithmetic, puts the box outside
 * [0, ray.tfar]. Two margins make that impossible for a box holding a
 * primitive that could still win:
 *  - every box is padded by BOX_PAD times its largest coordinate (plus
 *    BOX_PAD absolute; scene units are about 1), thousands of ulps, far more
 *    than any slab test's rounding;
 *  - ray.tfar, the culling distance, is never the best t itself but
 *    accel_cull_distance(t) = t (1 + 2^-12), so a candidate whose t equals
 *    the best (a tie, decided by index) or is below it is never culled.
 * The callbacks compare candidates only by hit_before() on the numbers of
 * intersect.h computed with the caller's tmax, never with ray.tfar. So the
 * result is the minimum over all primitives, whichever order they come in. */
#include "accel_embree.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "elapsed.h"

#define BOX_PAD (1.0f / 65536.0f)

struct accel_embree {
    accel_embree_device dev;
    RTCScene scene;
    const scene *s;
    accel_embree_stats stats;
};

/* One query: Embree's context first, so a callback can cast back to it. */
typedef struct {
    struct RTCIntersectContext ctx;
    const scene *s;
    ray_prep r;
    float tmax; /* the caller's */
    hit best;
    int found;
} query;

/* Tessera's test of primitive id (as bvh.c's prim_hit does it). */
static inline int prim_test(const scene *s, const ray_prep *r, uint32_t id, float tmax, float *t, float *b1,
                            float *b2) {
    *b1 = *b2 = 0;
    if (id < s->triangle_count)
        return id != r->skip && triangle_intersect(r, &s->triangles[id], tmax, t, b1, b2);
    return sphere_intersect(r, &s->spheres[id - s->triangle_count], id == r->skip, tmax, t);
}

/* fminf and fmaxf for the finite corners of a box, inline (fminf is a call
 * into libm: 10.5M triangles' boxes are asked for twice by Embree's build);
 * they differ from fminf/fmaxf only in the sign of a zero, which the
 * padding below erases (-0 - pad == +0 - pad): the same boxes, bit for bit. */
static inline float min3(float a, float b, float c) {
    float m = b < c ? b : c;
    return a < m ? a : m;
}
static inline float max3(float a, float b, float c) {
    float m = b > c ? b : c;
    return a > m ? a : m;
}

void accel_padded_box(const scene *s, uint32_t id, float lo[3], float hi[3]) {
    if (id < s->triangle_count) {
        const triangle *t = &s->triangles[id];
        lo[0] = min3(t->v0.x, t->v1.x, t->v2.x);
        lo[1] = min3(t->v0.y, t->v1.y, t->v2.y);
        lo[2] = min3(t->v0.z, t->v1.z, t->v2.z);
        hi[0] = max3(t->v0.x, t->v1.x, t->v2.x);
        hi[1] = max3(t->v0.y, t->v1.y, t->v2.y);
        hi[2] = max3(t->v0.z, t->v1.z, t->v2.z);
    } else {
        const sphere *sp = &s->spheres[id - s->triangle_count];
        vec3 c = sp->center;
        lo[0] = c.x - sp->radius, lo[1] = c.y - sp->radius, lo[2] = c.z - sp->radius;
        hi[0] = c.x + sp->radius, hi[1] = c.y + sp->radius, hi[2] = c.z + sp->radius;
    }
    float m = 0;
    for (int a = 0; a < 3; a++) m = max3(m, fabsf(lo[a]), fabsf(hi[a]));
    float pad = BOX_PAD * (1.0f + m);
    for (int a = 0; a < 3; a++) {
        lo[a] -= pad;
        hi[a] += pad;
    }
}

static void cb_bounds(const struct RTCBoundsFunctionArguments *args) {
    float lo[3], hi[3];
    accel_padded_box(args->geometryUserPtr, args->primID, lo, hi);
    struct RTCBounds *b = args->bounds_o;
    b->lower_x = lo[0], b->lower_y = lo[1], b->lower_z = lo[2];
    b->upper_x = hi[0], b->upper_y = hi[1], b->upper_z = hi[2];
}

static void cb_intersect(const struct RTCIntersectFunctionNArguments *args) {
    if (!args->valid[0]) return;
    query *q = (query *)args->context;
    float t, b1, b2;
    uint32_t id = args->primID;
    if (!prim_test(q->s, &q->r, id, q->tmax, &t, &b1, &b2)) return;
    if (q->found && !hit_before(t, id, &q->best)) return;
    q->found = 1;
    q->best = (hit){t, id, b1, b2, NULL, 0};
    struct RTCRayHit *rh = (struct RTCRayHit *)args->rayhit; /* N == 1: rtcIntersect1 */
    rh->ray.tfar = accel_cull_distance(t);
    rh->hit.geomID = args->geomID;
    rh->hit.primID = id;
}

static void cb_occluded(const struct RTCOccludedFunctionNArguments *args) {
    if (!args->valid[0]) return;
    query *q = (query *)args->context;
    float t, b1, b2;
    if (!prim_test(q->s, &q->r, args->primID, q->tmax, &t, &b1, &b2)) return;
    q->found = 1;
    ((struct RTCRay *)args->ray)->tfar = -INFINITY; /* Embree's "occluded, stop" */
}

static void cb_error(void *user, enum RTCError code, const char *str) {
    accel_embree_device *d = user;
    if (!d->error[0]) snprintf(d->error, sizeof d->error, "Embree error %d: %s", (int)code, str ? str : "?");
}

static bool cb_memory(void *user, ssize_t bytes, bool post) {
    accel_embree_device *d = user;
    (void)post;
    long long now = atomic_fetch_add(&d->bytes, (long long)bytes) + (long long)bytes;
    long long peak = atomic_load(&d->peak);
    while (now > peak && !atomic_compare_exchange_weak(&d->peak, &peak, now)) {
    }
    return true;
}

int accel_embree_device_open(accel_embree_device *d, char *err, size_t err_len) {
    const char *cfg = getenv("TESSERA_EMBREE_CONFIG");
    snprintf(d->config, sizeof d->config, "%s", cfg ? cfg : "");
    d->error[0] = 0;
    atomic_store(&d->bytes, 0);
    atomic_store(&d->peak, 0);
    d->device = rtcNewDevice(d->config);
    if (!d->device) {
        snprintf(err, err_len, "Embree refused device configuration \"%s\" (error %d)", d->config,
                 (int)rtcGetDeviceError(NULL));
        return -1;
    }
    rtcSetDeviceErrorFunction(d->device, cb_error, d);
    rtcSetDeviceMemoryMonitorFunction(d->device, cb_memory, d);
    return 0;
}

void accel_embree_device_close(accel_embree_device *d) {
    if (d->device) rtcReleaseDevice(d->device);
    d->device = NULL;
}

/* Embree's Morton-code build (LOW) unless TESSERA_EMBREE_QUALITY says
 * "medium" or "high" (binned SAH, with spatial splits for high). Measured on
 * 655k triangles (bench/meshes.sh): LOW builds in less time and a third of
 * the memory, and renders as fast within the noise; the bytes are the same
 * with any of them. */
static enum RTCBuildQuality build_quality(void) {
    const char *q = getenv("TESSERA_EMBREE_QUALITY");
    if (q && strcmp(q, "medium") == 0) return RTC_BUILD_QUALITY_MEDIUM;
    if (q && strcmp(q, "high") == 0) return RTC_BUILD_QUALITY_HIGH;
    return RTC_BUILD_QUALITY_LOW;
}

accel_embree *accel_embree_build(const scene *s, char *err, size_t err_len) {
    struct timespec t0 = elapsed_mark();
    accel_embree *e = calloc(1, sizeof *e);
    if (!e) return snprintf(err, err_len, "out of memory"), NULL;
    e->s = s;
    if (accel_embree_device_open(&e->dev, err, err_len) != 0) {
        free(e);
        return NULL;
    }
    e->stats.config = e->dev.config;
    e->scene = rtcNewScene(e->dev.device);
    rtcSetSceneBuildQuality(e->scene, build_quality());
    RTCGeometry g = rtcNewGeometry(e->dev.device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(g, s->triangle_count + s->sphere_count);
    rtcSetGeometryUserData(g, (void *)s);
    rtcSetGeometryBoundsFunction(g, cb_bounds, (void *)s);
    rtcSetGeometryIntersectFunction(g, cb_intersect);
    rtcSetGeometryOccludedFunction(g, cb_occluded);
    rtcCommitGeometry(g);
    rtcAttachGeometry(e->scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(e->scene);
    if (e->dev.error[0]) {
        snprintf(err, err_len, "%s", e->dev.error);
        accel_embree_free(e);
        return NULL;
    }
    e->stats.build_seconds = elapsed_seconds(&t0);
    e->stats.memory_bytes = (size_t)atomic_load(&e->dev.peak);
    e->stats.final_bytes = (size_t)atomic_load(&e->dev.bytes);
    return e;
}

void accel_embree_free(accel_embree *e) {
    if (!e) return;
    if (e->scene) rtcReleaseScene(e->scene);
    accel_embree_device_close(&e->dev);
    free(e);
}

void accel_embree_get_stats(const accel_embree *e, accel_embree_stats *out) { *out = e->stats; }

/* Start a query for ray r and the Embree ray that goes with it. */
static void query_start(query *q, const scene *s, const ray *r, float tmax, struct RTCRay *er) {
    rtcInitIntersectContext(&q->ctx);
    q->s = s;
    ray_prepare(r, &q->r);
    q->tmax = tmax;
    q->found = 0;
    q->best = (hit){tmax, PRIM_NONE, 0, 0, NULL, 0};
    er->org_x = r->o.x, er->org_y = r->o.y, er->org_z = r->o.z;
    er->dir_x = r->d.x, er->dir_y = r->d.y, er->dir_z = r->d.z;
    er->tnear = 0.0f;
    er->tfar = accel_cull_distance(tmax);
    er->time = 0.0f;
    er->mask = UINT32_MAX;
    er->id = 0;
    er->flags = 0;
}

int accel_embree_intersect(const accel_embree *e, const scene *s, const ray *r, float tmax, hit *h) {
    query q;
    struct RTCRayHit rh;
    query_start(&q, s, r, tmax, &rh.ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(e->scene, &q.ctx, &rh);
    *h = q.best;
    return q.found;
}

int accel_embree_occluded(const accel_embree *e, const scene *s, const ray *r, float tmax) {
    query q;
    struct RTCRay er;
    query_start(&q, s, r, tmax, &er);
    rtcOccluded1(e->scene, &q.ctx, &er);
    return q.found;
}
