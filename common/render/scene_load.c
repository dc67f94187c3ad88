/* scene_load.c - read a JSON scene file into a validated `scene`.
 *
 * Parsing happens in double precision into temporary lists (vertices in
 * world coordinates, triangles as three vertex indices, spheres, emitters);
 * once the bounds of all geometry are known the whole scene is moved into
 * internal units (see scene.h) and only then rounded to float (a vertex
 * gives the same float at each corner that uses it). A mesh's triangles
 * share its vertices, so a mesh costs 24 bytes per vertex and 24 per
 * triangle while loading. The mesh files are parsed before the shapes are
 * read, to allocate those lists once; the loops over a big mesh's vertices
 * and triangles run in ranges on every core (par.h), with the same result.
 * Every refusal names the file and the field; docs/scene-format.md
 * describes the format. */
#include <malloc.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "accel.h"
#include "bump_arena.h"
#include "import.h"
#include "json_field.h"
#include "memhint.h"
#include "mesh_normals.h"
#include "name_index.h"
#include "obj.h"
#include "par.h"
#include "scene_bundle.h"
#include "scene.h"
#include "limit.h"
#include "texture.h"

#define MAX_RESOLUTION LIMIT_SIDE
#define MAX_SPP LIMIT_SPP
#define MAX_DEPTH LIMIT_DEPTH
#define BIG SCENE_COORD_MAX /* bound for coordinates: anything larger is surely a mistake */
#define MESH_SCALE_MAX 1e6 /* a mesh scaled by 1e30 rendered black: float intersection maths overflows */

typedef struct {
    uint32_t v[3];     /* corners: indices into loader.wv */
    uint32_t material;
    int32_t emitter;   /* index into loader.emitters, or -1 */
    int32_t shade;     /* imported models: index into loader.shade_uv, shade_flags, or -1 */
} tri_r;

typedef struct {
    double c[3], r;
    uint32_t material;
    int emitter;
} sphere_d;

typedef struct {
    vec3 radiance;
    int two_sided;
} emitter_d;

typedef struct {
    double position[3];
    vec3 intensity;
    light_kind kind;        /* point, or an imported spot / directional light */
    double direction[3];
    float cos_inner, cos_outer;
} point_d;

/* A mesh file parsed before the shapes are loaded (load_shapes), kept for
 * the first mesh shape that names it. */
typedef struct {
    const scene_bundle_file *f;
    obj_mesh m;
    int failed, taken; /* failed: m is empty and err says why */
    char err[512];
} parsed_file;

typedef struct {
    json_ctx j;
    const scene_bundle *bundle; /* the scene text and its meshes */
    const char **material_names;
    name_index material_index; /* name -> material slot, for linear checks */
    double *wv;                  /* 3 per vertex, world coordinates */
    size_t wv_count, wv_cap;     /* in vertices */
    tri_r *tris;
    size_t tri_count, tri_cap;
    double tri_lo[3], tri_hi[3]; /* bounds of the triangles kept so far */
    sphere_d *spheres;
    size_t sphere_count, sphere_cap;
    emitter_d *emitters;
    size_t emitter_count, emitter_cap;
    point_d *points;
    size_t point_count, point_cap;
    parsed_file *parsed; /* every mesh file the shapes name, parsed ahead */
    size_t parsed_count, parsed_cap;
    const scene_bundle_file *obj_file; /* the OBJ parsed last, kept for the next shape naming it */
    obj_mesh obj;
    size_t obj_vn_base, obj_vt_base; /* where its normals and uvs start in vn, vt */
    double obj_smooth;               /* the smooth_angle it was read with (-1: none) */
    vec3 *vn;                        /* all meshes' shading normals (unit; zero for an unusable one) */
    size_t vn_count, vn_cap;
    float *vt; /* 2 per uv */
    size_t vt_count, vt_cap;
    uint32_t *tri_vn, *tri_vt; /* 3 per triangle, as long as the last triangle that has any */
    size_t tri_vn_len, tri_vn_cap, tri_vt_len, tri_vt_cap;
    scene *s;
    /* Imported models (import.h): per-corner uvs of the triangles whose
     * shade index points here (their normals go to vn, tri_vn), the model's
     * camera. */
    float *shade_uv;
    uint8_t *shade_flags;
    size_t shade_count, shade_cap;
    import_camera import_cam;
    int imported, imported_lights;
    const scene_overrides *ov; /* as given to the load (NULL: none) */
} loader;

/* Buffers of at least this many bytes go to scene.spare (keep_buffer);
 * $TESSERA_ARENA_SPARE_MIN overrides it (the tests' small scenes). */
#define SPARE_MIN ((size_t)16 << 20)

static size_t spare_min(void) {
    const char *e = getenv("TESSERA_ARENA_SPARE_MIN");
    return e && *e ? (size_t)strtoull(e, NULL, 10) : SPARE_MIN;
}

/* Whether L's scene keeps the loader's big buffers for its build: the
 * build follows in this process (L->ov), the render is short
 * (scene_render_is_long: a long one's tree goes on huge pages, which its
 * walks repay; these buffers are mostly on 4 KiB pages) and
 * $TESSERA_ARENA_SPARE is not "0". 10.5M triangles at 256x256x16: 6.06-6.68
 * s against 6.73-7.35 s (docs/meshes.md, thirty-first session). */
static int keeps_spare(const loader *L) {
    const char *e = getenv("TESSERA_ARENA_SPARE");
    if (!L->s || (e && strcmp(e, "0") == 0) || (L->ov && L->ov->no_accel && !L->ov->keep_spare)) return 0;
    return !scene_render_is_long(L->s, L->tri_count + L->sphere_count);
}

/* Free one of the loader's buffers, or give it to L->s->spare when it is
 * big and L keeps them (keeps_spare). */
static void keep_buffer(loader *L, void *p) {
    if (L->s) L->s->keeps_spare = keeps_spare(L);
    size_t bytes = p && L->s && L->s->keeps_spare ? malloc_usable_size(p) : 0;
    if (bytes && bytes >= spare_min()) bump_spare_add(&L->s->spare, p, bytes);
    else free(p);
}

/* Make room for one more element; returns the slot or NULL (out of memory). */
static void *push(void **arr, size_t *count, size_t *cap, size_t size) {
    if (*count == *cap) {
        size_t n = *cap ? 2 * *cap : 64;
        void *p = realloc(*arr, n * size);
        if (!p) return NULL;
        *arr = p;
        *cap = n;
    }
    return (char *)*arr + size * (*count)++;
}

static vec3 to_vec3(const double d[3]) { return vec3_make((float)d[0], (float)d[1], (float)d[2]); }

static void dsub(const double a[3], const double b[3], double o[3]) {
    for (int i = 0; i < 3; i++) o[i] = a[i] - b[i];
}
static void dcross(const double a[3], const double b[3], double o[3]) {
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}
static double ddot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static double dlen(const double a[3]) { return sqrt(ddot(a, a)); }

/* ---- render settings ---------------------------------------------------- */

static int load_render(loader *L, const cJSON *root, const scene_overrides *ov) {
    static const char *const keys[] = {"width", "height", "spp", "max_depth", "roulette_depth", "seed", "accel", NULL};
    const cJSON *r = cJSON_GetObjectItemCaseSensitive(root, "render");
    cJSON empty = {0};
    empty.type = cJSON_Object;
    if (!r) r = &empty;
    if (jf_check_object(&L->j, r, "render", keys)) return -1;
    long long w, h, spp, depth, roulette, seed;
    const char *accel = "auto";
    if (jf_string(&L->j, r, "render", "accel", 0, &accel)) return -1;
    if (!accel) accel = "auto";
    L->s->settings.accel = ACCEL_AUTO;
    for (accel_kind k = ACCEL_AUTO; k <= ACCEL_WIDE; k++)
        if (strcmp(accel, accel_kind_name(k)) == 0) L->s->settings.accel = k;
    if (strcmp(accel, accel_kind_name(L->s->settings.accel)) != 0)
        return jf_fail(&L->j, "render", "accel", "expected \"auto\", \"bvh\", \"flat\", \"embree\" or \"wide\", got \"%s\"", accel);
    if (jf_int(&L->j, r, "render", "width", 0, 512, 1, MAX_RESOLUTION, &w) ||
        jf_int(&L->j, r, "render", "height", 0, 512, 1, MAX_RESOLUTION, &h) ||
        jf_int(&L->j, r, "render", "spp", 0, 16, 1, MAX_SPP, &spp) ||
        jf_int(&L->j, r, "render", "max_depth", 0, 64, 1, MAX_DEPTH, &depth) ||
        jf_int(&L->j, r, "render", "roulette_depth", 0, SCENE_ROULETTE_DEPTH_DEFAULT, 0, MAX_DEPTH, &roulette) ||
        jf_int(&L->j, r, "render", "seed", 0, 0, 0, (1ll << 53), &seed))
        return -1;
    render_settings *st = &L->s->settings;
    st->width = (int)w;
    st->height = (int)h;
    st->spp = (int)spp;
    st->max_depth = (int)depth;
    st->roulette_depth = (int)roulette;
    st->seed = (uint64_t)seed;
    if (ov) {
        /* One side given: the other keeps the scene's aspect ratio. */
        if (ov->width > 0 && ov->height <= 0) st->height = (int)fmax(1, floor((double)ov->width * h / w + 0.5));
        if (ov->height > 0 && ov->width <= 0) st->width = (int)fmax(1, floor((double)ov->height * w / h + 0.5));
        if (ov->width > 0) st->width = ov->width;
        if (ov->height > 0) st->height = ov->height;
        if (ov->spp > 0) st->spp = ov->spp;
        if (ov->max_depth > 0) st->max_depth = ov->max_depth;
        if (ov->has_seed) st->seed = ov->seed;
        if (ov->has_roulette_depth) st->roulette_depth = ov->roulette_depth;
    }
    if (st->width > MAX_RESOLUTION || st->height > MAX_RESOLUTION || st->spp > MAX_SPP ||
        st->max_depth > MAX_DEPTH || st->roulette_depth < 0 || st->roulette_depth > MAX_DEPTH)
        return jf_fail(&L->j, "render", NULL, "command-line override out of range");
    return 0;
}

