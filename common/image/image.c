/* image.c - float images; PFM and PPM writers and readers; atomic saves.
 *
 * PNG, JPEG and OpenEXR are encoded by image_codecs.c.
 * PFM: "PF\n<w> <h>\n-1\n" then little-endian float32 RGB, rows from the
 * bottom of the image to the top (the format's convention). PPM: binary P6,
 * maxval 255, top row first. */
#include "image.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fileio.h"
#include "image_codecs.h"
#include "limit.h"
#include "png_text.h"

#define IMAGE_MAX_SIDE LIMIT_SIDE

int image_alloc(image *img, int width, int height) {
    img->width = width;
    img->height = height;
    img->rgb = calloc((size_t)width * (size_t)height * 3, sizeof(float));
    return img->rgb ? 0 : -1;
}

void image_free(image *img) {
    free(img->rgb);
    img->rgb = NULL;
}

static const char *extension(const char *path) {
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    return (dot && (!slash || dot > slash)) ? dot + 1 : "";
}

static void float_to_le(float f, uint8_t out[4]) {
    uint32_t u;
    memcpy(&u, &f, 4);
    for (int i = 0; i < 4; i++) out[i] = (uint8_t)(u >> (8 * i));
}

static float float_from_bytes(const uint8_t in[4], int little) {
    uint32_t u = 0;
    for (int i = 0; i < 4; i++) u |= (uint32_t)in[little ? i : 3 - i] << (8 * i);
    float f;
    memcpy(&f, &u, 4);
    return f;
}

/* Encoders fill a malloc'd buffer with the whole file. */
static uint8_t *encode_pfm(const image *img, size_t *len) {
    char header[64];
    int hl = snprintf(header, sizeof header, "PF\n%d %d\n-1.0\n", img->width, img->height);
    size_t n = (size_t)img->width * (size_t)img->height * 3;
    uint8_t *buf = malloc((size_t)hl + 4 * n);
    if (!buf) return NULL;
    memcpy(buf, header, (size_t)hl);
    uint8_t *p = buf + hl;
    for (int y = img->height - 1; y >= 0; y--)
        for (int i = 0; i < img->width * 3; i++, p += 4)
            float_to_le(img->rgb[(size_t)y * (size_t)img->width * 3 + (size_t)i], p);
    *len = (size_t)hl + 4 * n;
    return buf;
}

/* Tone map to 8-bit sRGB; returns a malloc'd width*height*3 buffer. */
static uint8_t *to_8bit(const image *img, image_write_options *opt) {
    size_t n = (size_t)img->width * (size_t)img->height;
    uint8_t *px = malloc(3 * n);
    if (px) opt->bad_pixels = tonemap_to_8bit(img->rgb, n, &opt->tonemap, px);
    return px;
}

static uint8_t *encode_ppm(const uint8_t *px, int width, int height, size_t *len) {
    char header[64];
    int hl = snprintf(header, sizeof header, "P6\n%d %d\n255\n", width, height);
    size_t n = 3 * (size_t)width * (size_t)height;
    uint8_t *buf = malloc((size_t)hl + n);
    if (!buf) return NULL;
    memcpy(buf, header, (size_t)hl);
    memcpy(buf + hl, px, n);
    *len = (size_t)hl + n;
    return buf;
}

/* Tone map to 16-bit sRGB and encode a 16-bit PNG. */
static uint8_t *encode_png16(const image *img, image_write_options *opt, size_t *len, char *err, size_t err_len) {
    size_t n = (size_t)img->width * (size_t)img->height;
    uint16_t *px16 = malloc(3 * n * sizeof(uint16_t));
    if (!px16) {
        snprintf(err, err_len, "out of memory");
        return NULL;
    }
    opt->bad_pixels = tonemap_encode(img->rgb, n, &opt->tonemap, 16, px16);
    uint8_t *buf = codec_png16_encode(px16, img->width, img->height, len, err, err_len);
    free(px16);
    return buf;
}

/* Encode an 8-bit format (ppm, png, jpg); NULL with err set on failure. */
static uint8_t *encode_8bit(const char *ext, const image *img, image_write_options *opt, size_t *len, char *err,
                            size_t err_len) {
    uint8_t *px = to_8bit(img, opt), *buf = NULL;
    if (!px) {
        snprintf(err, err_len, "out of memory");
        return NULL;
    }
    int quality = opt->jpeg_quality > 0 ? opt->jpeg_quality : 92;
    if (strcasecmp(ext, "ppm") == 0) {
        buf = encode_ppm(px, img->width, img->height, len);
        if (!buf) snprintf(err, err_len, "out of memory");
    } else if (strcasecmp(ext, "png") == 0) {
        buf = codec_png_encode(px, img->width, img->height, len, err, err_len);
    } else {
        buf = codec_jpeg_encode(px, img->width, img->height, quality, len, err, err_len);
    }
    free(px);
    return buf;
}

/* Whether image_write knows the format the extension ext names. */
static int known_format(const char *ext) {
    static const char *const known[] = {"pfm", "exr", "ppm", "png", "jpg", "jpeg"};
    for (size_t i = 0; i < sizeof known / sizeof known[0]; i++)
        if (strcasecmp(ext, known[i]) == 0) return 1;
    return 0;
}

/* image_write's message for an extension it does not know. */
static void unknown_format(const char *path, const char *ext, char *err, size_t err_len) {
    snprintf(err, err_len, "%s: unknown image format \"%s\" (known: .pfm .exr .ppm .png .jpg .jpeg)", path, ext);
}

