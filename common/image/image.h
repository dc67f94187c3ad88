/* image.h - float RGB images and the files they are saved to and loaded from.
 *
 * An image is 3 floats per pixel, row-major, row 0 at the top. The file
 * format is chosen by the extension: .pfm and .exr (linear float); .ppm,
 * .png, .jpg/.jpeg (tone mapped, sRGB, 8 bits). Writes are atomic: a temporary file in the same
 * folder, renamed into place once complete.
 *
 * Layer image/: image files, tone mapping, comparison; includes only
 * common/ (README "Where things are"). */
#ifndef TESSERA_IMAGE_H
#define TESSERA_IMAGE_H

#include <stddef.h>

#include "image_codecs.h"
#include "tonemap.h"

typedef struct {
    int width, height;
    float *rgb;
} image;

/* Allocate a black image. Returns 0, or -1 when out of memory. */
int image_alloc(image *img, int width, int height);

/* Free the pixels; the struct is the caller's. */
void image_free(image *img);

typedef struct {
    tonemap_options tonemap; /* for 8-bit formats */
    int jpeg_quality;        /* 1..100; 0 means the default, 92 */
    int png16;               /* 16-bit PNG instead of 8 */
    codec_exr_options exr;   /* compression (default ZIP), half, alpha, attributes (PNG: tEXt) */
    size_t bad_pixels;       /* out: NaN/Inf pixels written black */
} image_write_options;

/* Write img to path in the format its extension names. Returns 0, or -1 with
 * "PATH: reason" in err (unknown extension, with the known ones listed; I/O
 * errors). Nothing is left at path, nor any temporary file, on failure. */
int image_write(const char *path, const image *img, image_write_options *opt, char *err, size_t err_len);

/* What image_write(path, ...) would refuse before any work is done for it:
 * an extension it does not know, or a folder where no file can be made
 * (file_check_writable). Returns 0, or -1 with "PATH: reason" in err. */
int image_check_path(const char *path, char *err, size_t err_len);

/* Read a .pfm or .ppm file into img (allocated here; free with image_free).
 * PPM values are decoded from sRGB to linear. Returns 0, or -1 with
 * "PATH: reason" in err. */
int image_read(const char *path, image *img, char *err, size_t err_len);

#endif