/* ---- materials ---------------------------------------------------------- */

static int load_material(loader *L, const cJSON *m, const char *where, material *out) {
    static const char *const keys[] = {"type", "albedo", "diffuse", "specular", "exponent",
                                       "reflectance", "ior", "transmission", NULL};
    static const double zero[3] = {0, 0, 0}, one[3] = {1, 1, 1};
    json_ctx *j = &L->j;
    const char *type;
    double kd[3] = {0}, ks[3] = {0}, kt[3] = {0}, exponent = 0, ior = 1;
    if (jf_check_object(j, m, where, keys) || jf_string(j, m, where, "type", 1, &type)) return -1;
    memset(out, 0, sizeof *out);
    if (strcmp(type, "diffuse") == 0) {
        out->kind = MATERIAL_DIFFUSE;
        if (jf_vec3(j, m, where, "albedo", 1, zero, 0, 1, kd)) return -1;
    } else if (strcmp(type, "glossy") == 0) {
        out->kind = MATERIAL_GLOSSY;
        if (jf_vec3(j, m, where, "diffuse", 1, zero, 0, 1, kd) ||
            jf_vec3(j, m, where, "specular", 1, zero, 0, 1, ks) ||
            jf_number(j, m, where, "exponent", 1, 0, 0, 1e6, &exponent))
            return -1;
        for (int i = 0; i < 3; i++)
            if (kd[i] + ks[i] > 1.0)
                return jf_fail(j, where, "specular", "diffuse + specular exceeds 1 in channel %d: "
                               "the material would create energy", i);
    } else if (strcmp(type, "mirror") == 0) {
        out->kind = MATERIAL_MIRROR;
        if (jf_vec3(j, m, where, "reflectance", 0, one, 0, 1, ks)) return -1;
    } else if (strcmp(type, "glass") == 0) {
        out->kind = MATERIAL_GLASS;
        if (jf_number(j, m, where, "ior", 0, 1.5, 1.0001, 10, &ior) ||
            jf_vec3(j, m, where, "transmission", 0, one, 0, 1, kt))
            return -1;
    } else {
        return jf_fail(j, where, "type", "unknown material type \"%s\" (expected diffuse, glossy, "
                       "mirror or glass)", type);
    }
    /* Fields that belong to another type are mistakes worth reporting. */
    static const char *const used[][4] = {
        [MATERIAL_DIFFUSE] = {"albedo"}, [MATERIAL_GLOSSY] = {"diffuse", "specular", "exponent"},
        [MATERIAL_MIRROR] = {"reflectance"}, [MATERIAL_GLASS] = {"ior", "transmission"}};
    for (const cJSON *f = m->child; f; f = f->next) {
        int ok = strcmp(f->string, "type") == 0;
        for (int i = 0; i < 4 && used[out->kind][i]; i++) ok |= strcmp(f->string, used[out->kind][i]) == 0;
        if (!ok) return jf_fail(j, where, f->string, "not a field of a %s material", type);
    }
    out->kd = to_vec3(kd);
    out->ks = to_vec3(ks);
    out->kt = to_vec3(kt);
    out->exponent = (float)exponent;
    out->ior = (float)ior;
    float sd = vec3_luminance(out->kd), ss = vec3_luminance(out->ks);
    out->p_specular = (out->kind == MATERIAL_GLOSSY && sd + ss > 0) ? ss / (sd + ss) : 0;
    return 0;
}

static int load_materials(loader *L, const cJSON *root) {
    const cJSON *ms = cJSON_GetObjectItemCaseSensitive(root, "materials");
    scene *s = L->s;
    int n = ms ? cJSON_GetArraySize(ms) : 0;
    if (ms && !cJSON_IsObject(ms)) return jf_fail(&L->j, "materials", NULL, "expected an object of named materials");
    /* Slot 0 is the implicit "reflects nothing" material of bare emitters. */
    s->materials = calloc((size_t)n + 1, sizeof(material));
    L->material_names = calloc((size_t)n + 1, sizeof(char *));
    if (!s->materials || !L->material_names || name_index_init(&L->material_index, (size_t)n))
        return jf_fail(&L->j, "materials", NULL, "out of memory");
    s->materials[0].kind = MATERIAL_NONE;
    L->material_names[0] = "";
    s->material_count = 1;
    for (const cJSON *m = ms ? ms->child : NULL; m; m = m->next) {
        char where[320];
        snprintf(where, sizeof where, "materials.%s", m->string);
        if (name_index_add(&L->material_index, m->string, s->material_count) != 0)
            return jf_fail(&L->j, where, NULL, "material defined twice");
        if (load_material(L, m, where, &s->materials[s->material_count])) return -1;
        L->material_names[s->material_count++] = m->string;
    }
    return 0;
}

/* ---- shapes ------------------------------------------------------------- */

/* Resolve a shape's "material" name; absent is allowed only for emitters,
 * which then reflect nothing. */
static int shape_material(loader *L, const cJSON *sh, const char *where, int emits, uint32_t *out) {
    const char *name;
    if (jf_string(&L->j, sh, where, "material", 0, &name)) return -1;
    if (!name) {
        if (!emits) return jf_fail(&L->j, where, "material", "missing (a shape that emits nothing needs a material)");
        *out = 0;
        return 0;
    }
    int64_t i = name_index_find(&L->material_index, name);
    if (i >= 1) {
        *out = (uint32_t)i;
        return 0;
    }
    return jf_fail(&L->j, where, "material", "unknown material \"%s\"", name);
}

/* Parse "emission" and "two_sided"; *emitter becomes an index or -1. */
static int shape_emission(loader *L, const cJSON *sh, const char *where, int *emitter) {
    static const double zero[3] = {0, 0, 0};
    double e[3];
    int two_sided;
    if (jf_vec3(&L->j, sh, where, "emission", 0, zero, 0, BIG, e) ||
        jf_bool(&L->j, sh, where, "two_sided", 0, &two_sided))
        return -1;
    *emitter = -1;
    if (e[0] == 0 && e[1] == 0 && e[2] == 0) {
        if (cJSON_GetObjectItemCaseSensitive(sh, "two_sided"))
            return jf_fail(&L->j, where, "two_sided", "only meaningful with a non-zero emission");
        return 0;
    }
    emitter_d *em = push((void **)&L->emitters, &L->emitter_count, &L->emitter_cap, sizeof *em);
    if (!em) return jf_fail(&L->j, where, NULL, "out of memory");
    em->radiance = to_vec3(e);
    em->two_sided = two_sided;
    *emitter = (int)(L->emitter_count - 1);
    return 0;
}

/* Make room for n more vertices in L->wv (a mesh's exactly, a triangle's
 * by doubling); returns the first new one (the count is not advanced), or
 * NULL when out of memory or past 2^32 - 1 vertices (indices are 32 bits). */
static double *reserve_vertices(loader *L, size_t n) {
    if (L->wv_count + n > UINT32_MAX) return NULL;
    if (L->wv_count + n > L->wv_cap) {
        size_t cap = n > 3 ? L->wv_count + n : L->wv_cap ? 2 * L->wv_cap : 256;
        double *p = realloc(L->wv, 3 * cap * sizeof *p);
        if (!p) return NULL;
        L->wv = p;
        L->wv_cap = cap;
        memhint_fresh(p, 3 * cap * sizeof *p);
    }
    return L->wv + 3 * L->wv_count;
}

/* Whether the triangle a, b, c has an area worth keeping: its normal's
 * length against the product of two edges' lengths. */
static int triangle_has_area(const double *a, const double *b, const double *c) {
    double e1[3], e2[3], n[3];
    dsub(b, a, e1);
    dsub(c, a, e2);
    dcross(e1, e2, n);
    return dlen(n) > 1e-12 * dlen(e1) * dlen(e2);
}

