/* import.h - glTF 2.0 (.gltf, .glb) and OBJ + MTL models, read with Assimp,
 * into flat triangle lists with materials, textures, lights and a camera.
 *
 * Assimp (libassimp 5.2, C API) parses the geometry: accessors, primitives,
 * node hierarchy, OBJ faces and MTL files. Its 5.2 C API does not surface
 * everything a glTF renderer needs, so the glTF JSON is also read here
 * (cJSON) for: extensionsRequired (refused unless supported, naming them),
 * Draco compression (refused), materials with KHR_materials_emissive_strength,
 * _transmission, _ior and KHR_texture_transform, samplers' wrap modes, image
 * sources, cameras (yfov, aspect) and KHR_lights_punctual, whose node
 * transforms are computed from the JSON as the glTF spec defines them.
 *
 * Every file comes from a scene bundle (model_files.h names them): Assimp
 * reads through callbacks that serve bundle entries, so a worker needs no
 * filesystem. All errors are "NAME: what is wrong", NAME the model file. */
#ifndef TESSERA_IMPORT_H
#define TESSERA_IMPORT_H

#include <stddef.h>
#include <stdint.h>

#include "scene.h"
#include "scene_bundle.h"
#include "texture.h"

typedef struct {
    material mat;       /* tex_* index + 1 into import_model.textures */
    vec3 emission;      /* emitted radiance (emissive factor x strength); zero = none */
    int double_sided;   /* emits from both faces */
} import_material;

typedef struct {
    light_kind kind;       /* LIGHT_POINT, LIGHT_SPOT or LIGHT_DIRECTIONAL */
    double position[3];    /* world */
    double direction[3];   /* unit, the way the light travels */
    vec3 intensity;        /* colour x intensity (cd as W/sr; lux as W/m^2 for directional) */
    float cos_inner, cos_outer;
} import_light;

typedef struct {
    int present;
    char name[128];
    double position[3], forward[3], up[3]; /* world; unit vectors */
    double yfov;                           /* radians */
    double aspect;                         /* width / height, 0 = not given */
} import_camera;

typedef struct {
    const char *camera; /* --camera: node or camera name; NULL = the first */
    double scale;       /* applied after the model's own transforms: */
    double translate[3]; /* p -> R p * scale + translate */
    int has_rotate;     /* R: rotate (row-major), else the identity */
    double rotate[9];
} import_options;

typedef struct {
    size_t tri_count;
    double *positions;  /* 9 per triangle, world */
    float *normals;     /* 3 per distinct shading normal (unit, world): equal ones are stored once */
    size_t normal_count;
    uint32_t *normal_indices; /* 3 per triangle into normals, valid where flags & 1 */
    float *uvs;         /* 6 per triangle, glTF orientation, valid where flags & 2 */
    uint8_t *flags;
    uint32_t *material; /* per triangle, into materials */
    import_material *materials;
    uint32_t material_count;
    texture *textures;
    uint32_t texture_count;
    import_light *lights;
    size_t light_count;
    import_camera camera;
    size_t skipped_primitives; /* points and lines, skipped (warned once) */
} import_model;

/* Import the model named `name` in bundle b. Returns 0 and fills *out (free
 * with import_model_free), or -1 with "NAME: reason" in err. */
int import_model_load(const scene_bundle *b, const char *name, const import_options *opt, import_model *out,
                      char *err, size_t err_len);

/* Import from bytes already in memory (the fuzz target's entry point): the
 * model is `data` under `name`, with no other files. Same contract. */
int import_model_from_memory(const char *name, const uint8_t *data, size_t len, import_model *out, char *err,
                             size_t err_len);

/* Free what import_model_load allocated, textures included unless they
 * were moved out (set textures to NULL first). */
void import_model_free(import_model *m);

#endif
