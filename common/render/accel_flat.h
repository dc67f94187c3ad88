/* accel_flat.h - the flat intersector's kernel, written once for any vector
 * width: accel.c includes it for 4 lanes (SSE, any x86-64), 8 (AVX2) and 16
 * (AVX-512F), the widest the CPU has chosen at run time. Every lane performs
 * exactly the IEEE operations of the scalar triangle_intersect()
 * (intersect.h) in the same order, and the lanes a group finds are taken in
 * index order with the scalar acceptance test, so every width returns the
 * hit of the scalar loop over the triangles: the same bytes on any machine.
 *
 * Before including, define FLAT_LANES, FLAT(name) (the name with a width
 * suffix), FLAT_TARGET (a function attribute or nothing), FLAT_SPLAT(x),
 * FLAT_LANE_IDS and FLAT_BITS(mask) (bit k set where lane k of the mask is);
 * this file undefines them again at its end. With FLAT_LANES_ONLY defined,
 * only the lane kernel (test_loaded, test_lanes; no flat traversal) is
 * defined: the wide BVH's leaves use it (accel_wide.c). Not a public header. */

typedef float FLAT(vfloat) __attribute__((vector_size(FLAT_LANES * sizeof(float))));
typedef int32_t FLAT(vint) __attribute__((vector_size(FLAT_LANES * sizeof(int32_t))));
#define vfloat FLAT(vfloat)
#define vint FLAT(vint)

FLAT_TARGET static inline vfloat FLAT(vload)(const float *p) {
    vfloat v;
    memcpy(&v, p, sizeof v);
    return v;
}

FLAT_TARGET static inline vfloat FLAT(vsplat)(float x) { return (vfloat)FLAT_SPLAT(x); }

/* The lanes of a mask that are set, as bits (lane k: bit k). */
FLAT_TARGET static inline unsigned FLAT(vbits)(vint m) { return (unsigned)(FLAT_BITS(m)); }

/* A prepared ray's numbers splatted across the lanes once per ray rather
 * than once per group: the origin's coordinates in the order kx, ky, kz,
 * the shear, the primitive to skip and the triangle count. */
typedef struct {
    vfloat ox, oy, oz, sx, sy, sz;
    vint skip, count;
} FLAT(ray);

FLAT_TARGET static inline void FLAT(ray_splat)(const ray_prep *r, uint32_t count, FLAT(ray) *v) {
    const float o[3] = {r->o.x, r->o.y, r->o.z};
    v->ox = FLAT(vsplat)(o[r->kx]);
    v->oy = FLAT(vsplat)(o[r->ky]);
    v->oz = FLAT(vsplat)(o[r->kz]);
    v->sx = FLAT(vsplat)(r->sx);
    v->sy = FLAT(vsplat)(r->sy);
    v->sz = FLAT(vsplat)(r->sz);
    v->skip = (vint)FLAT(vsplat)(0.0f) + (int32_t)r->skip;
    v->count = (vint)FLAT(vsplat)(0.0f) + (int32_t)count;
}

/* Lane results of the watertight test for one group of triangles, after the
 * sign flip that makes det positive. */
typedef struct {
    vfloat T, det, V, W;
    vint ok;   /* inside, 0 < T < tmax * det (tmax at the group's start); may
                * be set on edge lanes too, which take_lane decides first */
    vint edge; /* some edge function was exactly 0: the scalar test decides */
} FLAT(group);

/* The vector half of triangle_intersect() (intersect.h), term for term, for
 * FLAT_LANES triangles whose vertices A, B, C are loaded already, each axis
 * in the ray's order kx, ky, kz; lanes outside `real` are never candidates
 * (nor are lanes whose vertices are NaN: no test of theirs holds). */
FLAT_TARGET static inline void FLAT(test_loaded)(vfloat Akx, vfloat Aky, vfloat Akz, vfloat Bkx, vfloat Bky,
                                                   vfloat Bkz, vfloat Ckx, vfloat Cky, vfloat Ckz, const FLAT(ray) *v,
                                                   vint real, float tmax, FLAT(group) *g) {
    vfloat sx = v->sx, sy = v->sy, sz = v->sz;
    vfloat Az = Akz - v->oz;
    vfloat Bz = Bkz - v->oz;
    vfloat Cz = Ckz - v->oz;
    vfloat Ax = (Akx - v->ox) - sx * Az;
    vfloat Ay = (Aky - v->oy) - sy * Az;
    vfloat Bx = (Bkx - v->ox) - sx * Bz;
    vfloat By = (Bky - v->oy) - sy * Bz;
    vfloat Cx = (Ckx - v->ox) - sx * Cz;
    vfloat Cy = (Cky - v->oy) - sy * Cz;
    vfloat U = Cx * By - Cy * Bx, V = Ax * Cy - Ay * Cx, W = Bx * Ay - By * Ax;
    vfloat zero = FLAT(vsplat)(0.0f);
    g->edge = real & ((U == zero) | (V == zero) | (W == zero));
    /* Outside unless U, V, W share a sign. With no zero among them (zeros
     * are edge lanes, decided by the scalar test), a float's sign bit is
     * its sign, so: do the sign bits differ? */
    vint outside = (((vint)U ^ (vint)V) | ((vint)U ^ (vint)W)) >> 31;
    vfloat det = U + V + W;
    vfloat T = U * sz * Az + V * sz * Bz + W * sz * Cz;
    /* Negate T, det, V, W where det < 0: flipping the sign bit is exact. */
    vint flip = (det < zero) & (int32_t)0x80000000u;
    g->T = (vfloat)((vint)T ^ flip);
    g->det = (vfloat)((vint)det ^ flip);
    g->V = (vfloat)((vint)V ^ flip);
    g->W = (vfloat)((vint)W ^ flip);
    /* No det != 0 test: where U, V, W are nonzero with one sign, their sum
     * is nonzero; where one is zero the lane is an edge lane. */
    g->ok = real & ~outside & (g->T > zero) & (g->T < FLAT(vsplat)(tmax) * g->det);
}

