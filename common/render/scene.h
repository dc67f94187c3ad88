/* scene.h - the in-memory scene every renderer module reads: camera,
 * materials, triangles, spheres, lights, render settings.
 *
 * A scene is built once by scene_load() (scene_load.c) and is immutable and
 * shared by all render threads afterwards. Geometry is stored in internal
 * units: world coordinates are translated to the centre of the geometry's
 * bounds and divided by a power of two so that the scene spans about [-1, 1].
 * That makes a box modelled in millimetres, in kilometres or 1e5 units from
 * the origin the same problem for single-precision floats. Radiance is
 * invariant under that change; point-light intensities are rescaled. */
#ifndef TESSERA_SCENE_H
#define TESSERA_SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "scene_bundle.h"
#include "vec.h"

typedef enum {
    MATERIAL_NONE,    /* reflects nothing (a bare emitter) */
    MATERIAL_DIFFUSE, /* Lambert */
    MATERIAL_GLOSSY,  /* normalised Phong: diffuse + specular lobe */
    MATERIAL_MIRROR,  /* ideal specular reflection */
    MATERIAL_GLASS,   /* smooth dielectric */
    MATERIAL_PBR      /* glTF metallic-roughness (render/bsdf_pbr.h) */
} material_kind;

typedef struct {
    material_kind kind;
    vec3 kd;          /* diffuse albedo (diffuse, glossy) */
    vec3 ks;          /* specular colour (glossy), reflectance (mirror) */
    vec3 kt;          /* transmission colour (glass) */
    float exponent;   /* Phong exponent (glossy) */
    float ior;        /* index of refraction inside / outside (glass) */
    float p_specular; /* glossy: probability of sampling the specular lobe */
    /* MATERIAL_PBR (glTF metallic-roughness, render/bsdf_pbr.h). At a hit
     * the textures are looked up and folded into a copy of the material. */
    vec3 base_color;       /* linear base colour factor */
    float metallic, roughness; /* factors in [0, 1] */
    float alpha_cutoff;    /* alphaMode MASK: cut out where alpha < cutoff; 0 = opaque */
    float base_alpha;      /* base colour factor's alpha */
    float normal_scale;    /* normalTexture.scale */
    /* Textures, as index + 1 into scene.textures (0 = none, so that a zeroed
     * material has none). tex_base also tints kd of diffuse and glossy. */
    uint32_t tex_base, tex_mr, tex_normal;
    int has_uv_xform;      /* KHR_texture_transform of the base colour texture: */
    float uv_xform[6];     /* uv' = (M0 u + M1 v + M2, M3 u + M4 v + M5) */
} material;

typedef enum { CAMERA_PERSPECTIVE, CAMERA_ENVIRONMENT } camera_kind;

typedef struct {
    camera_kind kind;
    vec3 position;          /* internal units */
    vec3 forward, right, up; /* orthonormal; right = forward x up */
    float tan_half_fov;     /* perspective: tan(vertical fov / 2) */
} camera;

/* Which ray intersector a scene uses (accel.h). */
typedef enum { ACCEL_AUTO, ACCEL_BVH, ACCEL_FLAT, ACCEL_EMBREE, ACCEL_WIDE } accel_kind;

/* render.roulette_depth when a scene does not say: roulette from the fifth
 * vertex on (docs/performance.md, issue 15: 10% less variance per sample
 * than from the fourth for 9% more rays). 1 is Cycles' rule (its Min Light
 * Bounces at their default, 0); docs/meshes.md says what each costs. */
#define SCENE_ROULETTE_DEPTH_DEFAULT 4

typedef struct {
    int width, height;
    int spp;       /* samples per pixel */
    int max_depth; /* maximum number of path segments after the camera ray */
    /* The first vertex (0 = the camera ray's hit) after whose bounce Russian
     * roulette may end a path (render.roulette_depth; integrator.c). */
    int roulette_depth;
    uint64_t seed;
    accel_kind accel; /* render.accel: "auto" (default), "bvh", "flat", "embree" or "wide" */
} render_settings;

