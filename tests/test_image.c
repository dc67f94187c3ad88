/* test_image.c - PFM/PPM round trips, orientation, Reinhard, atomic writes. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "image/image.h"
#include "image/image_compare.h"
#include "harness.h"
#include "util.h"

static void fill_test_image(image *img) {
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            for (int c = 0; c < 3; c++) img->rgb[3 * (y * img->width + x) + c] = (float)(x * 0.37 + y * 1.1 + c) / 7.0f;
    img->rgb[0] = 5.0f; /* top-left red corner: proves which way is up */
    img->rgb[1] = img->rgb[2] = 0.0f;
}

TEST(image_pfm_round_trip_bit_exact) {
    image a, b;
    char err[256];
    CHECK(image_alloc(&a, 7, 5) == 0, "alloc");
    fill_test_image(&a);
    image_write_options wo = {0};
    CHECK(image_write(util_temp_path("rt.pfm"), &a, &wo, err, sizeof err) == 0, "%s", err);
    CHECK(image_read(util_temp_path("rt.pfm"), &b, err, sizeof err) == 0, "%s", err);
    if (b.rgb) {
        CHECK(b.width == 7 && b.height == 5, "size %dx%d", b.width, b.height);
        CHECK(memcmp(a.rgb, b.rgb, sizeof(float) * 3 * 35) == 0, "pixels differ");
    }
    /* The file stores rows bottom-up: the last row in the file is our row 0. */
    FILE *f = fopen(util_temp_path("rt.pfm"), "rb");
    fseek(f, -7 * 12, SEEK_END);
    float first;
    CHECK(fread(&first, 4, 1, f) == 1 && first == 5.0f, "row 0 is not stored last");
    fclose(f);
    image_free(&a);
    image_free(&b);
}

TEST(image_ppm_round_trip) {
    image a, b;
    char err[256];
    image_alloc(&a, 4, 3);
    for (int i = 0; i < 36; i++) a.rgb[i] = (float)i / 40.0f;
    image_write_options wo = {.tonemap = {.kind = TONEMAP_CLAMP}};
    CHECK(image_write(util_temp_path("rt.ppm"), &a, &wo, err, sizeof err) == 0, "%s", err);
    CHECK(image_read(util_temp_path("rt.ppm"), &b, err, sizeof err) == 0, "%s", err);
    for (int i = 0; b.rgb && i < 36; i++)
        CHECK(fabsf(a.rgb[i] - b.rgb[i]) < 0.01f, "pixel value %d: %g vs %g", i, a.rgb[i], b.rgb[i]);
    image_free(&a);
    image_free(&b);
}

TEST(tonemap_reinhard_values) {
    CHECK(tonemap_reinhard(0) == 0, "0 maps to 0");
    CHECK(fabsf(tonemap_reinhard(1) - 0.5f) < 1e-7f, "1 maps to 1/2");
    CHECK(tonemap_reinhard(-3) == 0, "negative maps to 0");
    CHECK(tonemap_reinhard(1e30f) <= 1.0f, "huge stays <= 1");
    float prev = 0;
    for (int i = 1; i < 1000; i++) {
        float v = tonemap_reinhard(i * 0.05f);
        CHECK(v > prev, "not monotonic at %d", i);
        prev = v;
    }
    float px[] = {0, 0, 0, NAN, 1, 1, INFINITY, 0, 0, 1e30f, 1e30f, 1e30f, 0.5f, 0.5f, 0.5f};
    uint8_t out[15];
    tonemap_options o = {.kind = TONEMAP_REINHARD};
    size_t bad = tonemap_to_8bit(px, 5, &o, out);
    CHECK(bad == 2, "want 2 NaN/Inf pixels counted, got %zu", bad);
    CHECK(out[0] == 0 && out[3] == 0 && out[6] == 0, "black, NaN and Inf pixels must be black");
    CHECK(out[9] == 255, "huge radiance must map to white, got %d", out[9]);
    /* grey 0.5 -> L/(1+L) = 1/3 -> sRGB(1/3) = 0.6132 -> 156 */
    CHECK(out[12] == 156, "grey 0.5 maps to %d, want 156", out[12]);
}