/* Grow the bounds lo, hi by point p; the same as lo = fmin(lo, p) and
 * hi = fmax(hi, p), which keep their first argument on a tie (C99 F.9.9.2,
 * glibc), but inline. Bounds grown over parts of a list of points and
 * then grown by each other in the parts' order equal those grown over the
 * whole list: either way the first of the smallest (largest) stays. */
static void bounds_grow(double lo[3], double hi[3], const double p[3]) {
    for (int a = 0; a < 3; a++) {
        lo[a] = p[a] < lo[a] ? p[a] : lo[a];
        hi[a] = p[a] > hi[a] ? p[a] : hi[a];
    }
}

/* Grow the triangle bounds by point p. */
static void bounds_add(loader *L, const double p[3]) { bounds_grow(L->tri_lo, L->tri_hi, p); }

/* Append the triangle of vertices ia, ib, ic (in L->wv, with room made for
 * it in L->tris) and grow the bounds by its corners. */
static void keep_triangle(loader *L, uint32_t ia, uint32_t ib, uint32_t ic, uint32_t mat, int emitter) {
    tri_r *t = &L->tris[L->tri_count++];
    t->v[0] = ia;
    t->v[1] = ib;
    t->v[2] = ic;
    t->material = mat;
    t->emitter = emitter;
    t->shade = -1;
    bounds_add(L, L->wv + 3 * (size_t)ia);
    bounds_add(L, L->wv + 3 * (size_t)ib);
    bounds_add(L, L->wv + 3 * (size_t)ic);
}

/* Make room for n more triangles in L->tris (a mesh's exactly: one
 * allocation, not a doubling per mesh; one triangle by doubling). Returns
 * 0, or -1 when out of memory (then L->tris is unchanged). */
static int reserve_triangles(loader *L, size_t n) {
    if (L->tri_count + n <= L->tri_cap) return 0;
    size_t cap = n > 1 ? L->tri_count + n : L->tri_cap ? 2 * L->tri_cap : 64;
    tri_r *p = realloc(L->tris, cap * sizeof *p);
    if (!p) return -1;
    L->tris = p;
    L->tri_cap = cap;
    memhint_fresh(p, cap * sizeof *p);
    return 0;
}

/* Append a triangle given by its corners. `strict`: a degenerate triangle
 * is an error naming the shape; otherwise (meshes) it is skipped and
 * counted. */
static int add_triangle(loader *L, const double *a, const double *b, const double *c, uint32_t mat,
                        int emitter, int strict, const char *where) {
    if (!triangle_has_area(a, b, c)) {
        if (strict) return jf_fail(&L->j, where, "vertices", "degenerate triangle (zero area)");
        L->s->degenerate_triangles++;
        return 0;
    }
    double *w = reserve_vertices(L, 3);
    if (!w || reserve_triangles(L, 1)) return jf_fail(&L->j, where, NULL, "out of memory");
    memcpy(w, a, 3 * sizeof *w);
    memcpy(w + 3, b, 3 * sizeof *w);
    memcpy(w + 6, c, 3 * sizeof *w);
    uint32_t first = (uint32_t)L->wv_count;
    L->wv_count += 3;
    keep_triangle(L, first, first + 1, first + 2, mat, emitter);
    return 0;
}

/* Read "vertices": an array of exactly n points. */
static int read_vertices(loader *L, const cJSON *sh, const char *where, int n, double v[][3]) {
    const cJSON *vs = cJSON_GetObjectItemCaseSensitive(sh, "vertices");
    if (!cJSON_IsArray(vs) || cJSON_GetArraySize(vs) != n)
        return jf_fail(&L->j, where, "vertices", "expected an array of %d points [x, y, z]", n);
    int i = 0;
    for (const cJSON *p = vs->child; p; p = p->next, i++) {
        char w[320];
        snprintf(w, sizeof w, "%s.vertices[%d]", where, i);
        if (!cJSON_IsArray(p) || cJSON_GetArraySize(p) != 3)
            return jf_fail(&L->j, w, NULL, "expected a point [x, y, z]");
        int k = 0;
        for (const cJSON *c = p->child; c; c = c->next, k++) {
            if (!cJSON_IsNumber(c) || !isfinite(c->valuedouble) || fabs(c->valuedouble) > BIG)
                return jf_fail(&L->j, w, NULL, "coordinate %d is not a finite number", k);
            v[i][k] = c->valuedouble;
        }
    }
    return 0;
}

static int load_quad(loader *L, const cJSON *sh, const char *where, uint32_t mat, int em) {
    double v[4][3], e1[3], e2[3], n[3], d[3];
    if (read_vertices(L, sh, where, 4, v)) return -1;
    dsub(v[1], v[0], e1);
    dsub(v[2], v[0], e2);
    dcross(e1, e2, n);
    double nl = dlen(n), longest = 0;
    for (int i = 0; i < 4; i++) {
        dsub(v[(i + 1) % 4], v[i], d);
        longest = fmax(longest, dlen(d));
    }
    if (!(nl > 1e-12 * longest * longest)) return jf_fail(&L->j, where, "vertices", "degenerate quad (zero area)");
    dsub(v[3], v[0], d);
    if (fabs(ddot(d, n)) / nl > 0.01 * longest)
        return jf_fail(&L->j, where, "vertices", "quad is not planar (4th vertex %.3g from the plane "
                       "of the first three)", fabs(ddot(d, n)) / nl);
    for (int i = 0; i < 4; i++) { /* convex: every corner turns the same way */
        double a[3], b[3], c[3];
        dsub(v[(i + 1) % 4], v[i], a);
        dsub(v[(i + 2) % 4], v[(i + 1) % 4], b);
        dcross(a, b, c);
        if (ddot(c, n) <= 0) return jf_fail(&L->j, where, "vertices", "quad is not convex, or its corners are not in order");
    }
    return add_triangle(L, v[0], v[1], v[2], mat, em, 1, where) ||
           add_triangle(L, v[0], v[2], v[3], mat, em, 1, where);
}

static int load_sphere(loader *L, const cJSON *sh, const char *where, uint32_t mat, int em) {
    double c[3], r;
    if (jf_vec3(&L->j, sh, where, "center", 1, NULL, -BIG, BIG, c) ||
        jf_number(&L->j, sh, where, "radius", 1, 0, 0, BIG, &r))
        return -1;
    if (!(r > 0)) return jf_fail(&L->j, where, "radius", "must be greater than 0");
    sphere_d *sp = push((void **)&L->spheres, &L->sphere_count, &L->sphere_cap, sizeof *sp);
    if (!sp) return jf_fail(&L->j, where, NULL, "out of memory");
    memcpy(sp->c, c, sizeof c);
    sp->r = r;
    sp->material = mat;
    sp->emitter = em;
    return 0;
}

/* Give triangle `tri` the corner attribute indices idx in *arr (3 per
 * triangle, *len triangles so far); triangles in between get SCENE_NONE.
 * Returns 0 or -1 when out of memory. */
static int set_corners(uint32_t **arr, size_t *len, size_t *cap, size_t tri, const uint32_t idx[3]) {
    if (3 * (tri + 1) > *cap) {
        size_t n = *cap ? *cap : 768;
        while (n < 3 * (tri + 1)) n *= 2;
        uint32_t *p = realloc(*arr, n * sizeof *p);
        if (!p) return -1;
        *arr = p;
        *cap = n;
    }
    for (size_t i = 3 * *len; i < 3 * tri; i++) (*arr)[i] = SCENE_NONE;
    memcpy(*arr + 3 * tri, idx, 3 * sizeof *idx);
    *len = tri + 1;
    return 0;
}

/* Normals in[b, e) (3 floats each) made unit into out (zero when they
 * cannot be). */
typedef struct {
    const float *in;
    vec3 *out;
} unit_job;

static void unit_normals(void *ctx, size_t b, size_t e, int part) {
    const unit_job *J = ctx;
    (void)part;
    for (size_t i = b; i < e; i++) {
        const float *n = J->in + 3 * i;
        double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        J->out[i] = len > 1e-30 && isfinite(len) ? vec3_make((float)(n[0] / len), (float)(n[1] / len), (float)(n[2] / len))
                                                 : vec3_make(0, 0, 0);
    }
}

/* Append count normals (3 floats each; OBJ's or an imported model's) to the
 * loader's, made unit (zero when they cannot be). Returns 0 or -1 when out
 * of memory. */
static int append_normals(loader *L, const float *normals, size_t count) {
    if (!count) return 0;
    vec3 *p = realloc(L->vn, (L->vn_count + count) * sizeof *p);
    if (!p) return -1;
    L->vn = p;
    unit_job J = {normals, L->vn + L->vn_count};
    par_run(count, par_parts(count, 1 << 14), unit_normals, &J);
    L->vn_count += count;
    return 0;
}

/* Append the parsed OBJ's normals and uvs to the loader's. Returns 0 or -1
 * when out of memory. */