/* Asked between the steps of a load and during an acceleration build,
 * from the loading thread (and the build's): non-zero makes the load give
 * up with "cancelled" (a worker told to leave). Must be cheap and
 * thread-safe. */
typedef int (*scene_cancel_cb)(void *ctx);

/* Command-line overrides; a negative value (or has_seed == 0) means "keep
 * what the scene file says". */
typedef struct {
    int width, height, spp, max_depth;
    int has_seed;
    uint64_t seed;
    int has_roulette_depth; /* 1: roulette_depth replaces render.roulette_depth */
    int roulette_depth;
    int no_accel; /* 1: leave scene.accel NULL (a coordinator that only hands the scene out, or a
                   * caller that frees the bundle first, then calls scene_build_accel) */
    int keep_spare; /* with no_accel: scene_build_accel follows, so keep scene.spare for it (a
                     * load that builds its intersector itself keeps it anyway) */
    scene_cancel_cb cancelled; /* NULL: never; kept in the scene for scene_build_accel */
    void *cancel_ctx;
} scene_overrides;

typedef struct {
    vec3 v0, v1, v2;
} triangle;

/* The bound on any coordinate of a scene (its JSON numbers, the vertices
 * of its meshes' faces): past it a renderer's float arithmetic overflows
 * and the geometry would render black. */
#define SCENE_COORD_MAX 1e30

#define SCENE_NONE UINT32_MAX /* no per-corner attribute (scene.triangle_uvs, the loader's normal indices) */

typedef struct {
    vec3 center;
    float radius;
} sphere;

/* Per-primitive shading data, indexed like the primitive itself. */
typedef struct {
    uint32_t material;
    int32_t light; /* index into scene.lights, or -1 */
} prim_info;

/* A run of consecutive triangles with one material whose lights are none
 * or one each, consecutive (an emissive mesh): scene.info_runs holds a
 * scene's prim_info in a few of them when it can, so that shading a hit
 * need not read triangle_info from memory (scene_triangle_info). */
typedef struct {
    uint32_t start;     /* the run's first triangle */
    uint32_t material;
    int32_t light;      /* the first triangle's light, or -1 for none */
    int32_t light_step; /* 1: triangle start + k has light + k; 0: all have `light` */
} prim_info_run;

/* Runs kept at most: their table (1 KiB) stays in L1. A scene with more
 * keeps none, and lookups read triangle_info. */
#define SCENE_INFO_RUNS_MAX 64

typedef enum {
    LIGHT_TRIANGLE, LIGHT_SPHERE, LIGHT_POINT,
    LIGHT_SPOT,       /* KHR_lights_punctual spot: a point light with a cone (render/punctual.h) */
    LIGHT_DIRECTIONAL /* KHR_lights_punctual directional: irradiance from `direction` */
} light_kind;

typedef struct {
    light_kind kind;
    uint32_t prim;    /* triangle or sphere index (area lights) */
    int two_sided;    /* area lights: emits from both faces */
    vec3 radiance;    /* area lights: emitted radiance */
    vec3 intensity;   /* point lights: radiant intensity, internal units */
    vec3 position;    /* point lights */
    float area;       /* area lights, internal units */
    float select_pdf; /* probability that light sampling picks this light */
    vec3 direction;   /* spot, directional: unit direction the light travels */
    float cos_inner, cos_outer; /* spot: full intensity inside, none outside */
} light;

struct accel;

/* What a scene uses, recorded at load so that renderers run only those code
 * paths (bits of scene.features). */
enum {
    FEATURE_DIFFUSE = 1u << MATERIAL_DIFFUSE, /* a primitive has this material kind */
    FEATURE_GLOSSY = 1u << MATERIAL_GLOSSY,
    FEATURE_MIRROR = 1u << MATERIAL_MIRROR,
    FEATURE_GLASS = 1u << MATERIAL_GLASS,
    FEATURE_TRIANGLES = 1u << 8,
    FEATURE_SPHERES = 1u << 9,
    FEATURE_AREA_LIGHTS = 1u << 10,  /* emitting triangles or spheres */
    FEATURE_POINT_LIGHTS = 1u << 11, /* delta lights */
    FEATURE_BACKGROUND = 1u << 12,   /* escaping rays carry radiance */
    FEATURE_PBR = 1u << MATERIAL_PBR,
    FEATURE_CUTOUT = 1u << 13        /* a material has alphaMode MASK: shadow rays pass cutouts */
};

