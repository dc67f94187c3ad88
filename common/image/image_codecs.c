/* image_codecs.c - PNG through libpng's simplified API, JPEG through
 * libjpeg-turbo, OpenEXR through OpenEXRCore; all into memory. */
#include "image_codecs.h"
#include "limit.h"

#include <setjmp.h>
#include <stdio.h> /* before jpeglib.h, which needs FILE */
#include <stdlib.h>
#include <string.h>

#include "jpeg_guard.h"
#include <openexr.h> /* the OpenEXRCore C API */
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

/* A growing in-memory file: encoders write to it, image.c saves it. */
typedef struct {
    uint8_t *data;
    size_t len, cap;
    int failed; /* an allocation failed; further writes are dropped */
} mem_buffer;

/* Write n bytes at offset, growing the buffer (and len) as needed. */
static void mem_write_at(mem_buffer *m, size_t offset, const void *p, size_t n) {
    if (m->failed) return;
    if (offset + n > m->cap) {
        size_t cap = m->cap ? 2 * m->cap : 1 << 16;
        while (cap < offset + n) cap *= 2;
        uint8_t *q = realloc(m->data, cap);
        if (!q) {
            m->failed = 1;
            return;
        }
        m->data = q;
        m->cap = cap;
    }
    memcpy(m->data + offset, p, n);
    if (offset + n > m->len) m->len = offset + n;
}

static void png_mem_write(png_structp png, png_bytep data, size_t n) {
    mem_buffer *m = png_get_io_ptr(png);
    mem_write_at(m, m->len, data, n);
}
static void png_mem_flush(png_structp png) { (void)png; }

uint8_t *codec_png16_encode(const uint16_t *rgb16, int width, int height, size_t *len, char *err, size_t err_len) {
    mem_buffer m = {0};
    uint8_t *volatile row = malloc(6 * (size_t)width);
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!row || !info || setjmp(png_jmpbuf(png))) {
        snprintf(err, err_len, "PNG encoder: %s", row && info ? "libpng error" : "out of memory");
        png_destroy_write_struct(&png, &info);
        free(row);
        free(m.data);
        return NULL;
    }
    png_set_write_fn(png, &m, png_mem_write, png_mem_flush);
    png_set_IHDR(png, info, (png_uint_32)width, (png_uint_32)height, 16, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    for (int y = 0; y < height; y++) { /* PNG samples are big-endian */
        const uint16_t *src = rgb16 + 3 * (size_t)y * (size_t)width;
        for (int i = 0; i < 3 * width; i++) {
            row[2 * i] = (uint8_t)(src[i] >> 8);
            row[2 * i + 1] = (uint8_t)(src[i] & 0xff);
        }
        png_write_row(png, row);
    }
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    free(row);
    if (m.failed) {
        snprintf(err, err_len, "PNG encoder: out of memory");
        free(m.data);
        return NULL;
    }
    *len = m.len;
    return m.data;
}