static int add_mesh_attributes(loader *L, const obj_mesh *m) {
    L->obj_vn_base = L->vn_count;
    L->obj_vt_base = L->vt_count;
    if (append_normals(L, m->normals, m->normal_count)) return -1;
    if (m->uv_count) {
        float *p = realloc(L->vt, 2 * (L->vt_count + m->uv_count) * sizeof *p);
        if (!p) return -1;
        L->vt = p;
        memcpy(L->vt + 2 * L->vt_count, m->uvs, 2 * m->uv_count * sizeof *p);
        L->vt_count += m->uv_count;
    }
    return 0;
}

/* Record mesh triangle t's normals and uvs for the triangle just added as
 * number tri. A triangle with an unusable (zero) normal keeps none. */
static int add_triangle_attributes(loader *L, const obj_mesh *m, size_t t, size_t tri) {
    if (m->normal_indices && m->normal_indices[3 * t] != OBJ_NONE) {
        uint32_t idx[3];
        int usable = 1;
        for (int k = 0; k < 3; k++) {
            idx[k] = (uint32_t)(L->obj_vn_base + m->normal_indices[3 * t + k]);
            usable &= !vec3_is_zero(L->vn[idx[k]]);
        }
        if (usable && set_corners(&L->tri_vn, &L->tri_vn_len, &L->tri_vn_cap, tri, idx)) return -1;
    }
    if (m->uv_indices && m->uv_indices[3 * t] != OBJ_NONE) {
        uint32_t idx[3];
        for (int k = 0; k < 3; k++) idx[k] = (uint32_t)(L->obj_vt_base + m->uv_indices[3 * t + k]);
        if (set_corners(&L->tri_vt, &L->tri_vt_len, &L->tri_vt_cap, tri, idx)) return -1;
    }
    return 0;
}

/* The corner normals of triangles first + [b, e) from the loader's
 * indexed ones (par_run's body): each corner the normal its index names,
 * zero for a triangle without (the indices are all SCENE_NONE or none). */
typedef struct {
    const loader *L;
    size_t first;
    vec3 *out;
} corner_normals_job;

static void fill_corner_normals(void *ctx, size_t b, size_t e, int part) {
    const corner_normals_job *J = ctx;
    (void)part;
    for (size_t k = b; k < e; k++) {
        const uint32_t *idx = J->L->tri_vn + 3 * (J->first + k);
        for (int c = 0; c < 3; c++) J->out[3 * k + c] = idx[0] == SCENE_NONE ? vec3_splat(0.0f) : J->L->vn[idx[c]];
    }
}

/* The scene's corner normals (scene.h) over the triangles from the first
 * with normals to the last (L->tri_vn_len - 1), from the loader's normals
 * and indices, which are freed. Returns 0 or -1 when out of memory. */
static int assemble_corner_normals(loader *L) {
    scene *s = L->s;
    size_t first = 0;
    while (first < L->tri_vn_len && L->tri_vn[3 * first] == SCENE_NONE) first++;
    size_t n = L->tri_vn_len - first;
    if (n) {
        vec3 *c = malloc(3 * n * sizeof *c);
        memhint_fresh(c, 3 * n * sizeof *c);
        if (!c) return -1;
        corner_normals_job J = {L, first, c};
        par_run(n, par_parts_touch(n, 1 << 14), fill_corner_normals, &J);
        s->corner_normals = c;
        s->corner_normals_first = (uint32_t)first;
        s->corner_normal_tris = (uint32_t)n;
    }
    free(L->vn);
    free(L->tri_vn);
    L->vn = NULL;
    L->tri_vn = NULL;
    return 0;
}

/* Move the per-corner attributes into the scene: the normals as corner
 * normals, the uvs indexed (SCENE_NONE past the last triangle that has
 * any). Returns 0 or -1 when out of memory. */
static int assemble_attributes(loader *L) {
    scene *s = L->s;
    static const uint32_t none[3] = {SCENE_NONE, SCENE_NONE, SCENE_NONE};
    if (L->tri_vn_len && assemble_corner_normals(L)) return -1;
    if (L->tri_vt_len) {
        if (L->tri_count > L->tri_vt_len && set_corners(&L->tri_vt, &L->tri_vt_len, &L->tri_vt_cap, L->tri_count - 1, none))
            return -1;
        s->uvs = L->vt;
        s->uv_count = (uint32_t)L->vt_count;
        s->triangle_uvs = L->tri_vt;
        L->vt = NULL;
        L->tri_vt = NULL;
    }
    return 0;
}

/* The parse of file f (named `file`): the one load_shapes made, the first
 * time it is asked for (moved to *out), else a new one. Same contract as
 * obj_parse. */
static int parse_mesh_file(loader *L, const scene_bundle_file *f, const char *file, obj_mesh *out, char *err,
                           size_t err_len) {
    for (size_t i = 0; i < L->parsed_count; i++) {
        parsed_file *p = &L->parsed[i];
        if (p->f != f || p->taken) continue;
        p->taken = 1;
        if (p->failed) return snprintf(err, err_len, "%s", p->err), -1;
        *out = p->m;
        memset(&p->m, 0, sizeof p->m);
        return 0;
    }
    return obj_parse(f->data, f->len, file, out, err, err_len);
}

/* Free the parsed mesh files (the last one a shape used, and any no shape
 * took); it can be called again. */
static void free_parsed(loader *L) {
    obj_mesh_free(&L->obj);
    L->obj_file = NULL;
    for (size_t i = 0; i < L->parsed_count; i++) obj_mesh_free(&L->parsed[i].m);
    free(L->parsed);
    L->parsed = NULL;
    L->parsed_count = L->parsed_cap = 0;
}

/* Parse every mesh file the shapes name (each once, in the order they are
 * first named; a failure is kept for its shape to report, after whatever
 * comes before it) and make room for all the vertices and triangles the
 * shapes will add, so that the pool and the records are allocated once:
 * growing them took a copy, a slow one on the huge pages they were then on
 * (0.3 s at 2.6M triangles, 3.6 s at 10.5M). Room is only a hint: when it cannot be made,
 * the shapes make theirs, and report their errors, as they go. The parsed
 * files are alive together until their shapes take them. */
static void plan_shapes(loader *L, const cJSON *shapes) {
    size_t verts = 0, tris = 0;
    for (const cJSON *sh = shapes->child; sh; sh = sh->next) {
        const cJSON *type = cJSON_GetObjectItemCaseSensitive(sh, "type"),
                    *file = cJSON_GetObjectItemCaseSensitive(sh, "file");
        if (!cJSON_IsString(type)) continue;
        if (strcmp(type->valuestring, "triangle") == 0) verts += 3, tris += 1;
        if (strcmp(type->valuestring, "quad") == 0) verts += 6, tris += 2;
        if (strcmp(type->valuestring, "mesh") != 0 || !cJSON_IsString(file)) continue;
        const scene_bundle_file *f = scene_bundle_find(L->bundle, file->valuestring);
        if (!f || !f->data) continue;
        parsed_file *p = NULL;
        for (size_t i = 0; i < L->parsed_count && !p; i++) p = L->parsed[i].f == f ? &L->parsed[i] : NULL;
        if (!p) {
            if (scene_is_cancelled(L->s)) return; /* load_shapes says so */
            if (!(p = push((void **)&L->parsed, &L->parsed_count, &L->parsed_cap, sizeof *p))) return;
            p->f = f;
            p->taken = 0;
            p->failed = obj_parse(f->data, f->len, file->valuestring, &p->m, p->err, sizeof p->err) != 0;
        }
        if (!p->failed) verts += p->m.vertex_count, tris += p->m.triangle_count;
    }
    if (verts > 3) (void)reserve_vertices(L, verts);
    if (tris > 1) (void)reserve_triangles(L, tris);
}

/* One mesh instance being added (load_mesh): the parsed mesh, where its
 * world vertices and triangle records go, and per range (par.h) what it
 * kept. */
typedef struct {
    loader *L;
    const obj_mesh *m;
    double scale, translate[3];
    double *w;         /* the mesh's vertices in L->wv */
    tri_r *out;        /* its first triangle slot in L->tris */
    uint32_t *src;     /* NULL, or per kept triangle (as out) its number in the mesh */
    uint32_t base, mat; /* base: index of w's first vertex */
    int emitter;
    size_t kept[PAR_MAX_PARTS], skipped[PAR_MAX_PARTS];
    double lo[PAR_MAX_PARTS][3], hi[PAR_MAX_PARTS][3];
    size_t first;                                /* L->tri_count before the mesh */
    size_t vn_end[PAR_MAX_PARTS], vt_end[PAR_MAX_PARTS]; /* 1 + the last triangle given normals, uvs (0: none) */
} mesh_add;

/* Vertices [b, e) of the mesh in world coordinates. */
static void mesh_add_vertices(void *ctx, size_t b, size_t e, int part) {
    mesh_add *A = ctx;
    (void)part;
    for (size_t i = 3 * b; i < 3 * e; i += 3)
        for (int a = 0; a < 3; a++) A->w[i + a] = A->m->positions[i + a] * A->scale + A->translate[a];
}

