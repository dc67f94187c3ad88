/* image_codecs.c - PNG through libpng's simplified API, JPEG through
 * libjpeg-turbo, both into memory. */
#include "image_codecs.h"

#include <setjmp.h>
#include <stdio.h> /* before jpeglib.h, which needs FILE */
#include <stdlib.h>
#include <string.h>

#include <jpeglib.h>
#include <png.h>

uint8_t *codec_png_encode(const uint8_t *rgb, int width, int height, size_t *len, char *err, size_t err_len) {
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    img.width = (png_uint_32)width;
    img.height = (png_uint_32)height;
    img.format = PNG_FORMAT_RGB;
    png_alloc_size_t size = 0;
    /* First call measures, second writes. */
    if (!png_image_write_to_memory(&img, NULL, &size, 0, rgb, 0, NULL)) {
        snprintf(err, err_len, "PNG encoder: %s", img.message);
        png_image_free(&img);
        return NULL;
    }
    uint8_t *buf = malloc(size);
    if (!buf) {
        snprintf(err, err_len, "out of memory for a %zu-byte PNG", (size_t)size);
        return NULL;
    }
    if (!png_image_write_to_memory(&img, buf, &size, 0, rgb, 0, NULL)) {
        snprintf(err, err_len, "PNG encoder: %s", img.message);
        png_image_free(&img);
        free(buf);
        return NULL;
    }
    *len = size;
    return buf;
}

/* libjpeg reports errors by calling error_exit, which must not return: jump
 * back to the encoder with the message instead of exiting the process. */
typedef struct {
    struct jpeg_error_mgr mgr;
    jmp_buf escape;
    char message[JMSG_LENGTH_MAX];
} jpeg_errors;

static void jpeg_error_exit(j_common_ptr cinfo) {
    jpeg_errors *e = (jpeg_errors *)cinfo->err;
    (*cinfo->err->format_message)(cinfo, e->message);
    longjmp(e->escape, 1);
}

uint8_t *codec_jpeg_encode(const uint8_t *rgb, int width, int height, int quality, size_t *len, char *err,
                           size_t err_len) {
    struct jpeg_compress_struct cinfo;
    jpeg_errors jerr;
    unsigned char *volatile out = NULL;
    unsigned long out_len = 0;
    cinfo.err = jpeg_std_error(&jerr.mgr);
    jerr.mgr.error_exit = jpeg_error_exit;
    if (setjmp(jerr.escape)) {
        snprintf(err, err_len, "JPEG encoder: %s", jerr.message);
        jpeg_destroy_compress(&cinfo);
        free(out);
        return NULL;
    }
    jpeg_create_compress(&cinfo);
    jpeg_mem_dest(&cinfo, (unsigned char **)&out, &out_len);
    cinfo.image_width = (JDIMENSION)width;
    cinfo.image_height = (JDIMENSION)height;
    cinfo.input_components = 3;
    cinfo.in_color_space = JCS_RGB;
    jpeg_set_defaults(&cinfo);
    jpeg_set_quality(&cinfo, quality, TRUE);
    if (quality >= 90) { /* no chroma subsampling at high quality */
        cinfo.comp_info[0].h_samp_factor = cinfo.comp_info[0].v_samp_factor = 1;
    }
    jpeg_start_compress(&cinfo, TRUE);
    while (cinfo.next_scanline < cinfo.image_height) {
        JSAMPROW row = (JSAMPROW)(rgb + (size_t)cinfo.next_scanline * (size_t)width * 3);
        jpeg_write_scanlines(&cinfo, &row, 1);
    }
    jpeg_finish_compress(&cinfo);
    jpeg_destroy_compress(&cinfo);
    *len = out_len;
    return out;
}