int image_check_path(const char *path, char *err, size_t err_len) {
    if (!known_format(extension(path))) {
        unknown_format(path, extension(path), err, err_len);
        return -1;
    }
    return file_check_writable(path, err, err_len);
}

int image_write(const char *path, const image *img, image_write_options *opt, char *err, size_t err_len) {
    const char *ext = extension(path);
    size_t len = 0;
    uint8_t *buf = NULL;
    char why[256] = "out of memory";
    opt->bad_pixels = 0;
    if (strcasecmp(ext, "pfm") == 0) {
        buf = encode_pfm(img, &len);
    } else if (strcasecmp(ext, "exr") == 0) {
        buf = codec_exr_encode(img->rgb, img->width, img->height, &opt->exr, &len, why, sizeof why);
    } else if (opt->png16 && strcasecmp(ext, "png") == 0) {
        buf = encode_png16(img, opt, &len, why, sizeof why);
    } else if (strcasecmp(ext, "ppm") == 0 || strcasecmp(ext, "png") == 0 || strcasecmp(ext, "jpg") == 0 ||
               strcasecmp(ext, "jpeg") == 0) {
        buf = encode_8bit(ext, img, opt, &len, why, sizeof why);
    } else {
        unknown_format(path, ext, err, err_len);
        return -1;
    }
    if (buf && strcasecmp(ext, "png") == 0) /* the EXR attributes, as tEXt chunks */
        buf = png_text_insert(buf, &len, opt->exr.attrs, opt->exr.attr_count, why, sizeof why);
    if (!buf) {
        snprintf(err, err_len, "%s: cannot encode the image: %s", path, why);
        return -1;
    }
    int rc = file_write_atomic(path, buf, len, err, err_len);
    free(buf);
    return rc;
}

/* Parse "MAGIC w h third\n" (PNM-style header, whitespace separated, no
 * comments for PFM). Returns the offset of the pixel data or -1. */
static long parse_header(const char *buf, size_t len, const char *magic, int *w, int *h, double *third) {
    size_t ml = strlen(magic);
    if (len < ml || memcmp(buf, magic, ml) != 0) return -1;
    size_t pos = ml;
    double vals[3];
    for (int k = 0; k < 3; k++) {
        while (pos < len && (buf[pos] == ' ' || buf[pos] == '\t' || buf[pos] == '\n' || buf[pos] == '\r')) pos++;
        char num[40];
        size_t n = 0;
        while (pos < len && n < sizeof num - 1 && buf[pos] != ' ' && buf[pos] != '\t' && buf[pos] != '\n' && buf[pos] != '\r')
            num[n++] = buf[pos++];
        num[n] = '\0';
        char *end;
        vals[k] = strtod(num, &end);
        if (n == 0 || *end) return -1;
    }
    if (pos >= len) return -1;
    pos++; /* the single whitespace byte before the data */
    if (vals[0] < 1 || vals[0] > IMAGE_MAX_SIDE || vals[1] < 1 || vals[1] > IMAGE_MAX_SIDE ||
        vals[0] != floor(vals[0]) || vals[1] != floor(vals[1]))
        return -1;
    *w = (int)vals[0];
    *h = (int)vals[1];
    *third = vals[2];
    return (long)pos;
}

static int decode_pfm(const char *buf, size_t len, image *img) {
    int w, h;
    double scale;
    long off = parse_header(buf, len, "PF", &w, &h, &scale);
    if (off < 0 || scale == 0 || !isfinite(scale)) return -1;
    size_t n = (size_t)w * (size_t)h * 3;
    if (len - (size_t)off != 4 * n) return -1;
    if (image_alloc(img, w, h)) return -1;
    const uint8_t *p = (const uint8_t *)buf + off;
    int little = scale < 0;
    for (int y = h - 1; y >= 0; y--)
        for (int i = 0; i < w * 3; i++, p += 4) img->rgb[(size_t)y * (size_t)w * 3 + (size_t)i] = float_from_bytes(p, little);
    return 0;
}

static float srgb_decode(float c) { return c <= 0.04045f ? c / 12.92f : powf((c + 0.055f) / 1.055f, 2.4f); }

static int decode_ppm(const char *buf, size_t len, image *img) {
    int w, h;
    double maxval;
    long off = parse_header(buf, len, "P6", &w, &h, &maxval);
    if (off < 0 || maxval != 255) return -1;
    size_t n = (size_t)w * (size_t)h * 3;
    if (len - (size_t)off != n) return -1;
    if (image_alloc(img, w, h)) return -1;
    for (size_t i = 0; i < n; i++) img->rgb[i] = srgb_decode((uint8_t)buf[off + (long)i] / 255.0f);
    return 0;
}

int image_read(const char *path, image *img, char *err, size_t err_len) {
    size_t len;
    const char *ext = extension(path);
    int pfm = strcasecmp(ext, "pfm") == 0, ppm = strcasecmp(ext, "ppm") == 0;
    img->rgb = NULL;
    if (strcasecmp(ext, "exr") == 0) return codec_exr_decode(path, &img->width, &img->height, &img->rgb, err, err_len);
    if (!pfm && !ppm) {
        snprintf(err, err_len, "%s: cannot read \"%s\" images (known: .pfm .exr .ppm)", path, ext);
        return -1;
    }
    char *buf = file_read_all(path, (size_t)1 << 34, &len, err, err_len);
    if (!buf) return -1;
    int rc = pfm ? decode_pfm(buf, len, img) : decode_ppm(buf, len, img);
    free(buf);
    if (rc) snprintf(err, err_len, "%s: not a valid %s file (bad header or size)", path, pfm ? "PFM" : "binary PPM");
    return rc;
}