TEST(image_write_is_atomic) {
    image a;
    char err[256];
    image_alloc(&a, 2, 2);
    image_write_options wo = {0};
    CHECK(image_write("/tmp/no-such-dir-tessera/x.pfm", &a, &wo, err, sizeof err) != 0, "write into a missing folder");
    CHECK(strstr(err, "/tmp/no-such-dir-tessera/x.pfm") && strstr(err, "No such file"), "message: %s", err);
    if (geteuid() != 0) { /* root ignores permissions */
        system("mkdir -p /tmp/tessera-ro && chmod 555 /tmp/tessera-ro");
        CHECK(image_write("/tmp/tessera-ro/x.pfm", &a, &wo, err, sizeof err) != 0, "write into a read-only folder");
    }
    CHECK(image_write("/tmp/x.tga", &a, &wo, err, sizeof err) != 0 && strstr(err, "known: .pfm .exr .ppm .png .jpg .jpeg"), "%s", err);
    FILE *ls = popen("ls /tmp/no-such-dir-tessera /tmp/tessera-ro 2>/dev/null | grep -c tmp", "r");
    char buf[16] = "";
    CHECK(fgets(buf, sizeof buf, ls) && atoi(buf) == 0, "a temporary file was left behind");
    pclose(ls);
    image_free(&a);
}

#include <jpeglib.h>
#include <png.h>

/* PNG and JPEG: decoded by libpng and libjpeg, the image has the right size,
 * the red corner is at the top left, and values match the tone-mapped input. */
TEST(image_png_and_jpeg_decode) {
    image a;
    char err[256];
    image_alloc(&a, 40, 30);
    for (int i = 0; i < 40 * 30 * 3; i++) a.rgb[i] = 0.2f;
    for (int y = 0; y < 8; y++)
        for (int x = 0; x < 8; x++) { /* saturated red block, top left */
            float *p = a.rgb + 3 * (y * 40 + x);
            p[0] = 1e6f, p[1] = 0, p[2] = 0;
        }
    image_write_options wo = {.tonemap = {.kind = TONEMAP_CLAMP}};
    CHECK(image_write(util_temp_path("t.png"), &a, &wo, err, sizeof err) == 0, "%s", err);
    png_image pi;
    memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    CHECK(png_image_begin_read_from_file(&pi, util_temp_path("t.png")), "libpng cannot read it");
    pi.format = PNG_FORMAT_RGB;
    uint8_t *buf = malloc(PNG_IMAGE_SIZE(pi));
    CHECK(png_image_finish_read(&pi, NULL, buf, 0, NULL), "libpng decode failed");
    CHECK(pi.width == 40 && pi.height == 30, "PNG size %ux%u", pi.width, pi.height);
    CHECK(buf[0] == 255 && buf[1] == 0 && buf[2] == 0, "PNG top-left not red: %d %d %d", buf[0], buf[1], buf[2]);
    uint8_t grey = (uint8_t)lrintf(tonemap_srgb_encode(0.2f) * 255);
    size_t last = 3 * (40 * 30 - 1);
    CHECK(buf[last] == grey, "PNG bottom-right %d, want %d", buf[last], grey);
    free(buf);

    wo.jpeg_quality = 95;
    CHECK(image_write(util_temp_path("t.jpg"), &a, &wo, err, sizeof err) == 0, "%s", err);
    FILE *f = fopen(util_temp_path("t.jpg"), "rb");
    struct jpeg_decompress_struct d;
    struct jpeg_error_mgr jerr;
    d.err = jpeg_std_error(&jerr);
    jpeg_create_decompress(&d);
    jpeg_stdio_src(&d, f);
    jpeg_read_header(&d, TRUE);
    jpeg_start_decompress(&d);
    CHECK(d.output_width == 40 && d.output_height == 30 && d.output_components == 3, "JPEG size/components");
    uint8_t row[40 * 3];
    JSAMPROW rp = row;
    jpeg_read_scanlines(&d, &rp, 1);
    CHECK(row[3 * 2] > 230 && row[3 * 2 + 1] < 30 && row[3 * 2 + 2] < 30, "JPEG top-left not red: %d %d %d", row[6], row[7], row[8]);
    CHECK(abs(row[3 * 39] - grey) <= 3, "JPEG top-right %d, want about %d", row[3 * 39], grey);
    while (d.output_scanline < d.output_height) jpeg_read_scanlines(&d, &rp, 1);
    jpeg_finish_decompress(&d);
    jpeg_destroy_decompress(&d);
    fclose(f);
    image_free(&a);
}

