/* image_meta.h - the attributes every image Tessera writes carries, in the
 * EXR header and in PNG tEXt chunks, whichever command wrote it (`render`,
 * `submit --wait`, `fetch`): tessera:scene (the scene file as named on the
 * command line), tessera:spp, tessera:seed and tessera:version. Nothing
 * that varies between runs, so the same render gives the same bytes. */
#ifndef TESSERA_IMAGE_META_H
#define TESSERA_IMAGE_META_H

#include <stdint.h>

#include "image.h"

#define IMAGE_META_COUNT 4

typedef struct {
    char spp[24], seed[24];
    char scene[1024]; /* image_meta_from_exr's copy */
    codec_attribute attrs[IMAGE_META_COUNT];
} image_meta;

/* Fill m for a render of scene (kept by pointer: it must outlive m) with
 * spp samples per pixel and seed, and point wo's attributes at m (so m
 * must outlive the image_write that uses wo). Can't fail. */
void image_meta_apply(image_meta *m, const char *scene, int spp, uint64_t seed, image_write_options *wo);

/* Read tessera:scene, tessera:spp and tessera:seed from the header of the
 * EXR file at path and apply them as image_meta_apply does (`tessera
 * tonemap` keeps the header of its input). Returns 0, or -1 with wo
 * untouched when path is not an EXR file holding all three (a PFM has no
 * header). */
int image_meta_from_exr(image_meta *m, const char *path, image_write_options *wo);

#endif
