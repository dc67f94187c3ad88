/* bundle_paths.h - which local files a scene bundle may carry off the
 * machine: `tessera submit` uploads the files a scene names, so a scene
 * naming "../../.ssh/id_ed25519" or "/etc/shadow" as a mesh must be
 * refused, naming the path, before anything is sent. A file is allowed
 * when, with every symbolic link resolved, it lies under the scene's own
 * folder. */
#ifndef TESSERA_BUNDLE_PATHS_H
#define TESSERA_BUNDLE_PATHS_H

#include <stddef.h>

#include "scene_bundle.h"

/* Check every file of b (read by scene_bundle_read from scene_path) lies
 * under scene_path's folder. Returns 0, or -1 with "SCENE: mesh file PATH
 * is outside the scene's folder DIR; submit uploads only files under it"
 * in err. Files that could not be read are left to the loader's message. */
int bundle_paths_check(const scene_bundle *b, const char *scene_path, char *err, size_t err_len);

#endif
