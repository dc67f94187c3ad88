/* image_codecs.h - encoders of 8-bit sRGB pixels into PNG and JPEG files in
 * memory, for image.c (which tone maps first and writes atomically).
 *
 * Each returns a malloc'd buffer holding the whole file (the caller frees
 * it) and its length, or NULL with the library's reason in err. */
#ifndef TESSERA_IMAGE_CODECS_H
#define TESSERA_IMAGE_CODECS_H

#include <stddef.h>
#include <stdint.h>

/* rgb: width * height * 3 bytes, top row first. */
uint8_t *codec_png_encode(const uint8_t *rgb, int width, int height, size_t *len, char *err, size_t err_len);

/* 16-bit sRGB PNG (full libpng API: IHDR depth 16 and an sRGB chunk).
 * rgb16: width * height * 3 values in host order, top row first. */
uint8_t *codec_png16_encode(const uint16_t *rgb16, int width, int height, size_t *len, char *err, size_t err_len);

/* quality 1..100 (libjpeg-turbo, 4:2:0 below 90, 4:4:4 from 90). */
uint8_t *codec_jpeg_encode(const uint8_t *rgb, int width, int height, int quality, size_t *len, char *err,
                           size_t err_len);



/* A string attribute to record in the file's header. */
typedef struct {
    const char *name, *value;
} codec_attribute;

/* DWAA is not offered: Debian's OpenEXRCore 3.1 C API does not implement it. */
typedef enum { CODEC_EXR_ZIP, CODEC_EXR_PIZ, CODEC_EXR_NONE } codec_exr_compression;

/* Scanline OpenEXR (OpenEXRCore C API): R, G, B channels (and A = 1 with
 * alpha), float32 or half, display and data window (0,0)-(width-1,height-1),
 * the given compression and string attributes. rgb: 3 floats per pixel, top
 * row first. */
typedef struct {
    codec_exr_compression compression;
    int half;  /* 16-bit half channels instead of float32 */
    int alpha; /* add an A channel of 1 */
    const codec_attribute *attrs;
    int attr_count;
} codec_exr_options;

uint8_t *codec_exr_encode(const float *rgb, int width, int height, const codec_exr_options *opt, size_t *len,
                          char *err, size_t err_len);

/* Read a scanline OpenEXR file's R, G, B channels (any pixel type, converted
 * to float) over its data window. Returns 0 and a malloc'd rgb buffer (3
 * floats per pixel, top row first; the caller frees it), or -1 with the
 * reason in err (not EXR, tiled, no R/G/B channels, corrupt). */
int codec_exr_decode(const char *path, int *width, int *height, float **rgb, char *err, size_t err_len);

#endif