/* EXR: the header as read by OpenEXR's own exrheader (Debian `openexr`):
 * size, windows, float RGB channels, compression, our attributes. */
TEST(image_exr_header_read_by_exrheader) {
    image a;
    char err[256], out[8192];
    image_alloc(&a, 40, 30);
    a.rgb[0] = 5.0f;
    codec_attribute attrs[] = {{"tessera:spp", "64"}, {"tessera:scene", "test.json"}};
    const char *names[] = {"zip", "piz", "none"};
    for (int c = 0; c < 3; c++) {
        image_write_options wo = {.exr = {.compression = (codec_exr_compression)c, .attrs = attrs, .attr_count = 2}};
        CHECK(image_write(util_temp_path("t.exr"), &a, &wo, err, sizeof err) == 0, "%s", err);
        char hdr_cmd[600];
        snprintf(hdr_cmd, sizeof hdr_cmd, "exrheader %s 2>&1", util_temp_path("t.exr"));
        FILE *p = popen(hdr_cmd, "r");
        size_t n = p ? fread(out, 1, sizeof out - 1, p) : 0;
        out[n] = '\0';
        int st = p ? pclose(p) : -1;
        CHECK(st == 0, "exrheader failed (%d): %s", st, out);
        CHECK(strstr(out, "dataWindow (type box2i): (0 0) - (39 29)") && strstr(out, "displayWindow (type box2i): (0 0) - (39 29)"),
              "windows wrong: %s", out);
        CHECK(strstr(out, "R, 32-bit floating-point") && strstr(out, "G, 32-bit floating-point") &&
                  strstr(out, "B, 32-bit floating-point"), "channels wrong: %s", out);
        char want[64];
        snprintf(want, sizeof want, "compression (type compression): %s", names[c]);
        CHECK(strstr(out, want) != NULL, "want \"%s\" in: %s", want, out);
        CHECK(strstr(out, "tessera:spp (type string): \"64\"") && strstr(out, "tessera:scene (type string): \"test.json\""),
              "attributes missing: %s", out);
    }
    image_free(&a);
}

TEST(tonemap_operators_known_values) {
    CHECK(fabsf(tonemap_reinhard_extended(4.0f, 4.0f) - 1.0f) < 1e-6f, "the white point must map to 1");
    CHECK(tonemap_reinhard_extended(0.0f, 4.0f) == 0.0f && tonemap_aces(0.0f) == 0.0f, "0 maps to 0");
    CHECK(tonemap_aces(1e30f) == 1.0f && tonemap_aces(-1.0f) == 0.0f && tonemap_aces(NAN) == 0.0f, "ACES bounds");
    float pe = 0, pa = 0;
    for (int i = 1; i < 400; i++) {
        float L = i * 0.01f, e = tonemap_reinhard_extended(L, 4.0f), a = tonemap_aces(L);
        CHECK(e > pe && a >= pa, "not monotonic at L=%g", L);
        pe = e, pa = a;
    }
    tonemap_kind k;
    CHECK(tonemap_parse("photographic", &k) == 0 && k == TONEMAP_PHOTOGRAPHIC, "parse photographic");
    CHECK(tonemap_parse("filmic", &k) != 0, "unknown names are refused");
}

/* The photographic operator normalises exposure: a grey image of any
 * brightness maps to the same bytes (key 0.18 of its log-average). */