/* Triangles [b, e) of the mesh: the ones with an area are written from
 * slot b on, in order; their count, the skipped ones' and their corners'
 * bounds go to the range's slots. */
static void mesh_add_triangles(void *ctx, size_t b, size_t e, int part) {
    mesh_add *A = ctx;
    size_t kept = 0;
    double *lo = A->lo[part], *hi = A->hi[part];
    for (int a = 0; a < 3; a++) lo[a] = INFINITY, hi[a] = -INFINITY;
    for (size_t t = b; t < e; t++) {
        const uint32_t *idx = A->m->indices + 3 * t;
        const double *p[3] = {A->w + 3 * (size_t)idx[0], A->w + 3 * (size_t)idx[1], A->w + 3 * (size_t)idx[2]};
        if (!triangle_has_area(p[0], p[1], p[2])) continue;
        if (A->src) A->src[b + kept] = (uint32_t)t;
        tri_r *r = &A->out[b + kept++];
        for (int k = 0; k < 3; k++) {
            r->v[k] = A->base + idx[k];
            bounds_grow(lo, hi, p[k]);
        }
        r->material = A->mat;
        r->emitter = A->emitter;
        r->shade = -1;
    }
    A->kept[part] = kept;
    A->skipped[part] = e - b - kept;
}

/* Add the triangles of a mesh without normals or uvs, in ranges on every
 * core: the same records, bounds and count of skipped triangles as
 * keep_triangle one by one (each range's kept ones are moved down behind
 * the previous range's when triangles were skipped). */
static void add_mesh_triangles(mesh_add *A) {
    loader *L = A->L;
    int parts = par_parts_touch(A->m->triangle_count, 1 << 14);
    par_run(A->m->triangle_count, parts, mesh_add_triangles, A);
    size_t kept = 0;
    for (int k = 0; k < parts; k++) {
        size_t b, e;
        par_range(A->m->triangle_count, parts, k, &b, &e);
        if (kept != b) memmove(A->out + kept, A->out + b, A->kept[k] * sizeof *A->out);
        if (kept != b && A->src) memmove(A->src + kept, A->src + b, A->kept[k] * sizeof *A->src);
        kept += A->kept[k];
        L->s->degenerate_triangles += A->skipped[k];
        for (int a = 0; a < 3; a++) { /* as bounds_grow, by the range's bounds in order */
            L->tri_lo[a] = A->lo[k][a] < L->tri_lo[a] ? A->lo[k][a] : L->tri_lo[a];
            L->tri_hi[a] = A->hi[k][a] > L->tri_hi[a] ? A->hi[k][a] : L->tri_hi[a];
        }
    }
    L->tri_count += kept;
}

/* Kept triangles [b, e) of the mesh (numbers A->first + b on): their
 * normal and uv indices into L->tri_vn and L->tri_vt (made long enough), as
 * add_triangle_attributes gives them one by one, SCENE_NONE for a triangle
 * without; the range's last triangle that got any is noted. */
static void mesh_add_attributes(void *ctx, size_t b, size_t e, int part) {
    mesh_add *A = ctx;
    loader *L = A->L;
    const obj_mesh *m = A->m;
    A->vn_end[part] = A->vt_end[part] = 0;
    for (size_t j = b; j < e; j++) {
        size_t t = A->src[j], tri = A->first + j;
        if (m->normal_indices) {
            uint32_t idx[3] = {SCENE_NONE, SCENE_NONE, SCENE_NONE};
            int usable = m->normal_indices[3 * t] != OBJ_NONE;
            for (int k = 0; k < 3 && usable; k++) {
                idx[k] = (uint32_t)(L->obj_vn_base + m->normal_indices[3 * t + k]);
                usable &= !vec3_is_zero(L->vn[idx[k]]);
            }
            for (int k = 0; k < 3; k++) L->tri_vn[3 * tri + k] = usable ? idx[k] : SCENE_NONE;
            if (usable) A->vn_end[part] = tri + 1;
        }
        if (m->uv_indices) {
            int has = m->uv_indices[3 * t] != OBJ_NONE;
            for (int k = 0; k < 3; k++)
                L->tri_vt[3 * tri + k] = has ? (uint32_t)(L->obj_vt_base + m->uv_indices[3 * t + k]) : SCENE_NONE;
            if (has) A->vt_end[part] = tri + 1;
        }
    }
}

/* The per-corner list *arr (*len triangles long, capacity *cap entries)
 * made room for `tris` triangles. Returns 0 or -1 when out of memory. */
static int corners_room(uint32_t **arr, size_t *cap, size_t tris) {
    if (3 * tris <= *cap) return 0;
    uint32_t *p = realloc(*arr, 3 * tris * sizeof *p);
    if (!p) return -1;
    *arr = p;
    *cap = 3 * tris;
    return 0;
}

/* After mesh_add_attributes: a list that got entries is SCENE_NONE from its
 * old end to the mesh's first triangle and now ends after its last entry. */
static void corners_close(uint32_t *arr, size_t *len, size_t first, const size_t end[PAR_MAX_PARTS], int parts) {
    size_t last = 0;
    for (int k = 0; k < parts; k++) last = end[k] > last ? end[k] : last;
    if (!last) return;
    for (size_t i = 3 * *len; i < 3 * first; i++) arr[i] = SCENE_NONE;
    *len = last;
}

/* Add the mesh's triangles with their normals and uvs in ranges: the
 * triangles as add_mesh_triangles, noting where each kept one came from,
 * then their attribute indices. Returns 0 or -1 when out of memory. */
static int add_mesh_triangles_with_attributes(mesh_add *A) {
    loader *L = A->L;
    A->first = L->tri_count;
    A->src = malloc((A->m->triangle_count + 1) * sizeof *A->src);
    memhint_fresh(A->src, (A->m->triangle_count + 1) * sizeof *A->src);
    if (!A->src) return -1;
    add_mesh_triangles(A);
    size_t kept = L->tri_count - A->first;
    int rc = (A->m->normal_indices && corners_room(&L->tri_vn, &L->tri_vn_cap, L->tri_count)) ||
             (A->m->uv_indices && corners_room(&L->tri_vt, &L->tri_vt_cap, L->tri_count));
    if (rc == 0) {
        int parts = par_parts(kept, 1 << 14);
        par_run(kept, parts, mesh_add_attributes, A);
        if (A->m->normal_indices) corners_close(L->tri_vn, &L->tri_vn_len, A->first, A->vn_end, parts);
        if (A->m->uv_indices) corners_close(L->tri_vt, &L->tri_vt_len, A->first, A->vt_end, parts);
    }
    free(A->src);
    A->src = NULL;
    return rc ? -1 : 0;
}

static int add_mesh_shape(loader *L, const cJSON *sh, const char *where, uint32_t mat, int em) {
    static const double zero[3] = {0, 0, 0};
    const char *file;
    double scale, translate[3], smooth;
    if (jf_string(&L->j, sh, where, "file", 1, &file) ||
        jf_number(&L->j, sh, where, "scale", 0, 1, 0, MESH_SCALE_MAX, &scale) ||
        jf_number(&L->j, sh, where, "smooth_angle", 0, -1, 0, 180, &smooth) ||
        jf_vec3(&L->j, sh, where, "translate", 0, zero, -BIG, BIG, translate))
        return -1;
    if (!(scale > 0)) return jf_fail(&L->j, where, "scale", "must be greater than 0");
    const scene_bundle_file *f = scene_bundle_find(L->bundle, file);
    if (!f) return jf_fail(&L->j, where, "file", "%s: not in the scene bundle", file);
    if (!f->data) return jf_fail(&L->j, where, "file", "%s", f->error);
    char oerr[512];
    if (L->obj_file != f || L->obj_smooth != smooth) { /* instances of one file parse it once */
        obj_mesh_free(&L->obj);
        L->obj_file = NULL;
        if (parse_mesh_file(L, f, file, &L->obj, oerr, sizeof oerr))
            return jf_fail(&L->j, where, "file", "%s", oerr);
        L->obj_file = f;
        L->obj_smooth = smooth;
        if ((smooth >= 0 && !L->obj.normal_indices && mesh_normals_from_faces(&L->obj, smooth)) ||
            add_mesh_attributes(L, &L->obj))
            return jf_fail(&L->j, where, NULL, "out of memory");
    }
    const obj_mesh m = L->obj;
    double *w = reserve_vertices(L, m.vertex_count);
    if (!w || reserve_triangles(L, m.triangle_count))
        return jf_fail(&L->j, where, NULL, "out of memory (%zu triangles)", L->tri_count + m.triangle_count);
    mesh_add A = {.L = L, .m = &m, .scale = scale, .translate = {translate[0], translate[1], translate[2]}, .w = w,
                  .out = L->tris + L->tri_count, .base = (uint32_t)L->wv_count, .mat = mat, .emitter = em};
    par_run(m.vertex_count, par_parts_touch(m.vertex_count, 1 << 14), mesh_add_vertices, &A); /* once per vertex */
    size_t base = L->wv_count;
    L->wv_count += m.vertex_count;
    if (!m.normal_indices && !m.uv_indices) {
        add_mesh_triangles(&A);
        return 0;
    }
    if (par_parts(m.triangle_count, 1 << 14) > 1)
        return add_mesh_triangles_with_attributes(&A) ? jf_fail(&L->j, where, NULL, "out of memory") : 0;
    for (size_t t = 0; t < m.triangle_count; t++) {
        const uint32_t *idx = m.indices + 3 * t;
        if (!triangle_has_area(w + 3 * (size_t)idx[0], w + 3 * (size_t)idx[1], w + 3 * (size_t)idx[2])) {
            L->s->degenerate_triangles++;
            continue;
        }
        size_t before = L->tri_count;
        keep_triangle(L, (uint32_t)(base + idx[0]), (uint32_t)(base + idx[1]), (uint32_t)(base + idx[2]), mat, em);
        if (add_triangle_attributes(L, &m, t, before)) return jf_fail(&L->j, where, NULL, "out of memory");
    }
    return 0;
}

