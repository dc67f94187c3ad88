/* scene_memory.h - will a scene fit? An estimate of the peak memory that
 * loading a scene bundle takes, and of the memory this host can give, so a
 * worker can refuse a scene with the figures (its tiles go back to the
 * coordinator's queue) instead of being killed by the kernel mid-load. */
#ifndef TESSERA_SCENE_MEMORY_H
#define TESSERA_SCENE_MEMORY_H

#include <stddef.h>
#include <stdint.h>

#include "scene_bundle.h"

/* Peak bytes per triangle while loading and building (loader copy, scene
 * arrays, Embree's build). Measured with bench/meshes.sh: 10.5M triangles
 * first peaked at 2493 MB RSS including the 217 MB of OBJ text (~217 B per
 * triangle); since the loading work of the third session they peak at
 * 1191-1226 MB (~120 B per triangle, docs/meshes.md "Memory"), so 256
 * keeps a margin of about 2. Since 2026-11-27 "auto" builds the wide BVH
 * by Morton codes at that size: 1857 MB peak at 10.5M, ~177 B per
 * triangle, a margin of 1.4. (The wide BVH's binned SAH forced there:
 * 1554 MB.) */
#define SCENE_MEMORY_BYTES_PER_TRIANGLE 256

/* The same for a triangle of a model the importer reads (glTF, or an OBJ
 * named by "import" or a "model" shape: render/import.h). Assimp keeps a
 * vertex per corner and the importer its own copies: measured (one-pixel
 * `--workers 0` runs of an icosphere written as .glb, 328k against 1.31M
 * triangles, the slope of peak RSS) 221 B per triangle with positions
 * only, 290 B with normals and texture coordinates; 448 keeps a margin of
 * about 1.5. */
#define SCENE_MEMORY_BYTES_PER_IMPORTED_TRIANGLE 448

/* Estimated peak bytes to load bundle b: its own size, plus
 * SCENE_MEMORY_BYTES_PER_TRIANGLE per triangle its meshes' OBJ faces make
 * (counted from the text, fan-triangulated, times the scene's uses of the
 * file), SCENE_MEMORY_BYTES_PER_IMPORTED_TRIANGLE per triangle of its
 * models (a glTF's primitives times the nodes naming their mesh; a model
 * OBJ's faces), and 4 bytes per texel of its PNG and JPEG textures (bundle
 * files and a binary glTF's images, from their headers). *triangles gets
 * the triangles counted. Can't fail. */
uint64_t scene_memory_estimate(const scene_bundle *b, uint64_t *triangles);

/* scene_memory_estimate for a scene already loaded from b with `loaded`
 * triangles (scene.triangle_count): its meshes' OBJ texts are not read
 * again (at 10.5M triangles a 217 MB scan), its meshes counted as `loaded`
 * less its models' triangles. Can't fail. */
uint64_t scene_memory_estimate_loaded(const scene_bundle *b, uint64_t loaded, uint64_t *triangles);

/* Bytes this process may still allocate: the smaller of the host's
 * MemAvailable and the cgroup's memory.max - memory.current where there is
 * a limit. TESSERA_MEMORY_AVAILABLE_MB overrides it (for tests). Returns
 * UINT64_MAX when nothing can be read. */
uint64_t scene_memory_available(void);

/* If loading b would not fit, write "needs about X MiB ... only Y MiB
 * available" to err and return -1; else 0. */
int scene_memory_check(const scene_bundle *b, char *err, size_t err_len);

#endif