typedef struct scene {
    char *path; /* as given to scene_load */
    render_settings settings;
    camera cam;
    vec3 background; /* radiance of rays that escape */

    material *materials;
    uint32_t material_count;

    triangle *triangles;
    vec3 *triangle_normals; /* unit geometric normals, (v1 - v0) x (v2 - v0) */
    prim_info *triangle_info;
    prim_info_run *info_runs; /* triangle_info in runs (build_info_runs, scene_load.c), or NULL */
    uint32_t info_run_count;  /* 0: none, look up triangle_info */
    uint32_t triangle_count;
    int triangles_on_huge_pages; /* the three arrays above asked for them (scene_render_is_long) */

    sphere *spheres;
    prim_info *sphere_info;
    uint32_t sphere_count;

    light *lights;
    float *light_cdf; /* light_count + 1 entries, last is 1 */
    uint32_t light_count;

    /* Per-corner shading attributes of meshes (OBJ vn and vt), NULL when no
     * triangle has any. The corner normals are the scene's one
     * representation of shading normals: `mesh` shapes' vn (or normals made
     * from faces) and imported models' (glTF NORMAL, OBJ through the
     * importer) alike, all shaded by shading_normal.h's rules: triangle
     * corner_normals_first + k (k < corner_normal_tris) has its three at
     * corner_normals[3k .. 3k + 2], zero vectors for a triangle without;
     * triangles outside that range have none. Unit length (world and
     * internal frames differ only by a uniform scale). Each triangle's own
     * copy, so that a hit's normals are one load after the walk, not an
     * index's and then the normals' (docs/meshes.md, twenty-ninth session). */
    vec3 *corner_normals;
    uint32_t corner_normals_first, corner_normal_tris;
    float *uvs;                        /* 2 per texture coordinate: u, v */
    uint32_t uv_count;
    uint32_t *triangle_uvs;            /* 3 per triangle into uvs, SCENE_NONE for a triangle without */

    struct accel *accel; /* the ray intersector chosen for this scene */
    uint32_t features;   /* FEATURE_* bits */

    /* World = internal * world_scale + world_center. */
    double world_center[3];
    double world_scale;

    size_t degenerate_triangles; /* skipped at load, reported with -v */
    /* The automatic camera of an imported model without one: framed for
     * the image's aspect ratio (the only part of a load that depends on
     * the image size) from these bounds, in the model's units;
     * scene_frame_camera frames it again for another size. framed == 0
     * for any other camera. */
    struct {
        int framed;
        double lo[3], hi[3];
    } auto_camera;

    /* Imported models (render/import.h): per-corner texture coordinates,
     * NULL unless an imported triangle has normals or uvs; triangle t's
     * corners are entries 3t, 3t+1, 3t+2. (Their normals are in
     * corner_normals above.) */
    float *corner_uvs;    /* 2 per corner, glTF convention (v down the image) */
    struct texture *textures; /* render/texture.h */
    uint32_t texture_count;

    /* The load's scene_overrides.cancelled and its context, asked by
     * scene_build_accel's build too; NULL for none. */
    scene_cancel_cb cancelled;
    void *cancel_ctx;

    /* The loader's big freed buffers, kept for the wide tree's arena of a
     * short render (render/bump_arena.h: memory already faulted in costs
     * this VM a fraction of fresh memory); taken by the build, the rest
     * freed by scene_build_accel, scene_release_spare or scene_free. NULL
     * for none. keeps_spare: the load decided to keep them (and the
     * bundle's text, scene_bundle_free_keeping). */
    struct bump_spare *spare;
    int keeps_spare;
} scene;