/* A mesh shape: its triangles added (add_mesh_shape), then refused if a
 * face reaches beyond +-BIG after the shape's scale and translate (a vertex
 * no face uses does not count). Returns 0, or -1 with the error set. */
static int load_mesh(loader *L, const cJSON *sh, const char *where, uint32_t mat, int em) {
    if (add_mesh_shape(L, sh, where, mat, em)) return -1;
    for (int a = 0; a < 3; a++) /* the shapes before passed this, so any excess is this mesh's */
        if (L->tri_lo[a] < -BIG || L->tri_hi[a] > BIG)
            return jf_fail(&L->j, where, "file", "%s: a face's vertex lies at %c = %g, beyond +-%g (after the shape's "
                           "scale and translate)", cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(sh, "file")),
                           "xyz"[a], L->tri_lo[a] < -BIG ? L->tri_lo[a] : L->tri_hi[a], BIG);
    return 0;
}

#include "scene_load_import.inc"

static int load_shape(loader *L, const cJSON *sh, const char *where) {
    static const char *const keys[] = {"type", "name", "material", "emission", "two_sided", "vertices",
                                       "center", "radius", "file", "scale", "translate", "rotate", "smooth_angle", NULL};
    const char *type, *name;
    int em = -1;
    uint32_t mat = 0;
    if (jf_check_object(&L->j, sh, where, keys) || jf_string(&L->j, sh, where, "type", 1, &type) ||
        jf_string(&L->j, sh, where, "name", 0, &name) || shape_emission(L, sh, where, &em) ||
        shape_material(L, sh, where, em >= 0 || strcmp(type, "model") == 0, &mat))
        return -1;
    if (strcmp(type, "model") != 0 && cJSON_GetObjectItemCaseSensitive(sh, "rotate"))
        return jf_fail(&L->j, where, "rotate", "only model shapes rotate");
    if (strcmp(type, "triangle") == 0) {
        double v[3][3];
        return read_vertices(L, sh, where, 3, v) || add_triangle(L, v[0], v[1], v[2], mat, em, 1, where);
    }
    if (strcmp(type, "quad") == 0) return load_quad(L, sh, where, mat, em);
    if (strcmp(type, "sphere") == 0) return load_sphere(L, sh, where, mat, em);
    if (strcmp(type, "mesh") == 0) return load_mesh(L, sh, where, mat, em);
    if (strcmp(type, "model") == 0) return load_model_shape(L, sh, where, mat, em);
    return jf_fail(&L->j, where, "type", "unknown shape type \"%s\" (expected triangle, quad, sphere, mesh "
                   "or model)", type);
}

/* Whether the caller asked the load to stop (scene_overrides.cancelled):
 * -1 with "FILE: cancelled" in the error, else 0. Asked between steps. */
static int load_cancelled(loader *L) {
    if (!scene_is_cancelled(L->s)) return 0;
    snprintf(L->j.err, L->j.err_len, "%s: cancelled", L->j.file);
    return -1;
}

static int load_shapes(loader *L, const cJSON *root) {
    const cJSON *shapes = cJSON_GetObjectItemCaseSensitive(root, "shapes");
    if (!shapes) return 0;
    if (!cJSON_IsArray(shapes)) return jf_fail(&L->j, "shapes", NULL, "expected an array of shapes");
    plan_shapes(L, shapes);
    int i = 0;
    for (const cJSON *sh = shapes->child; sh; sh = sh->next, i++) {
        char where[64];
        snprintf(where, sizeof where, "shapes[%d]", i);
        if (load_cancelled(L) || load_shape(L, sh, where)) return -1;
    }
    free_parsed(L); /* before the scene is assembled, the peak of the load */
    return 0;
}

static int load_lights(loader *L, const cJSON *root) {
    static const char *const keys[] = {"type", "position", "intensity", NULL};
    const cJSON *lights = cJSON_GetObjectItemCaseSensitive(root, "lights");
    if (!lights) return 0;
    if (!cJSON_IsArray(lights)) return jf_fail(&L->j, "lights", NULL, "expected an array of lights");
    int n = cJSON_GetArraySize(lights), i = 0;
    point_d *np = realloc(L->points, (L->point_count + (size_t)n + 1) * sizeof(point_d));
    if (!np) return jf_fail(&L->j, "lights", NULL, "out of memory");
    L->points = np;
    L->point_cap = L->point_count + (size_t)n + 1;
    for (const cJSON *l = lights->child; l; l = l->next, i++) {
        char where[64];
        const char *type;
        double I[3];
        snprintf(where, sizeof where, "lights[%d]", i);
        point_d *p = &L->points[L->point_count];
        memset(p, 0, sizeof *p);
        p->kind = LIGHT_POINT;
        if (jf_check_object(&L->j, l, where, keys) || jf_string(&L->j, l, where, "type", 1, &type)) return -1;
        if (strcmp(type, "point") != 0)
            return jf_fail(&L->j, where, "type", "unknown light type \"%s\" (expected point; area lights "
                           "are shapes with an emission)", type);
        if (jf_vec3(&L->j, l, where, "position", 1, NULL, -BIG, BIG, p->position) ||
            jf_vec3(&L->j, l, where, "intensity", 1, NULL, 0, BIG, I))
            return -1;
        p->intensity = to_vec3(I);
        L->point_count++;
    }
    return 0;
}

/* ---- camera and units --------------------------------------------------- */

/* Pick the internal frame: centre of the geometry's bounds, and a power of
 * two (exact to divide by) at least half the largest extent. */
static void choose_units(loader *L) {
    double lo[3], hi[3];
    memcpy(lo, L->tri_lo, sizeof lo); /* the triangles', grown as they were added */
    memcpy(hi, L->tri_hi, sizeof hi);
    for (size_t i = 0; i < L->sphere_count; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], L->spheres[i].c[a] - L->spheres[i].r);
            hi[a] = fmax(hi[a], L->spheres[i].c[a] + L->spheres[i].r);
        }
    scene *s = L->s;
    double half = 0;
    for (int a = 0; a < 3; a++) {
        s->world_center[a] = L->tri_count + L->sphere_count ? 0.5 * (lo[a] + hi[a]) : 0;
        if (L->tri_count + L->sphere_count) half = fmax(half, 0.5 * (hi[a] - lo[a]));
    }
    int e = 1;
    if (half > 0) frexp(half, &e);
    s->world_scale = ldexp(1.0, e);
}

static vec3 to_internal(const scene *s, const double w[3]) {
    double p[3];
    for (int a = 0; a < 3; a++) p[a] = (w[a] - s->world_center[a]) / s->world_scale;
    return to_vec3(p);
}

static int load_camera(loader *L, const cJSON *root) {
    static const char *const keys[] = {"type", "position", "look_at", "up", "fov", NULL};
    static const double yup[3] = {0, 1, 0};
    const cJSON *c = cJSON_GetObjectItemCaseSensitive(root, "camera");
    json_ctx *j = &L->j;
    const char *type;
    double pos[3], at[3], up[3], fov, f[3], r[3], u[3];
    if (!c) return jf_fail(j, "camera", NULL, "missing");
    if (jf_check_object(j, c, "camera", keys) || jf_string(j, c, "camera", "type", 1, &type) ||
        jf_vec3(j, c, "camera", "position", 1, NULL, -BIG, BIG, pos))
        return -1;
    camera *cam = &L->s->cam;
    cam->position = to_internal(L->s, pos);
    if (strcmp(type, "environment") == 0) {
        for (const char *const *k = keys + 2; *k; k++)
            if (cJSON_GetObjectItemCaseSensitive(c, *k))
                return jf_fail(j, "camera", *k, "not a field of an environment camera");
        cam->kind = CAMERA_ENVIRONMENT;
        cam->forward = vec3_make(0, 0, 1);
        cam->right = vec3_make(1, 0, 0);
        cam->up = vec3_make(0, 1, 0);
        return 0;
    }
    if (strcmp(type, "perspective") != 0)
        return jf_fail(j, "camera", "type", "unknown camera type \"%s\" (expected perspective or environment)", type);
    if (jf_vec3(j, c, "camera", "look_at", 1, NULL, -BIG, BIG, at) ||
        jf_vec3(j, c, "camera", "up", 0, yup, -BIG, BIG, up) ||
        jf_number(j, c, "camera", "fov", 1, 0, 0, 180, &fov))
        return -1;
    if (!(fov > 0.001 && fov < 179.9)) return jf_fail(j, "camera", "fov", "expected degrees between 0.001 and 179.9, got %g", fov);
    dsub(at, pos, f);
    if (!(dlen(f) > 0)) return jf_fail(j, "camera", "look_at", "equals the position: no view direction");
    if (!(dlen(up) > 0)) return jf_fail(j, "camera", "up", "zero vector cannot be normalised");
    double fl = dlen(f), ul = dlen(up);
    for (int a = 0; a < 3; a++) {
        f[a] /= fl;
        up[a] /= ul;
    }
    dcross(f, up, r);
    double rl = dlen(r);
    if (!(rl > 1e-6)) return jf_fail(j, "camera", "up", "parallel to the view direction");
    for (int a = 0; a < 3; a++) r[a] /= rl;
    dcross(r, f, u);
    cam->kind = CAMERA_PERSPECTIVE;
    cam->forward = to_vec3(f);
    cam->right = to_vec3(r);
    cam->up = to_vec3(u);
    cam->tan_half_fov = (float)tan(fov * M_PI / 360.0);
    return 0;
}