/* test_loaded for the FLAT_LANES triangles whose vertex k's axis a is at
 * p[k][a][lane]. */
FLAT_TARGET static inline void FLAT(test_lanes)(const float *const p[3][3], const ray_prep *r, const FLAT(ray) *v,
                                                  vint real, float tmax, FLAT(group) *g) {
    const int kx = r->kx, ky = r->ky, kz = r->kz;
    FLAT(test_loaded)(FLAT(vload)(p[0][kx]), FLAT(vload)(p[0][ky]), FLAT(vload)(p[0][kz]), FLAT(vload)(p[1][kx]),
                      FLAT(vload)(p[1][ky]), FLAT(vload)(p[1][kz]), FLAT(vload)(p[2][kx]), FLAT(vload)(p[2][ky]),
                      FLAT(vload)(p[2][kz]), v, real, tmax, g);
}

#ifndef FLAT_LANES_ONLY
/* test_lanes for the flat arrays' triangles [base, base + FLAT_LANES). */
FLAT_TARGET static inline void FLAT(test_group)(const flat_triangles *f, const ray_prep *r, const FLAT(ray) *v,
                                                  uint32_t base, float tmax, FLAT(group) *g) {
    const float *const p[3][3] = {{f->v[0][0] + base, f->v[0][1] + base, f->v[0][2] + base},
                                  {f->v[1][0] + base, f->v[1][1] + base, f->v[1][2] + base},
                                  {f->v[2][0] + base, f->v[2][1] + base, f->v[2][2] + base}};
    vint lane_ids = (vint)FLAT_LANE_IDS + (int32_t)base;
    vint real = (lane_ids < v->count) & (lane_ids != v->skip);
    FLAT(test_lanes)(p, r, v, real, tmax, g);
}

/* The scalar tail for lane k of a group, with the current closest distance
 * h->t: the same acceptance test and arithmetic as triangle_intersect(). */
FLAT_TARGET static inline int FLAT(take_lane)(const FLAT(group) *g, const scene *s, const ray_prep *r, uint32_t id, int k,
                                 hit *h) {
    float t, b1, b2;
    if (g->edge[k]) {
        if (!triangle_intersect(r, &s->triangles[id], h->t, &t, &b1, &b2)) return 0;
    } else {
        if (!g->ok[k] || g->T[k] >= h->t * g->det[k]) return 0;
        float inv = 1.0f / g->det[k];
        t = g->T[k] * inv;
        b1 = g->V[k] * inv;
        b2 = g->W[k] * inv;
    }
    h->t = t;
    h->prim = id;
    h->b1 = b1;
    h->b2 = b2;
    return 1;
}

/* Every triangle, then every sphere; with any_hit, stop at the first hit. */
FLAT_TARGET static int FLAT(traverse)(const flat_triangles *f, const scene *s, const ray *ray_in, float tmax, hit *h,
                                      int any_hit) {
    ray_prep r; /* inv_d unset: no slab test here */
    ray_prepare_shear(ray_in, &r);
    FLAT(ray) v;
    FLAT(ray_splat)(&r, f->count, &v);
    h->t = tmax;
    int found = 0;
    /* Groups up to the last triangle: the arrays are padded to the widest
     * kernel's lanes, so a narrow kernel need not walk the whole padding. */
    for (uint32_t base = 0; base < f->count; base += FLAT_LANES) {
        FLAT(group) g;
        FLAT(test_group)(f, &r, &v, base, h->t, &g);
        /* The candidate lanes in index order, lowest bit first. */
        for (unsigned bits = FLAT(vbits)(g.ok | g.edge); bits; bits &= bits - 1) {
            int k = __builtin_ctz(bits);
            if (FLAT(take_lane)(&g, s, &r, base + (uint32_t)k, k, h)) {
                found = 1;
                if (any_hit) return 1;
            }
        }
    }
    for (uint32_t i = 0; i < s->sphere_count; i++) {
        uint32_t id = scene_sphere_base(s) + i;
        float t;
        if (!sphere_intersect(&r, &s->spheres[i], id == r.skip, h->t, &t)) continue;
        h->t = t;
        h->prim = id;
        h->b1 = h->b2 = 0.0f;
        found = 1;
        if (any_hit) return 1;
    }
    return found;
}
#endif /* FLAT_LANES_ONLY */

#undef vfloat
#undef vint
#undef FLAT_LANES
#undef FLAT
#undef FLAT_TARGET
#undef FLAT_SPLAT
#undef FLAT_LANE_IDS
#undef FLAT_BITS