/* Load and validate a scene file. On success returns the scene (free it with
 * scene_free). On any error returns NULL and writes one line to err naming
 * the file and, where it applies, the line and column or the JSON field,
 * e.g. "scenes/x.json: shapes[3].material: unknown material \"whte\"".
 * `overrides` may be NULL. */
scene *scene_load(const char *path, const scene_overrides *overrides, char *err, size_t err_len);

/* Load and validate the scene held in a bundle (scene_bundle.h): its first
 * entry is the scene text, the rest its meshes. Same contract as
 * scene_load; messages name the bundle's first entry as the file. */
scene *scene_load_bundle(const scene_bundle *b, const scene_overrides *overrides, char *err, size_t err_len);

/* Build the intersector (settings.accel) of a scene loaded with no_accel,
 * once the caller has freed what the build does not need (the bundle's
 * mesh text: the build is the load's peak). Returns 0, or -1 with err
 * "FILE: shapes: building the intersector: WHY" (s->accel stays NULL). */
int scene_build_accel(scene *s, char *err, size_t err_len);

/* Free s->spare (the loader's buffers kept for the build) now: for a
 * caller that loaded with keep_spare and then builds no intersector. */
void scene_release_spare(scene *s);

/* Free bundle b (loaded into s), its big files' text going to s->spare
 * when s keeps it (keeps_spare), as the loader's own buffers did. */
void scene_bundle_free_keeping(scene_bundle *b, scene *s);

/* Frame s's automatic camera (s->auto_camera.framed) for the aspect ratio
 * of s->settings.width and height, as the load does: a worker renders a
 * job of another size from a shared scene through a copy so framed. Does
 * nothing for any other camera; can't fail. */
void scene_frame_camera(scene *s);

/* Whether s's load or build was asked to stop (scene_overrides.cancelled);
 * 0 when no callback was given. */
static inline int scene_is_cancelled(const scene *s) { return s->cancelled && s->cancelled(s->cancel_ctx); }

/* Free a scene and everything it owns; NULL is allowed. */
void scene_free(scene *s);

/* The names of the FEATURE_* bits set in features, space-separated, into
 * buf (always NUL-terminated). Can't fail; truncates to len. */
void scene_feature_names(uint32_t features, char *buf, size_t len);

/* Whether s's render (width x height x spp of its settings) is long enough
 * for the arrays it reads at random, the wide tree and the triangle
 * records, to win back the first touch of fresh huge pages: at least
 * prims / 4 samples. Fresh huge pages cost this VM 6 times a 4 KiB page's
 * first touch, and a walk or a hit's shading finds them in the TLB:
 * docs/meshes.md, "The goal, per size" (seventeenth session). */
static inline int scene_render_is_long(const scene *s, size_t prims) {
    uint64_t samples = (uint64_t)s->settings.width * (uint64_t)s->settings.height * (uint64_t)s->settings.spp;
    return samples >= prims / 4;
}

/* Index of the first primitive id that is a sphere: ids below are triangles. */
static inline uint32_t scene_sphere_base(const scene *s) { return s->triangle_count; }

/* Triangle prim's prim_info: from the runs when the scene has them (a
 * branch-free binary search of a table in L1), else triangle_info[prim].
 * The same value either way. */
static inline prim_info scene_triangle_info(const scene *s, uint32_t prim) {
    if (!s->info_run_count) return s->triangle_info[prim];
    const prim_info_run *r = s->info_runs;
    for (uint32_t n = s->info_run_count; n > 1;) {
        uint32_t half = n / 2;
        r = r[half].start <= prim ? r + half : r;
        n -= half;
    }
    prim_info out = {r->material, r->light < 0 ? -1 : r->light + r->light_step * (int32_t)(prim - r->start)};
    return out;
}

/* A triangle's unit geometric normal, (v1 - v0) x (v2 - v0) normalized:
 * scene.triangle_normals holds it, and shading recomputes it from corners
 * the intersector has just read (the same operations, so the same bits). */
static inline vec3 triangle_geometric_normal(vec3 v0, vec3 v1, vec3 v2) {
    return vec3_normalize(vec3_cross(vec3_sub(v1, v0), vec3_sub(v2, v0)));
}

#endif