/* ---- assembling the scene ----------------------------------------------- */

static void set_prim_light(scene *s, light *l) {
    prim_info *info = l->kind == LIGHT_TRIANGLE ? &s->triangle_info[l->prim] : &s->sphere_info[l->prim];
    info->light = (int32_t)(l - s->lights);
}

/* Power of a light, the weight for picking it (its colour's mean). */
static double light_power(const light *l) {
    if (l->kind == LIGHT_POINT) return 4.0 * M_PI * (l->intensity.x + l->intensity.y + l->intensity.z) / 3.0;
    if (l->kind == LIGHT_SPOT || l->kind == LIGHT_DIRECTIONAL) return import_light_power(l);
    double sides = l->two_sided ? 2.0 : 1.0;
    return sides * M_PI * l->area * (l->radiance.x + l->radiance.y + l->radiance.z) / 3.0;
}

static int build_lights(loader *L) {
    scene *s = L->s;
    size_t n = L->point_count;
    for (size_t t = 0; t < L->tri_count; t++) n += L->tris[t].emitter >= 0;
    for (size_t i = 0; i < L->sphere_count; i++) n += L->spheres[i].emitter >= 0;
    s->lights = calloc(n + 1, sizeof(light));
    s->light_cdf = calloc(n + 2, sizeof(float));
    if (!s->lights || !s->light_cdf) return jf_fail(&L->j, "lights", NULL, "out of memory");
    for (uint32_t t = 0; t < s->triangle_count; t++) {
        if (L->tris[t].emitter < 0) continue;
        const triangle *tr = &s->triangles[t];
        light *l = &s->lights[s->light_count++];
        l->kind = LIGHT_TRIANGLE;
        l->prim = t;
        l->radiance = L->emitters[L->tris[t].emitter].radiance;
        l->two_sided = L->emitters[L->tris[t].emitter].two_sided;
        l->area = 0.5f * vec3_length(vec3_cross(vec3_sub(tr->v1, tr->v0), vec3_sub(tr->v2, tr->v0)));
        set_prim_light(s, l);
    }
    for (uint32_t i = 0; i < s->sphere_count; i++) {
        if (L->spheres[i].emitter < 0) continue;
        light *l = &s->lights[s->light_count++];
        l->kind = LIGHT_SPHERE;
        l->prim = i;
        l->radiance = L->emitters[L->spheres[i].emitter].radiance;
        l->two_sided = L->emitters[L->spheres[i].emitter].two_sided;
        l->area = 4.0f * TS_PI * s->spheres[i].radius * s->spheres[i].radius;
        set_prim_light(s, l);
    }
    double inv_s2 = 1.0 / (s->world_scale * s->world_scale);
    for (size_t i = 0; i < L->point_count; i++) {
        light *l = &s->lights[s->light_count++];
        l->kind = L->points[i].kind;
        l->position = to_internal(s, L->points[i].position);
        l->intensity = vec3_scale(L->points[i].intensity, l->kind == LIGHT_DIRECTIONAL ? 1.0f : (float)inv_s2);
        l->direction = to_vec3(L->points[i].direction);
        l->cos_inner = L->points[i].cos_inner;
        l->cos_outer = L->points[i].cos_outer;
    }
    double total = 0, run = 0;
    for (uint32_t i = 0; i < s->light_count; i++) total += light_power(&s->lights[i]);
    for (uint32_t i = 0; i < s->light_count; i++) {
        double p = total > 0 ? light_power(&s->lights[i]) / total : 1.0 / s->light_count;
        s->lights[i].select_pdf = (float)p;
        s->light_cdf[i] = (float)run;
        run += p;
    }
    s->light_cdf[s->light_count] = 1.0f;
    return 0;
}

/* Triangles [b, e) into the scene: corners in internal units (a vertex is
 * converted for each triangle that keeps it, the same float each time;
 * only kept triangles' corners are converted: they lie within the bounds,
 * while a vertex no face, or only a degenerate one, uses may lie anywhere,
 * beyond what a float holds), geometric normals, materials. */
static void assemble_triangles(void *ctx, size_t b, size_t e, int part) {
    loader *L = ctx;
    scene *s = L->s;
    (void)part;
    for (size_t t = b; t < e; t++) {
        triangle *tr = &s->triangles[t];
        tr->v0 = to_internal(s, L->wv + 3 * (size_t)L->tris[t].v[0]);
        tr->v1 = to_internal(s, L->wv + 3 * (size_t)L->tris[t].v[1]);
        tr->v2 = to_internal(s, L->wv + 3 * (size_t)L->tris[t].v[2]);
        s->triangle_normals[t] = triangle_geometric_normal(tr->v0, tr->v1, tr->v2);
        s->triangle_info[t].material = L->tris[t].material;
        s->triangle_info[t].light = -1;
    }
}

static int assemble(loader *L) {
    scene *s = L->s;
    s->triangle_count = (uint32_t)L->tri_count;
    s->sphere_count = (uint32_t)L->sphere_count;
    /* Every element is written below: malloc, not calloc, and one spare
     * (zeroed) so that no size is 0. */
    s->triangles = malloc((L->tri_count + 1) * sizeof(triangle));
    s->triangle_info = malloc((L->tri_count + 1) * sizeof(prim_info));
    s->triangle_normals = malloc((L->tri_count + 1) * sizeof(vec3));
    s->spheres = calloc(L->sphere_count + 1, sizeof(sphere));
    s->sphere_info = calloc(L->sphere_count + 1, sizeof(prim_info));
    if (!s->triangles || !s->triangle_info || !s->triangle_normals || !s->spheres || !s->sphere_info)
        return jf_fail(&L->j, "shapes", NULL, "out of memory");
    /* The records a hit's shading reads, on huge pages for a long render
     * (scene_render_is_long), or where they are cheaper to fault in
     * (memhint_fresh_huge): at 655k triangles and 128x128x64 on 4
     * KiB pages the render took 3.8% more CPU, and at 10.5M and 256x256x16
     * on huge pages 3.74-4.17 s against 3.28-3.43 s on a host where they
     * are dearer (docs/meshes.md). */
    size_t tri_bytes = (L->tri_count + 1) * sizeof(triangle);
    s->triangles_on_huge_pages = scene_render_is_long(s, L->tri_count + L->sphere_count) ||
                                 memhint_fresh_huge(s->triangles, tri_bytes);
    if (s->triangles_on_huge_pages) { /* (again, for a short render: a no-op) and the two smaller arrays */
        memhint_huge(s->triangles, tri_bytes);
        memhint_huge(s->triangle_info, (L->tri_count + 1) * sizeof(prim_info));
        memhint_huge(s->triangle_normals, (L->tri_count + 1) * sizeof(vec3));
    }
    memset(&s->triangles[L->tri_count], 0, sizeof(triangle));
    memset(&s->triangle_info[L->tri_count], 0, sizeof(prim_info));
    memset(&s->triangle_normals[L->tri_count], 0, sizeof(vec3));
    par_run(L->tri_count, par_parts_touch(L->tri_count, 1 << 14), assemble_triangles, L);
    keep_buffer(L, L->wv); /* not needed past here: the scene's peak memory is the intersector's build */
    L->wv = NULL;
    for (size_t i = 0; i < L->sphere_count; i++) {
        s->spheres[i].center = to_internal(s, L->spheres[i].c);
        s->spheres[i].radius = (float)(L->spheres[i].r / s->world_scale);
        if (!(s->spheres[i].radius > 0))
            return jf_fail(&L->j, "shapes", NULL, "a sphere is too small next to the rest of the scene");
        s->sphere_info[i].material = L->spheres[i].material;
        s->sphere_info[i].light = -1;
    }
    if (assemble_attributes(L)) return jf_fail(&L->j, "shapes", NULL, "out of memory");
    return build_lights(L);
}