TEST(tonemap_photographic_auto_exposure) {
    float dim[12], bright[12];
    for (int i = 0; i < 12; i++) dim[i] = 0.01f, bright[i] = 100.0f;
    dim[0] = dim[1] = dim[2] = 0.02f; /* a white point above the grey */
    bright[0] = bright[1] = bright[2] = 200.0f;
    uint8_t a[12], b[12];
    tonemap_options o = {.kind = TONEMAP_PHOTOGRAPHIC};
    tonemap_to_8bit(dim, 4, &o, a);
    tonemap_to_8bit(bright, 4, &o, b);
    CHECK(memcmp(a, b, 12) == 0, "grey %d vs %d", a[3], b[3]);
    CHECK(a[0] == 255, "the brightest pixel is the white point: %d", a[0]);
}

TEST(cli_tonemap_matches_render) {
    char cmd[4096], out[4096], dir[128];
    const char *t = harness_tessera();
    snprintf(dir, sizeof dir, "%.120s", util_temp_path("")); /* this run's own folder, not one shared with other runs */
    /* From an EXR, which carries the render's tessera:* header, the PNG is
     * the same bytes, tEXt chunks included; from a PFM, the same pixels. */
    snprintf(cmd, sizeof cmd,
             "%s render tests/scenes/cornell-small.json --spp 2 -o %stm.exr && "
             "%s render tests/scenes/cornell-small.json --spp 2 --tonemap photographic -o %stm1.png && "
             "%s tonemap %stm.exr --tonemap photographic -o %stm2.png && cmp %stm1.png %stm2.png && "
             "%s render tests/scenes/cornell-small.json --spp 2 -o %stm.pfm && "
             "%s tonemap %stm.pfm --tonemap photographic -o %stm3.png && "
             "idiff -fail 0 -failpercent 0 %stm1.png %stm3.png", t, dir, t, dir, t, dir, dir, dir, dir, t, dir, t, dir,
             dir, dir, dir);
    CHECK(util_run(cmd, out, sizeof out) == 0, "re-tone-mapping differs from rendering: %s", out);
    snprintf(cmd, sizeof cmd, "iinfo -v %stm2.png", dir);
    CHECK(util_run(cmd, out, sizeof out) == 0 && strstr(out, "tessera:scene: \"tests/scenes/cornell-small.json\""),
          "tonemap dropped the EXR's header: %s", out);
    snprintf(cmd, sizeof cmd, "%s tonemap %stm.pfm --tonemap sepia -o %sx.png", t, dir, dir);
    CHECK(util_run(cmd, out, sizeof out) == 2 && strstr(out, "unknown operator \"sepia\""), "bad operator: %s", out);
    snprintf(cmd, sizeof cmd, "%s tonemap /tmp/nothing-tessera.pfm -o %sx.png", t, dir);
    CHECK(util_run(cmd, out, sizeof out) == 1 && strstr(out, "/tmp/nothing-tessera.pfm: cannot open"),
          "missing input: %s", out);
}

/* EXR: every compression round-trips bit for bit through our reader;
 * garbage is refused with the file named. */
TEST(image_exr_round_trip_bit_exact) {
    image a, b;
    char err[256];
    image_alloc(&a, 37, 23);
    fill_test_image(&a);
    a.rgb[5] = 1e-30f; /* a denormal-range value and a huge one */
    a.rgb[8] = 3e38f;
    for (int c = 0; c < 3; c++) {
        image_write_options wo = {.exr = {.compression = (codec_exr_compression)c}};
        CHECK(image_write(util_temp_path("rt.exr"), &a, &wo, err, sizeof err) == 0, "%s", err);
        CHECK(image_read(util_temp_path("rt.exr"), &b, err, sizeof err) == 0, "compression %d: %s", c, err);
        if (!b.rgb) continue;
        CHECK(b.width == 37 && b.height == 23, "size %dx%d", b.width, b.height);
        CHECK(memcmp(a.rgb, b.rgb, sizeof(float) * 3 * 37 * 23) == 0, "compression %d: pixels differ", c);
        image_free(&b);
    }
    FILE *f = fopen(util_temp_path("bad.exr"), "w");
    fputs("this is not an EXR file", f);
    fclose(f);
    CHECK(image_read(util_temp_path("bad.exr"), &b, err, sizeof err) != 0 && strstr(err, "bad.exr: not a readable OpenEXR"),
          "garbage accepted or unclear: %s", err);
    image_free(&a);
}

