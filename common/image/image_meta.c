/* image_meta.c - the tessera:* attributes of written images (see image_meta.h). */
#include "image_meta.h"

#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

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

/* Errors are reported through the return codes; keep stderr quiet. */
static void meta_quiet_error(exr_const_context_t ctxt, exr_result_t code, const char *msg) {
    (void)ctxt;
    (void)code;
    (void)msg;
}

int image_meta_from_exr(image_meta *m, const char *path, image_write_options *wo) {
    size_t n = strlen(path);
    if (n < 4 || strcasecmp(path + n - 4, ".exr") != 0) return -1;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = meta_quiet_error;
    exr_context_t ctx = NULL;
    const char *names[3] = {"tessera:scene", "tessera:spp", "tessera:seed"}, *vals[3] = {0};
    int32_t lens[3] = {0};
    exr_result_t rv = exr_start_read(&ctx, path, &init);
    for (int i = 0; i < 3 && !rv; i++) rv = exr_attr_get_string(ctx, 0, names[i], &lens[i], &vals[i]);
    if (!rv) {
        snprintf(m->scene, sizeof m->scene, "%.*s", (int)lens[0], vals[0]);
        char spp[24], seed[24];
        snprintf(spp, sizeof spp, "%.*s", (int)lens[1], vals[1]);
        snprintf(seed, sizeof seed, "%.*s", (int)lens[2], vals[2]);
        image_meta_apply(m, m->scene, atoi(spp), strtoull(seed, NULL, 10), wo);
    }
    if (ctx) exr_finish(&ctx);
    return rv ? -1 : 0;
}
