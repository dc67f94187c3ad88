/* local_fork.h - a local farm's workers started as forks of `tessera
 * render`, after it has loaded the scene and built its intersector: each
 * worker begins with the scene in the coordinator's pages (copy on write,
 * shared, never loaded or built again), then runs as tessera-worker would
 * (worker_run) once the farm tells it where to dial (local_farm.h,
 * local_farm_forked). The farm restarts a worker that dies by spawning
 * tessera-worker, which loads the scene from its bundle: the same bytes.
 *
 * Why: each spawned worker parsed the scene and built the tree again on
 * its one thread after this process had, and kept its own copy of both
 * (docs/meshes.md, "Twenty-seventh session"). */
#ifndef TESSERA_CLI_LOCAL_FORK_H
#define TESSERA_CLI_LOCAL_FORK_H

#include <stddef.h>

#include "coordinator/local_farm.h"
#include "render/scene.h"

typedef struct {
    int workers;            /* how many to fork, named local-0 ... local-(n-1) */
    int threads;            /* render threads of each */
    int verbose, quiet;     /* their logging, as tessera-worker's --verbose / --quiet */
    const char *token_file; /* the farm's token file (each proves it), or NULL */
} local_fork_options;

/* Fork o->workers workers over s (its intersector built; not changed
 * here), whose bundle hashes to hash. Each child waits, before anything
 * else, for the farm's address on its fd (end of file without one: it
 * exits 0). Call before this process has an event loop or threads: the
 * children keep only the calling thread and must not inherit libuv's
 * signal handling. Returns 0 with out[0 .. workers) filled (the caller
 * hands them to local_farm_render, which adopts or releases them), or -1
 * with the reason in err and no child left. */
int local_fork_workers(const local_fork_options *o, scene *s, const char *hash, local_farm_forked *out, char *err,
                       size_t err_len);

#endif
