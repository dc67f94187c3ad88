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

/* quality 1..100 (libjpeg-turbo, 4:2:0 below 90, 4:4:4 from 90). */
uint8_t *codec_jpeg_encode(const uint8_t *rgb, int width, int height, int quality, size_t *len, char *err,
                           size_t err_len);

#endif
