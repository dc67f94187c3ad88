/* texture.c - PNG/JPEG decoding through libpng's simplified API and libjpeg,
 * with the declared size checked first, and bilinear lookup. */
#include "texture.h"

#include <png.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "jpeg_guard.h"

static int size_ok(long w, long h, const char *name, char *err, size_t err_len) {
    if (w < 1 || h < 1 || w > TEXTURE_MAX_SIDE || h > TEXTURE_MAX_SIDE ||
        (unsigned long long)w * (unsigned long long)h > TEXTURE_MAX_TEXELS) {
        snprintf(err, err_len, "%s: texture is %ldx%ld, larger than the limit (%d on a side, %u texels)", name, w,
                 h, TEXTURE_MAX_SIDE, TEXTURE_MAX_TEXELS);
        return 0;
    }
    return 1;
}

static int decode_png(const uint8_t *data, size_t len, const char *name, texture *out, char *err, size_t err_len) {
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_memory(&img, data, len)) {
        snprintf(err, err_len, "%s: bad PNG: %s", name, img.message);
        png_image_free(&img);
        return -1;
    }
    if (!size_ok((long)img.width, (long)img.height, name, err, err_len)) {
        png_image_free(&img);
        return -1;
    }
    img.format = PNG_FORMAT_RGBA;
    out->width = (int)img.width;
    out->height = (int)img.height;
    out->rgba = malloc(PNG_IMAGE_SIZE(img));
    if (!out->rgba) {
        snprintf(err, err_len, "%s: out of memory for a %ux%u texture", name, img.width, img.height);
        png_image_free(&img);
        return -1;
    }
    if (!png_image_finish_read(&img, NULL, out->rgba, 0, NULL)) {
        snprintf(err, err_len, "%s: bad PNG: %s", name, img.message);
        png_image_free(&img);
        free(out->rgba);
        out->rgba = NULL;
        return -1;
    }
    return 0;
}

static int decode_jpeg(const uint8_t *data, size_t len, const char *name, texture *out, char *err, size_t err_len) {
    struct jpeg_decompress_struct ci;
    jpeg_guard je;
    uint8_t *volatile row = NULL;
    memset(&ci, 0, sizeof ci);
    ci.err = jpeg_guard_init(&je);
    if (setjmp(je.escape)) {
        snprintf(err, err_len, "%s: bad JPEG: %s", name, je.message);
        jpeg_destroy_decompress(&ci);
        free(row);
        free(out->rgba);
        out->rgba = NULL;
        return -1;
    }
    jpeg_create_decompress(&ci);
    jpeg_mem_src(&ci, data, (unsigned long)len);
    jpeg_read_header(&ci, TRUE);
    if (!size_ok((long)ci.image_width, (long)ci.image_height, name, err, err_len)) {
        jpeg_destroy_decompress(&ci);
        return -1;
    }
    ci.out_color_space = JCS_RGB;
    jpeg_start_decompress(&ci);
    out->width = (int)ci.output_width;
    out->height = (int)ci.output_height;
    out->rgba = malloc((size_t)out->width * (size_t)out->height * 4);
    row = malloc((size_t)out->width * 3);
    if (!out->rgba || !row) {
        snprintf(je.message, sizeof je.message, "out of memory");
        longjmp(je.escape, 1);
    }
    while (ci.output_scanline < ci.output_height) {
        JSAMPROW r = row;
        size_t y = ci.output_scanline;
        if (jpeg_read_scanlines(&ci, &r, 1) != 1) break;
        uint8_t *dst = out->rgba + y * (size_t)out->width * 4;
        for (int x = 0; x < out->width; x++) {
            dst[4 * x] = row[3 * x];
            dst[4 * x + 1] = row[3 * x + 1];
            dst[4 * x + 2] = row[3 * x + 2];
            dst[4 * x + 3] = 255;
        }
    }
    jpeg_finish_decompress(&ci);
    jpeg_destroy_decompress(&ci);
    free(row);
    return 0;
}

int texture_decode(const uint8_t *data, size_t len, const char *name, texture *out, char *err, size_t err_len) {
    memset(out, 0, sizeof *out);
    static const uint8_t png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    if (len >= 8 && memcmp(data, png_sig, 8) == 0) return decode_png(data, len, name, out, err, err_len);
    if (len >= 3 && data[0] == 0xff && data[1] == 0xd8 && data[2] == 0xff)
        return decode_jpeg(data, len, name, out, err, err_len);
    snprintf(err, err_len, "%s: not a PNG or JPEG image", name);
    return -1;
}

static float srgb_table[256];
static pthread_once_t srgb_once = PTHREAD_ONCE_INIT;

static void srgb_fill(void) {
    for (int i = 0; i < 256; i++) {
        double v = i / 255.0;
        srgb_table[i] = (float)(v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4));
    }
}

float texture_srgb_to_linear(uint8_t c) {
    pthread_once(&srgb_once, srgb_fill);
    return srgb_table[c];
}

/* Texel index along one axis of size n for integer coordinate i. */
static int wrap_index(int i, int n, texture_wrap w) {
    switch (w) {
    case WRAP_CLAMP:
        return i < 0 ? 0 : i >= n ? n - 1 : i;
    case WRAP_MIRROR: {
        int period = 2 * n, k = i % period;
        if (k < 0) k += period;
        return k < n ? k : period - 1 - k;
    }
    default: {
        int k = i % n;
        return k < 0 ? k + n : k;
    }
    }
}

static void fetch(const texture *t, int x, int y, float out[4]) {
    const uint8_t *p = t->rgba + ((size_t)y * (size_t)t->width + (size_t)x) * 4;
    for (int c = 0; c < 3; c++) out[c] = t->srgb ? texture_srgb_to_linear(p[c]) : p[c] * (1.0f / 255.0f);
    out[3] = p[3] * (1.0f / 255.0f);
}

texel texture_lookup(const texture *t, float u, float v) {
    if (!isfinite(u) || !isfinite(v)) u = v = 0.0f;
    /* Keep the coordinate in a range where the float-to-int conversion is
     * exact and defined; repeat and mirror are periodic, so shifting by
     * whole periods changes nothing. */
    u = t->wrap_s == WRAP_CLAMP ? min_f(max_f(u, 0.0f), 1.0f) : u - 2.0f * floorf(u * 0.5f);
    v = t->wrap_t == WRAP_CLAMP ? min_f(max_f(v, 0.0f), 1.0f) : v - 2.0f * floorf(v * 0.5f);
    float x = u * (float)t->width - 0.5f, y = v * (float)t->height - 0.5f;
    float fx = floorf(x), fy = floorf(y);
    float ax = x - fx, ay = y - fy;
    int x0 = (int)fx, y0 = (int)fy;
    float c00[4], c10[4], c01[4], c11[4];
    int xa = wrap_index(x0, t->width, t->wrap_s), xb = wrap_index(x0 + 1, t->width, t->wrap_s);
    int ya = wrap_index(y0, t->height, t->wrap_t), yb = wrap_index(y0 + 1, t->height, t->wrap_t);
    fetch(t, xa, ya, c00);
    fetch(t, xb, ya, c10);
    fetch(t, xa, yb, c01);
    fetch(t, xb, yb, c11);
    float r[4];
    for (int c = 0; c < 4; c++)
        r[c] = (1 - ay) * ((1 - ax) * c00[c] + ax * c10[c]) + ay * ((1 - ax) * c01[c] + ax * c11[c]);
    texel out = {vec3_make(r[0], r[1], r[2]), r[3]};
    return out;
}

void texture_free(texture *t) {
    if (!t) return;
    free(t->rgba);
    t->rgba = NULL;
}
