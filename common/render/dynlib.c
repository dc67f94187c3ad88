/* dynlib.c - Embree and Assimp opened when first used, not at start-up.
 *
 * Linked the usual way, the two C++ libraries (with libstdc++, TBB, draco
 * and minizip behind them) were loaded and relocated by every tessera and
 * tessera-worker process before main: about 15 ms of CPU each, paid three
 * times by a local-farm render that uses neither (docs/performance.md, "Fixed
 * costs"). Only meshes (Embree's intersector and BVH builder) and imported
 * models (Assimp) need them, so the functions Tessera calls are defined here with
 * the libraries' own prototypes (the headers are included, so the compiler
 * checks them), and each opens its library (dlopen, by the soname the build
 * found) and looks itself up on its first call. The release programs link
 * neither library (the sanitizer builds do, and these wrappers then find
 * them loaded: see the Makefile); the callers (accel_embree.c, import.c)
 * are unchanged. */
#include <dlfcn.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>

#include <assimp/cfileio.h>
#include <assimp/cimport.h>
#include <assimp/material.h>
#include <embree3/rtcore.h>

#ifndef TESSERA_EMBREE_SONAME
#define TESSERA_EMBREE_SONAME "libembree3.so.3"
#endif
#ifndef TESSERA_ASSIMP_SONAME
#define TESSERA_ASSIMP_SONAME "libassimp.so.5"
#endif

/* One library: opened at most once, under its lock; `error` says why it
 * could not be. */
typedef struct {
    const char *soname;
    pthread_mutex_t lock;
    void *handle;
    int failed;
    char error[400];
} dynlib;

static dynlib embree = {.soname = TESSERA_EMBREE_SONAME, .lock = PTHREAD_MUTEX_INITIALIZER};
static dynlib assimp = {.soname = TESSERA_ASSIMP_SONAME, .lock = PTHREAD_MUTEX_INITIALIZER};

/* The address of `name` in lib, opening lib first if need be. Returns NULL
 * when the library cannot be opened or lacks the symbol (lib->error then
 * says which). Thread-safe. */
static void *dynlib_symbol(dynlib *lib, const char *name) {
    pthread_mutex_lock(&lib->lock);
    if (!lib->handle && !lib->failed) {
        lib->handle = dlopen(lib->soname, RTLD_NOW | RTLD_LOCAL);
        if (!lib->handle) {
            lib->failed = 1;
            snprintf(lib->error, sizeof lib->error, "cannot load %s: %s", lib->soname, dlerror());
        }
    }
    void *p = lib->handle ? dlsym(lib->handle, name) : NULL;
    if (lib->handle && !p) snprintf(lib->error, sizeof lib->error, "%s has no %s", lib->soname, name);
    pthread_mutex_unlock(&lib->lock);
    return p;
}

/* A wrapper with the library function's signature and contract: it calls
 * the real function, found on the first call and kept; when it cannot be
 * found, it returns `fail` (a void wrapper does nothing). */
