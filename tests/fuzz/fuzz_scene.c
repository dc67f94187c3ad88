/* fuzz_scene.c - libFuzzer target: any bytes as a scene file (with one
 * mesh, "m.obj", holding the same bytes) must load or be refused with a
 * message; never crash, hang or leak. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "render/scene.h"
#include "render/scene_bundle.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    char *text = malloc(size + 1);
    if (!text) return 0;
    memcpy(text, data, size);
    text[size] = '\0';
    scene_bundle_file files[2] = {{.name = "fuzz.json", .data = text, .len = size},
                                  {.name = "m.obj", .data = text, .len = size}};
    scene_bundle b = {files, 2};
    char err[1024];
    scene_overrides ov = {.width = 64, .height = 64, .spp = -1, .max_depth = -1}; /* a small image */
    scene *s = scene_load_bundle(&b, &ov, err, sizeof err);
    if (!s && !err[0]) abort(); /* a refusal must say why */
    scene_free(s);
    free(text);
    return 0;
}
