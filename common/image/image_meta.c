/* image_meta.c - the tessera:* attributes of written images (see image_meta.h). */
#include "image_meta.h"

#include <stdio.h>

#include "version.h"

void image_meta_apply(image_meta *m, const char *scene, int spp, uint64_t seed, image_write_options *wo) {
    snprintf(m->spp, sizeof m->spp, "%d", spp);
    snprintf(m->seed, sizeof m->seed, "%llu", (unsigned long long)seed);
    m->attrs[0] = (codec_attribute){"tessera:scene", scene};
    m->attrs[1] = (codec_attribute){"tessera:spp", m->spp};
    m->attrs[2] = (codec_attribute){"tessera:seed", m->seed};
    m->attrs[3] = (codec_attribute){"tessera:version", TESSERA_VERSION};
    wo->exr.attrs = m->attrs;
    wo->exr.attr_count = IMAGE_META_COUNT;
}