/* Half EXR with alpha: values within half precision, A = 1 (exrheader). */
TEST(image_exr_half_and_alpha) {
    image a, b;
    char err[256], out[4096];
    image_alloc(&a, 16, 9);
    fill_test_image(&a);
    image_write_options wo = {.exr = {.half = 1, .alpha = 1}};
    CHECK(image_write(util_temp_path("half.exr"), &a, &wo, err, sizeof err) == 0, "%s", err);
    CHECK(image_read(util_temp_path("half.exr"), &b, err, sizeof err) == 0, "%s", err);
    for (int i = 0; b.rgb && i < 16 * 9 * 3; i++)
        CHECK(fabsf(a.rgb[i] - b.rgb[i]) <= fabsf(a.rgb[i]) * 0x1p-11f + 1e-7f, "pixel value %d: %g vs %g", i, a.rgb[i], b.rgb[i]);
    char hdr_cmd[600];
    snprintf(hdr_cmd, sizeof hdr_cmd, "exrheader %s", util_temp_path("half.exr"));
    CHECK(util_run(hdr_cmd, out, sizeof out) == 0 && strstr(out, "A, 16-bit floating-point") &&
              strstr(out, "R, 16-bit floating-point"), "channels: %s", out);
    image_free(&a);
    image_free(&b);
}

/* Every format we write is read by OpenImageIO (iinfo, oiiotool; Debian
 * openimageio-tools) with the right size, and its top-left pixel, cut out by
 * oiiotool, is the red corner: the right way up. */
TEST(image_formats_read_by_openimageio) {
    image a;
    char err[256], out[4096], cmd[1400];
    image_alloc(&a, 40, 30);
    for (int i = 0; i < 40 * 30 * 3; i++) a.rgb[i] = 0.1f;
    for (int y = 0; y < 6; y++)
        for (int x = 0; x < 6; x++) {
            float *p = a.rgb + 3 * (y * 40 + x);
            p[0] = 4.0f, p[1] = 0.0f, p[2] = 0.0f;
        }
    const char *exts[] = {"exr", "pfm", "png", "ppm", "jpg"};
    for (int e = 0; e < 5; e++) {
        char path[600], px_path[600], name[32];
        snprintf(name, sizeof name, "oiio.%s", exts[e]);
        snprintf(path, sizeof path, "%s", util_temp_path(name));
        snprintf(px_path, sizeof px_path, "%s", util_temp_path("oiio-px.exr"));
        image_write_options wo = {.tonemap = {.kind = TONEMAP_CLAMP}, .jpeg_quality = 95};
        CHECK(image_write(path, &a, &wo, err, sizeof err) == 0, "%s", err);
        snprintf(cmd, sizeof cmd, "iinfo %s", path);
        CHECK(util_run(cmd, out, sizeof out) == 0 && strstr(out, "40 x   30"), "iinfo on .%s: %s", exts[e], out);
        snprintf(cmd, sizeof cmd, "oiiotool %s --cut 1x1+2+2 -d float -o %s", path, px_path);
        CHECK(util_run(cmd, out, sizeof out) == 0, "oiiotool on .%s: %s", exts[e], out);
        image px;
        if (image_read(px_path, &px, err, sizeof err) == 0) {
            CHECK(px.rgb[0] > 0.9f && px.rgb[1] < 0.05f && px.rgb[2] < 0.05f, ".%s: top-left pixel (%g, %g, %g) is not red",
                  exts[e], px.rgb[0], px.rgb[1], px.rgb[2]);
            image_free(&px);
        } else {
            CHECK(0, "%s", err);
        }
    }
    char exr_path[600];
    snprintf(exr_path, sizeof exr_path, "%s", util_temp_path("oiio.exr"));
    snprintf(cmd, sizeof cmd, "idiff %s %s", exr_path, util_temp_path("oiio.pfm"));
    CHECK(util_run(cmd, out, sizeof out) == 0 && strstr(out, "PASS"), "idiff: EXR and PFM differ: %s", out);
    image_free(&a);
}