#define DYNLIB_CALL(lib, ret, name, params, args, fail)                                                  \
    ret name params {                                                                                    \
        typedef ret(*name##_fn) params;                                                                  \
        static _Atomic(name##_fn) real;                                                                  \
        name##_fn f = atomic_load_explicit(&real, memory_order_acquire);                                 \
        if (!f) {                                                                                        \
            *(void **)&f = dynlib_symbol(&lib, #name);                                                   \
            if (!f) return fail;                                                                         \
            atomic_store_explicit(&real, f, memory_order_release);                                       \
        }                                                                                                \
        return f args;                                                                                   \
    }
#define DYNLIB_CALL_VOID(lib, name, params, args)                                                        \
    void name params {                                                                                   \
        typedef void(*name##_fn) params;                                                                 \
        static _Atomic(name##_fn) real;                                                                  \
        name##_fn f = atomic_load_explicit(&real, memory_order_acquire);                                 \
        if (!f) {                                                                                        \
            *(void **)&f = dynlib_symbol(&lib, #name);                                                   \
            if (!f) return;                                                                              \
            atomic_store_explicit(&real, f, memory_order_release);                                       \
        }                                                                                                \
        f args;                                                                                          \
    }

/* ---- Embree: a device that cannot be made is NULL, its error UNKNOWN ---- */

DYNLIB_CALL(embree, RTCDevice, rtcNewDevice, (const char *config), (config), NULL)
DYNLIB_CALL(embree, enum RTCError, rtcGetDeviceError, (RTCDevice device), (device), RTC_ERROR_UNKNOWN)
DYNLIB_CALL_VOID(embree, rtcReleaseDevice, (RTCDevice device), (device))
DYNLIB_CALL_VOID(embree, rtcSetDeviceErrorFunction, (RTCDevice device, RTCErrorFunction error, void *user),
                 (device, error, user))
DYNLIB_CALL_VOID(embree, rtcSetDeviceMemoryMonitorFunction,
                 (RTCDevice device, RTCMemoryMonitorFunction monitor, void *user), (device, monitor, user))
DYNLIB_CALL(embree, RTCGeometry, rtcNewGeometry, (RTCDevice device, enum RTCGeometryType type), (device, type),
            NULL)
DYNLIB_CALL_VOID(embree, rtcReleaseGeometry, (RTCGeometry geometry), (geometry))
DYNLIB_CALL_VOID(embree, rtcCommitGeometry, (RTCGeometry geometry), (geometry))
DYNLIB_CALL_VOID(embree, rtcSetGeometryUserData, (RTCGeometry geometry, void *ptr), (geometry, ptr))
DYNLIB_CALL_VOID(embree, rtcSetGeometryUserPrimitiveCount, (RTCGeometry geometry, unsigned int count),
                 (geometry, count))
DYNLIB_CALL_VOID(embree, rtcSetGeometryBoundsFunction, (RTCGeometry geometry, RTCBoundsFunction bounds, void *user),
                 (geometry, bounds, user))
DYNLIB_CALL_VOID(embree, rtcSetGeometryIntersectFunction, (RTCGeometry geometry, RTCIntersectFunctionN intersect),
                 (geometry, intersect))
DYNLIB_CALL_VOID(embree, rtcSetGeometryOccludedFunction, (RTCGeometry geometry, RTCOccludedFunctionN occluded),
                 (geometry, occluded))
DYNLIB_CALL(embree, RTCScene, rtcNewScene, (RTCDevice device), (device), NULL)
DYNLIB_CALL_VOID(embree, rtcReleaseScene, (RTCScene scene), (scene))
DYNLIB_CALL_VOID(embree, rtcSetSceneBuildQuality, (RTCScene scene, enum RTCBuildQuality quality), (scene, quality))
DYNLIB_CALL(embree, unsigned int, rtcAttachGeometry, (RTCScene scene, RTCGeometry geometry), (scene, geometry),
            RTC_INVALID_GEOMETRY_ID)
DYNLIB_CALL_VOID(embree, rtcCommitScene, (RTCScene scene), (scene))
DYNLIB_CALL_VOID(embree, rtcIntersect1, (RTCScene scene, struct RTCIntersectContext *context, struct RTCRayHit *rayhit),
                 (scene, context, rayhit))
DYNLIB_CALL_VOID(embree, rtcOccluded1, (RTCScene scene, struct RTCIntersectContext *context, struct RTCRay *ray),
                 (scene, context, ray))

/* The BVH builder (accel_wide.c): a BVH that cannot be made is NULL, and
 * so is a build or an allocation without the library. */
DYNLIB_CALL(embree, RTCBVH, rtcNewBVH, (RTCDevice device), (device), NULL)
DYNLIB_CALL(embree, void *, rtcBuildBVH, (const struct RTCBuildArguments *args), (args), NULL)
DYNLIB_CALL(embree, void *, rtcThreadLocalAlloc, (RTCThreadLocalAllocator allocator, size_t bytes, size_t align),
            (allocator, bytes, align), NULL)
DYNLIB_CALL_VOID(embree, rtcReleaseBVH, (RTCBVH bvh), (bvh))

/* ---- Assimp: an import that cannot be run is NULL, and the error says why ---- */

DYNLIB_CALL(assimp, const struct aiScene *, aiImportFileEx, (const char *file, unsigned int flags, struct aiFileIO *fs),
            (file, flags, fs), NULL)
DYNLIB_CALL_VOID(assimp, aiReleaseImport, (const struct aiScene *scene), (scene))
DYNLIB_CALL(assimp, enum aiReturn, aiGetMaterialFloatArray,
            (const struct aiMaterial *mat, const char *key, unsigned int type, unsigned int index, ai_real *out,
             unsigned int *max),
            (mat, key, type, index, out, max), aiReturn_FAILURE)
DYNLIB_CALL(assimp, enum aiReturn, aiGetMaterialColor,
            (const struct aiMaterial *mat, const char *key, unsigned int type, unsigned int index,
             struct aiColor4D *out),
            (mat, key, type, index, out), aiReturn_FAILURE)
DYNLIB_CALL(assimp, enum aiReturn, aiGetMaterialString,
            (const struct aiMaterial *mat, const char *key, unsigned int type, unsigned int index,
             struct aiString *out),
            (mat, key, type, index, out), aiReturn_FAILURE)
DYNLIB_CALL(assimp, enum aiReturn, aiGetMaterialTexture,
            (const struct aiMaterial *mat, enum aiTextureType type, unsigned int index, struct aiString *path,
             enum aiTextureMapping *mapping, unsigned int *uvindex, ai_real *blend, enum aiTextureOp *op,
             enum aiTextureMapMode *mapmode, unsigned int *flags),
            (mat, type, index, path, mapping, uvindex, blend, op, mapmode, flags), aiReturn_FAILURE)

/* Assimp's last error, or why Assimp could not be loaded. Never NULL when
 * the library is missing; otherwise what Assimp returns. */
const char *aiGetErrorString(void) {
    typedef const char *(*fn)(void);
    fn f;
    *(void **)&f = dynlib_symbol(&assimp, "aiGetErrorString");
    if (!f) return assimp.error;
    return f();
}
