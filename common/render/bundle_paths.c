/* bundle_paths.c - files of a bundle kept under the scene's folder
 * (bundle_paths.h). */
#define _GNU_SOURCE
#include "bundle_paths.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int bundle_paths_check(const scene_bundle *b, const char *scene_path, char *err, size_t err_len) {
    char dir[4096], root[PATH_MAX], path[8192], real[PATH_MAX];
    scene_bundle_folder(scene_path, dir, sizeof dir);
    if (!realpath(dir, root)) {
        snprintf(err, err_len, "%s: cannot resolve the scene's folder %s", scene_path, dir);
        return -1;
    }
    size_t rl = strlen(root);
    for (size_t i = 1; i < b->count; i++) {
        const char *name = b->files[i].name;
        if (!b->files[i].data || b->files[i].streamed) continue; /* unreadable (the loader names it); not a file */
        if (name[0] == '/') snprintf(path, sizeof path, "%s", name);
        else snprintf(path, sizeof path, "%s/%s", dir, name);
        int inside = realpath(path, real) && strncmp(real, root, rl) == 0 &&
                     (real[rl] == '/' || (rl == 1 && root[0] == '/'));
        if (!inside) {
            snprintf(err, err_len,
                     "%s: mesh file %s is outside the scene's folder %s; submit uploads only files under it",
                     scene_path, name, root);
            return -1;
        }
    }
    return 0;
}