/* s->info_runs for the assembled triangles: their prim_info as at most
 * SCENE_INFO_RUNS_MAX runs (prim_info_run), or none (info_run_count 0)
 * when they take more or the table cannot be allocated: lookups then read
 * triangle_info. Can't fail. */
static void build_info_runs(scene *s) {
    prim_info_run runs[SCENE_INFO_RUNS_MAX];
    uint32_t n = 0;
    for (uint32_t i = 0; i < s->triangle_count; i++) {
        prim_info in = s->triangle_info[i];
        if (n) {
            prim_info_run *r = &runs[n - 1];
            int32_t k = (int32_t)(i - r->start);
            if (in.material == r->material && r->light < 0 && in.light < 0) continue;
            if (in.material == r->material && r->light >= 0 && in.light == r->light + k) {
                r->light_step = 1; /* a run with a light grows only by the next one */
                continue;
            }
        }
        if (n == SCENE_INFO_RUNS_MAX) return;
        runs[n++] = (prim_info_run){i, in.material, in.light, 0};
    }
    if (!n || !(s->info_runs = malloc(n * sizeof *runs))) return;
    memcpy(s->info_runs, runs, n * sizeof *runs);
    s->info_run_count = n;
}

/* Set s->features from what the assembled scene contains. */
static void record_features(scene *s) {
    uint32_t f = 0;
    for (uint32_t i = 0; i < s->triangle_count; i++) f |= 1u << s->materials[s->triangle_info[i].material].kind;
    for (uint32_t i = 0; i < s->sphere_count; i++) f |= 1u << s->materials[s->sphere_info[i].material].kind;
    f &= ~(1u << MATERIAL_NONE);
    if (s->triangle_count) f |= FEATURE_TRIANGLES;
    if (s->sphere_count) f |= FEATURE_SPHERES;
    for (uint32_t i = 0; i < s->light_count; i++)
        f |= s->lights[i].kind >= LIGHT_POINT ? FEATURE_POINT_LIGHTS : FEATURE_AREA_LIGHTS;
    if (!vec3_is_zero(s->background)) f |= FEATURE_BACKGROUND;
    for (uint32_t i = 0; i < s->material_count && s->corner_uvs; i++)
        if (s->materials[i].alpha_cutoff > 0.0f) f |= FEATURE_CUTOUT;
    s->features = f;
}

void scene_feature_names(uint32_t features, char *buf, size_t len) {
    static const struct {
        uint32_t bit;
        const char *name;
    } names[] = {{FEATURE_DIFFUSE, "diffuse"},         {FEATURE_GLOSSY, "glossy"},
                 {FEATURE_MIRROR, "mirror"},           {FEATURE_GLASS, "glass"},
                 {FEATURE_TRIANGLES, "triangles"},     {FEATURE_SPHERES, "spheres"},
                 {FEATURE_AREA_LIGHTS, "area-lights"}, {FEATURE_POINT_LIGHTS, "point-lights"},
                 {FEATURE_BACKGROUND, "background"}, {FEATURE_PBR, "pbr"},
                 {FEATURE_CUTOUT, "cutout"}};
    size_t used = 0;
    if (len) buf[0] = '\0';
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        if (!(features & names[i].bit) || used >= len) continue;
        int n = snprintf(buf + used, len - used, "%s%s", used ? " " : "", names[i].name);
        if (n > 0) used += (size_t)n;
    }
}

/* Free the loader's temporaries (the scene and the JSON stay; the pool
 * and the records may go to the scene's spare, keep_buffer); it can be
 * called again. */
static void loader_free(loader *L) {
    keep_buffer(L, L->wv);
    keep_buffer(L, L->tris);
    L->wv = NULL;
    L->tris = NULL;
    void *temps[] = {(void *)L->material_names, L->wv, L->tris, L->spheres, L->emitters, L->points, L->shade_uv,
                     L->shade_flags, L->vn, L->vt, L->tri_vn, L->tri_vt};
    for (size_t i = 0; i < sizeof temps / sizeof temps[0]; i++) free(temps[i]);
    name_index_free(&L->material_index);
    free_parsed(L);
    json_ctx j = L->j;
    scene *s = L->s;
    memset(L, 0, sizeof *L);
    L->j = j;
    L->s = s;
}

static int load_root(loader *L, const cJSON *root, const scene_overrides *ov) {
    static const char *const keys[] = {"render", "camera", "background", "materials", "shapes", "lights", "import", NULL};
    static const double black[3] = {0, 0, 0};
    double bg[3];
    if (jf_check_object(&L->j, root, "", keys) || load_render(L, root, ov) || load_materials(L, root) ||
        load_shapes(L, root) || load_lights(L, root) || load_import(L, root, ov) ||
        jf_vec3(&L->j, root, "", "background", 0, black, 0, BIG, bg))
        return -1;
    L->s->background = to_vec3(bg);
    if (L->imported && !cJSON_GetObjectItemCaseSensitive(root, "background") && !L->imported_lights)
        L->s->background = vec3_splat(IMPORT_DEFAULT_SKY); /* no light in the model: a uniform sky */
    choose_units(L);
    if (L->imported && !cJSON_GetObjectItemCaseSensitive(root, "camera")) {
        if (import_camera_set(L)) return -1;
    } else if (load_camera(L, root)) {
        return -1;
    }
    if (load_cancelled(L) || assemble(L) || load_cancelled(L) || assemble_shading(L)) return -1;
    record_features(L->s);
    build_info_runs(L->s);
    return 0;
}

int scene_build_accel(scene *s, char *err, size_t err_len) {
    char why[256];
    if (scene_is_cancelled(s)) {
        snprintf(err, err_len, "%s: cancelled", s->path);
        return -1;
    }
    s->accel = accel_build_err(s, s->settings.accel, why, sizeof why);
    scene_release_spare(s); /* what the build did not take */
    if (s->accel) return 0;
    snprintf(err, err_len, "%s: shapes: building the intersector: %s", s->path, why);
    return -1;
}

void scene_release_spare(scene *s) {
    bump_spare_free(s->spare);
    s->spare = NULL;
    s->keeps_spare = 0;
}

void scene_bundle_free_keeping(scene_bundle *b, scene *s) {
    for (size_t i = 0; s && s->keeps_spare && i < b->count; i++) {
        size_t bytes = b->files[i].data ? malloc_usable_size(b->files[i].data) : 0;
        if (!bytes || bytes < spare_min()) continue;
        bump_spare_add(&s->spare, b->files[i].data, bytes);
        b->files[i].data = NULL;
    }
    scene_bundle_free(b);
}

scene *scene_load_bundle(const scene_bundle *b, const scene_overrides *ov, char *err, size_t err_len) {
    const char *path = b->files[0].name;
    loader L;
    memset(&L, 0, sizeof L);
    for (int a = 0; a < 3; a++) {
        L.tri_lo[a] = INFINITY;
        L.tri_hi[a] = -INFINITY;
    }
    L.j.file = path;
    L.j.err = err;
    L.j.err_len = err_len;
    L.bundle = b;
    L.ov = ov;
    L.s = calloc(1, sizeof(scene));
    if (L.s && ov) {
        L.s->cancelled = ov->cancelled;
        L.s->cancel_ctx = ov->cancel_ctx;
    }
    cJSON *root = L.s ? jf_parse(&L.j, b->files[0].data, b->files[0].len) : NULL;
    int rc = root ? load_root(&L, root, ov) : -1;
    if (!L.s) snprintf(err, err_len, "%s: out of memory", path);
    if (rc == 0) L.s->path = strdup(path);
    cJSON_Delete(root);
    loader_free(&L);
    if (rc != 0 || !L.s->path || (!(ov && ov->no_accel) && scene_build_accel(L.s, err, err_len))) {
        scene_free(L.s); /* (the loader's temporaries went first: the intersector's build is the load's peak) */
        return NULL;
    }
    return L.s;
}

scene *scene_load(const char *path, const scene_overrides *ov, char *err, size_t err_len) {
    scene_bundle b;
    if (scene_bundle_read(path, &b, err, err_len)) return NULL;
    scene *s = scene_load_bundle(&b, ov, err, err_len);
    scene_bundle_free(&b);
    return s;
}

void scene_free(scene *s) {
    if (!s) return;
    accel_free(s->accel);
    free(s->path);
    free(s->materials);
    free(s->triangles);
    free(s->triangle_info);
    free(s->info_runs);
    free(s->triangle_normals);
    free(s->corner_normals);
    free(s->uvs);
    free(s->triangle_uvs);
    free(s->spheres);
    free(s->sphere_info);
    free(s->lights);
    free(s->light_cdf);
    free(s->corner_uvs);
    for (uint32_t i = 0; s->textures && i < s->texture_count; i++) texture_free(&s->textures[i]);
    free(s->textures);
    bump_spare_free(s->spare);
    free(s);
}