uint8_t *codec_jpeg_encode(const uint8_t *rgb, int width, int height, int quality, size_t *len, char *err,
                           size_t err_len) {
    struct jpeg_compress_struct cinfo;
    jpeg_guard jerr;
    unsigned char *volatile out = NULL;
    unsigned long out_len = 0;
    cinfo.err = jpeg_guard_init(&jerr);
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

/* ---- OpenEXR ------------------------------------------------------------ */

/* The file is assembled in memory (the library writes at offsets), so that
 * image.c can save it atomically like every other format. */
static int64_t exr_memory_write(exr_const_context_t ctxt, void *user, const void *buf, uint64_t sz, uint64_t offset,
                                exr_stream_error_func_ptr_t error_cb) {
    (void)ctxt;
    (void)error_cb;
    mem_buffer *m = user;
    mem_write_at(m, (size_t)offset, buf, (size_t)sz);
    return m->failed ? -1 : (int64_t)sz;
}

/* Errors are reported through the return codes; keep stderr quiet. */
static void exr_quiet_error(exr_const_context_t ctxt, exr_result_t code, const char *msg) {
    (void)ctxt;
    (void)code;
    (void)msg;
}

static exr_compression_t exr_compression_of(codec_exr_compression c) {
    switch (c) {
    case CODEC_EXR_PIZ: return EXR_COMPRESSION_PIZ;
    case CODEC_EXR_NONE: return EXR_COMPRESSION_NONE;
    default: return EXR_COMPRESSION_ZIP;
    }
}

/* Header: one scanline part, R G B (A) channels, attributes. */
static exr_result_t exr_define_part(exr_context_t ctx, int width, int height, const codec_exr_options *opt) {
    int part;
    exr_result_t rv = exr_add_part(ctx, "rgb", EXR_STORAGE_SCANLINE, &part);
    if (!rv) rv = exr_initialize_required_attr_simple(ctx, part, width, height, exr_compression_of(opt->compression));
    const char *names[4] = {"A", "B", "G", "R"}; /* the library wants them sorted */
    exr_pixel_type_t type = opt->half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
    for (int c = opt->alpha ? 0 : 1; c < 4 && !rv; c++)
        rv = exr_add_channel(ctx, part, names[c], type, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    for (int i = 0; i < opt->attr_count && !rv; i++) rv = exr_attr_set_string(ctx, part, opt->attrs[i].name, opt->attrs[i].value);
    return rv;
}

/* Encode and write every chunk of scanlines; A reads from a row of ones. */
static exr_result_t exr_write_pixels(exr_context_t ctx, const float *rgb, const float *ones, int width, int height) {
    int32_t lines;
    exr_result_t rv = exr_get_scanlines_per_chunk(ctx, 0, &lines);
    exr_encode_pipeline_t enc;
    int started = 0;
    for (int y = 0; y < height && !rv; y += lines) {
        exr_chunk_info_t chunk;
        rv = exr_write_scanline_chunk_info(ctx, 0, y, &chunk);
        if (!rv) rv = started ? exr_encoding_update(ctx, 0, &chunk, &enc) : exr_encoding_initialize(ctx, 0, &chunk, &enc);
        if (rv) break;
        started = 1;
        for (int c = 0; c < enc.channel_count; c++) {
            exr_coding_channel_info_t *ch = &enc.channels[c];
            char n = ch->channel_name[0];
            int offset = n == 'R' ? 0 : n == 'G' ? 1 : 2;
            int alpha = n == 'A';
            ch->encode_from_ptr = alpha ? (const uint8_t *)ones
                                        : (const uint8_t *)(rgb + 3 * (size_t)y * (size_t)width + offset);
            ch->user_pixel_stride = (alpha ? 1 : 3) * (int32_t)sizeof(float);
            ch->user_line_stride = alpha ? 0 : 3 * (int32_t)sizeof(float) * width;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = sizeof(float);
        }
        rv = exr_encoding_choose_default_routines(ctx, 0, &enc);
        if (!rv) rv = exr_encoding_run(ctx, 0, &enc);
    }
    if (started) exr_encoding_destroy(ctx, &enc);
    return rv;
}

uint8_t *codec_exr_encode(const float *rgb, int width, int height, const codec_exr_options *opt, size_t *len,
                          char *err, size_t err_len) {
    mem_buffer mem = {0};
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.user_data = &mem;
    init.write_fn = exr_memory_write;
    init.error_handler_fn = exr_quiet_error;
    float *ones = malloc(sizeof(float) * (size_t)width);
    if (!ones) {
        snprintf(err, err_len, "out of memory");
        return NULL;
    }
    for (int x = 0; x < width; x++) ones[x] = 1.0f;
    exr_context_t ctx = NULL;
    exr_result_t rv = exr_start_write(&ctx, "memory.exr", EXR_WRITE_FILE_DIRECTLY, &init);
    if (!rv) rv = exr_define_part(ctx, width, height, opt);
    if (!rv) rv = exr_write_header(ctx);
    if (!rv) rv = exr_write_pixels(ctx, rgb, ones, width, height);
    exr_result_t fin = ctx ? exr_finish(&ctx) : EXR_ERR_SUCCESS;
    free(ones);
    if (!rv) rv = fin;
    if (rv || mem.failed) {
        snprintf(err, err_len, "OpenEXR encoder: %s", mem.failed ? "out of memory" : exr_get_default_error_message(rv));
        free(mem.data);
        return NULL;
    }
    *len = mem.len;
    return mem.data;
}

/* Point each R, G, B channel of a decode pipeline at its place in rgb;
 * other channels are skipped. Returns how many of R, G, B were found. */
static int exr_bind_channels(exr_decode_pipeline_t *dec, float *rgb, int width) {
    int found = 0;
    for (int c = 0; c < dec->channel_count; c++) {
        exr_coding_channel_info_t *ch = &dec->channels[c];
        const char *n = ch->channel_name;
        int off = strcmp(n, "R") == 0 ? 0 : strcmp(n, "G") == 0 ? 1 : strcmp(n, "B") == 0 ? 2 : -1;
        if (off < 0) {
            ch->decode_to_ptr = NULL;
            continue;
        }
        found++;
        ch->decode_to_ptr = (uint8_t *)(rgb + off);
        ch->user_pixel_stride = 3 * (int32_t)sizeof(float);
        ch->user_line_stride = 3 * (int32_t)sizeof(float) * width;
        ch->user_data_type = EXR_PIXEL_FLOAT;
        ch->user_bytes_per_element = sizeof(float);
    }
    return found;
}

/* Decode every scanline chunk of part 0 into rgb. */
static exr_result_t exr_read_pixels(exr_context_t ctx, const exr_attr_box2i_t *dw, float *rgb, char *err,
                                    size_t err_len) {
    int width = dw->max.x - dw->min.x + 1;
    int32_t lines;
    exr_result_t rv = exr_get_scanlines_per_chunk(ctx, 0, &lines);
    exr_decode_pipeline_t dec;
    int started = 0;
    for (int y = dw->min.y; y <= dw->max.y && !rv; y += lines) {
        exr_chunk_info_t chunk;
        rv = exr_read_scanline_chunk_info(ctx, 0, y, &chunk);
        if (!rv) rv = started ? exr_decoding_update(ctx, 0, &chunk, &dec) : exr_decoding_initialize(ctx, 0, &chunk, &dec);
        if (rv) break;
        started = 1;
        if (exr_bind_channels(&dec, rgb + 3 * (size_t)(chunk.start_y - dw->min.y) * (size_t)width, width) != 3) {
            snprintf(err, err_len, "no R, G and B channels");
            rv = EXR_ERR_INVALID_ARGUMENT;
            break;
        }
        rv = exr_decoding_choose_default_routines(ctx, 0, &dec);
        if (!rv) rv = exr_decoding_run(ctx, 0, &dec);
    }
    if (started) exr_decoding_destroy(ctx, &dec);
    return rv;
}

int codec_exr_decode(const char *path, int *width, int *height, float **rgb, char *err, size_t err_len) {
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_quiet_error;
    exr_context_t ctx = NULL;
    exr_storage_t storage;
    exr_attr_box2i_t dw;
    float *px = NULL;
    char why[160] = "";
    exr_result_t rv = exr_start_read(&ctx, path, &init);
    if (!rv) rv = exr_get_storage(ctx, 0, &storage);
    if (!rv && storage != EXR_STORAGE_SCANLINE) {
        snprintf(why, sizeof why, "only scanline images are read, not tiled or deep");
        rv = EXR_ERR_INVALID_ARGUMENT;
    }
    if (!rv) rv = exr_get_data_window(ctx, 0, &dw);
    long long w = rv ? 0 : (long long)dw.max.x - dw.min.x + 1, h = rv ? 0 : (long long)dw.max.y - dw.min.y + 1;
    if (!rv && (w < 1 || h < 1 || w > LIMIT_SIDE || h > LIMIT_SIDE)) {
        snprintf(why, sizeof why, "data window of %lldx%lld pixels is out of range", w, h);
        rv = EXR_ERR_INVALID_ARGUMENT;
    }
    if (!rv && !(px = calloc((size_t)(w * h * 3), sizeof(float)))) {
        snprintf(why, sizeof why, "out of memory");
        rv = EXR_ERR_OUT_OF_MEMORY;
    }
    if (!rv) rv = exr_read_pixels(ctx, &dw, px, why, sizeof why);
    if (ctx) exr_finish(&ctx);
    if (rv) {
        snprintf(err, err_len, "%s: not a readable OpenEXR image: %s", path, why[0] ? why : exr_get_default_error_message(rv));
        free(px);
        return -1;
    }
    *width = (int)w;
    *height = (int)h;
    *rgb = px;
    return 0;
}