/* 16-bit PNG: OpenImageIO reads uint16 RGB tagged sRGB, and the value is the
 * sRGB encoding of the input to 16-bit precision. */
TEST(image_png16) {
    image a, px;
    char err[256], out[4096];
    image_alloc(&a, 8, 4);
    for (int i = 0; i < 8 * 4 * 3; i++) a.rgb[i] = 0.3f;
    image_write_options wo = {.tonemap = {.kind = TONEMAP_CLAMP}, .png16 = 1};
    char png[600], px_exr[600], cmd[1400];
    snprintf(png, sizeof png, "%s", util_temp_path("16.png"));
    snprintf(px_exr, sizeof px_exr, "%s", util_temp_path("16px.exr"));
    CHECK(image_write(png, &a, &wo, err, sizeof err) == 0, "%s", err);
    snprintf(cmd, sizeof cmd, "iinfo -v %s", png);
    CHECK(util_run(cmd, out, sizeof out) == 0 && strstr(out, "8 x    4, 3 channel, uint16 png") &&
              strstr(out, "sRGB"), "iinfo: %s", out);
    snprintf(cmd, sizeof cmd, "oiiotool %s --cut 1x1+3+2 -d float -o %s", png, px_exr);
    CHECK(util_run(cmd, out, sizeof out) == 0, "%s", out);
    if (image_read(px_exr, &px, err, sizeof err) == 0) {
        float want = (float)lrintf(tonemap_srgb_encode(0.3f) * 65535.0f) / 65535.0f;
        CHECK(fabsf(px.rgb[0] - want) < 1e-6f, "16-bit value %.7f, want %.7f", px.rgb[0], want);
        image_free(&px);
    } else {
        CHECK(0, "%s", err);
    }
    image_free(&a);
}

/* The benchmark's error measures on images with known answers. */
TEST(image_compare_measures) {
    image a, r;
    image_error e;
    image_alloc(&a, 2, 1);
    image_alloc(&r, 2, 1);
    for (int i = 0; i < 6; i++) r.rgb[i] = 1.0f;
    CHECK(image_compare(&a, &a, &e) == 0 && e.rmse == 0 && e.relmse == 0 && e.max_abs == 0, "self-compare not 0");
    for (int i = 0; i < 6; i++) a.rgb[i] = 1.5f; /* off by 0.5 everywhere */
    CHECK(image_compare(&a, &r, &e) == 0 && fabs(e.rmse - 0.5) < 1e-12 && fabs(e.relmse - 0.25 / 1.01) < 1e-12 &&
              fabs(e.max_abs - 0.5) < 1e-12,
          "rmse %g relmse %g max %g", e.rmse, e.relmse, e.max_abs);
    a.rgb[0] = NAN;
    CHECK(image_compare(&a, &r, &e) == 0 && e.nonfinite == 1 && fabs(e.rmse - 0.5) < 1e-12, "NaN not set apart");
    image b;
    image_alloc(&b, 1, 2);
    CHECK(image_compare(&b, &r, &e) == -1, "sizes differ but compared");
    image_free(&a);
    image_free(&r);
    image_free(&b);
    char cmd[1024], out[4096];
    snprintf(cmd, sizeof cmd, "%s render tests/scenes/cornell-small.json --workers 0 --spp 4 -o /tmp/tessera-cmp.pfm "
             ">/dev/null && %s compare /tmp/tessera-cmp.pfm /tmp/tessera-cmp.pfm", harness_tessera(), harness_tessera());
    CHECK(util_run(cmd, out, sizeof out) == 0 && strstr(out, "rmse 0 relmse 0 max 0 nonfinite 0"), "cli: %s", out);
}
