/* test_gltf.c - models (render/import.h): glTF and OBJ + MTL through the
 * importer, refusals of bad files, textures (decoding, limits, sRGB, wrap
 * modes, orientation), shading with textures and the same bytes from any
 * farm layout. Scenes from scenes/gltf (bench/gltf/make_scenes.py). */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/types.h>
#include <unistd.h>

#include "image/image_codecs.h"
#include "render/import.h"
#include "render/model_files.h"
#include "render/punctual.h"
#include "render/scene.h"
#include "render/texture.h"
#include "harness.h"
#include "util.h"

/* A one-triangle glTF with an embedded buffer; the parts a test changes
 * are parameters. */
#define TRI_DATA "data:application/octet-stream;base64,AACAvwAAgL8AAAAAAACAPwAAgL8AAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="
#define TRI_BAD_INDEX "data:application/octet-stream;base64,AACAvwAAgL8AAAAAAACAPwAAgL8AAAAAAAAAAAAAgD8AAAAAAAABAAcAAAA="

static const char *tri_gltf(const char *name, const char *top, int mode, const char *material, const char *textures,
                            const char *buffer_uri, int index_type, int position_type) {
    static char text[8192];
    snprintf(text, sizeof text,
             "{\"asset\": {\"version\": \"2.0\"}, %s \"scenes\": [{\"nodes\": [0]}], \"nodes\": [{\"mesh\": 0}],"
             " \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0}, \"indices\": 1, \"mode\": %d,"
             " \"material\": 0}]}], \"materials\": [{%s}], %s"
             " \"buffers\": [{\"byteLength\": 44, \"uri\": \"%s\"}],"
             " \"bufferViews\": [{\"buffer\": 0, \"byteOffset\": 0, \"byteLength\": 36},"
             "                   {\"buffer\": 0, \"byteOffset\": 36, \"byteLength\": 6}],"
             " \"accessors\": [{\"bufferView\": 0, \"componentType\": %d, \"count\": 3, \"type\": \"VEC3\","
             "                  \"min\": [-1, -1, 0], \"max\": [1, 1, 0]},"
             "                 {\"bufferView\": 1, \"componentType\": %d, \"count\": 3, \"type\": \"SCALAR\"}]}",
             top, mode, material, textures, buffer_uri, position_type, index_type);
    return util_write_temp(name, text);
}

static const char *good(const char *name) { return tri_gltf(name, "", 4, "", "", TRI_DATA, 5123, 5126); }

/* Load path; return the error ("" on success, the scene freed). */
static const char *load_error(const char *path) {
    static char err[1024];
    err[0] = '\0';
    scene *s = scene_load(path, NULL, err, sizeof err);
    if (s) {
        scene_free(s);
        err[0] = '\0';
    }
    return err;
}

static void write_bytes(const char *name, const void *data, size_t len) {
    FILE *f = fopen(util_temp_path(name), "wb");
    if (f) {
        fwrite(data, 1, len, f);
        fclose(f);
    }
}

TEST(gltf_minimal_loads_with_a_default_camera_and_sky) {
    char err[1024];
    scene *s = scene_load(good("tri.gltf"), NULL, err, sizeof err);
    CHECK(s, "a valid one-triangle glTF was refused: %s", err);
    if (!s) return;
    CHECK(s->triangle_count == 1, "%u triangles", s->triangle_count);
    CHECK(s->materials[s->triangle_info[0].material].kind == MATERIAL_PBR, "not the glTF material");
    CHECK(s->features & FEATURE_BACKGROUND, "a model without lights gets a sky");
    CHECK(s->cam.kind == CAMERA_PERSPECTIVE && s->cam.forward.z < 0, "automatic camera looks at the model from +z");
    scene_free(s);
}

TEST(gltf_bad_files_are_refused_naming_the_fault) {
    static const struct {
        const char *top, *material, *textures, *uri;
        int mode, index_type, position_type;
        const char *want; /* substring of the message */
    } cases[] = {
        {"", "", "", TRI_BAD_INDEX, 4, 5123, 5126, "bad.gltf"},            /* index out of range */
        {"", "", "", TRI_DATA, 4, 5126, 5126, "accessors[1]"},            /* float indices overrun */
        {"", "", "", TRI_DATA, 4, 5123, 5121, "attributes.POSITION"},     /* byte positions */
        {"", "", "", "nothere.bin", 4, 5123, 5126, "nothere.bin"},         /* missing buffer */
        {"\"extensionsRequired\": [\"EXT_foo_bar\", \"KHR_materials_ior\"], \"extensionsUsed\": [\"EXT_foo_bar\"],",
         "", "", TRI_DATA, 4, 5123, 5126, "unsupported extensions marked required: EXT_foo_bar"},
        {"\"extensionsRequired\": [\"KHR_draco_mesh_compression\"],", "", "", TRI_DATA, 4, 5123, 5126, "Draco"},
        {"", "", "", TRI_DATA, 0, 5123, 5126, "no triangles"}, /* points */
        {"", "", "", TRI_DATA, 1, 5123, 5126, "no triangles"}, /* lines */
        {"", "\"pbrMetallicRoughness\": {\"baseColorTexture\": {\"index\": 0}}",
         "\"textures\": [{\"source\": 0}], \"images\": [{\"uri\": \"missing.png\"}],", TRI_DATA, 4, 5123, 5126,
         "missing.png"},
        {"", "\"pbrMetallicRoughness\": {\"baseColorTexture\": {\"index\": 0}}",
         "\"textures\": [{\"source\": 0}], \"images\": [{\"uri\": \"huge.png\"}],", TRI_DATA, 4, 5123, 5126,
         "50000x50000"},
        {"", "\"pbrMetallicRoughness\": {\"baseColorTexture\": {\"index\": 3}}", "", TRI_DATA, 4, 5123, 5126,
         "textures"},
    };
    /* A PNG whose header declares 50000 x 50000 (10 GB of RGBA). */
    static const unsigned char huge[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R',
                                         0, 0, 0xc3, 0x50, 0, 0, 0xc3, 0x50, 8, 6, 0, 0, 0, 0x4b, 0xaf, 0x3d, 0xca,
                                         0x00, 0x00, 0x00, 0x00, 'I', 'D', 'A', 'T', 0x35, 0xaf, 0x06, 0x1e,
                                         0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82};
    write_bytes("huge.png", huge, sizeof huge);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *path = tri_gltf("bad.gltf", cases[i].top, cases[i].mode, cases[i].material, cases[i].textures,
                                    cases[i].uri, cases[i].index_type, cases[i].position_type);
        const char *err = load_error(path);
        CHECK(err[0] && strstr(err, cases[i].want), "case %zu: want an error with \"%s\", got \"%s\"", i,
              cases[i].want, err);
    }
    /* A model whose face reaches beyond the scene's bound (SCENE_COORD_MAX)
     * is refused naming the mesh, axis and coordinate, not called "not
     * finite". */
    static const char far_obj[] = "v 0 0 0\nv 1 0 0\nv 0 3e31 0\nf 1 2 3\n";
    write_bytes("far.obj", far_obj, sizeof far_obj - 1);
    const char *far_err = load_error(util_temp_path("far.obj"));
    CHECK(strstr(far_err, "a face's vertex lies at y = 3e+31, beyond +-1e+30 (after the file's transforms)"),
          "a model with a vertex at 3e31: got \"%s\"", far_err);
    /* A data: URI whose header (before the comma) Assimp 5.2 would misread,
     * leaking inside it (found by fuzz_gltf; import.c check_data_uris):
     * read up to 126 characters, refused from 127 naming the field. */
    for (int n = 126; n <= 127; n++) {
        char uri[512], pad[200];
        const char *tail = strchr(TRI_DATA, ';'); /* ";base64,..." */
        int np = n - (int)strlen("data:application/") - (int)strlen(";base64");
        memset(pad, 'x', (size_t)np);
        snprintf(uri, sizeof uri, "data:application/%.*s%s", np, pad, tail);
        const char *err = load_error(tri_gltf("long-uri.gltf", "", 4, "", "", uri, 5123, 5126));
        if (n == 126)
            CHECK(!err[0], "a data: URI with a %d-character header was refused: %s", n, err);
        else
            CHECK(strstr(err, "buffers[0].uri") && strstr(err, "127 characters"),
                  "a data: URI with a %d-character header: want an error naming buffers[0].uri, got \"%s\"", n, err);
    }
    /* A base64 payload with bytes that are not base64 after its padding (on
     * bytes past 0x7f there Assimp 5.2 leaked; found by fuzz_gltf) or
     * before it: refused, naming the field and the byte. */
    static const char *const tails[] = {"\xff\xff", "AB", "="};
    for (int k = 0; k < 4; k++) {
        char uri[512];
        if (k < 3) snprintf(uri, sizeof uri, "%s%s", TRI_DATA, tails[k]); /* ...=\xff\xff, ...=AB, ...== (61 chars) */
        else snprintf(uri, sizeof uri, "%s", TRI_DATA), uri[strlen(uri) - 5] = '*';
        const char *err = load_error(tri_gltf("bad-base64.gltf", "", 4, "", "", uri, 5123, 5126));
        CHECK(strstr(err, "buffers[0].uri: the data: URI's base64 is not base64 from its byte"),
              "payload %d: want an error naming buffers[0].uri, got \"%s\"", k, err);
    }
    /* Not glTF 2. */
    util_write_temp("v1.gltf", "{\"asset\": {\"version\": \"1.0\"}}");
    CHECK(strstr(load_error(util_temp_path("v1.gltf")), "only glTF 2"), "glTF 1 accepted");
}

TEST(gltf_truncated_glb_is_refused) {
    size_t len;
    char err[256];
    FILE *f = fopen("scenes/gltf/suzanne.glb", "rb");
    CHECK(f, "scenes/gltf/suzanne.glb missing");
    if (!f) return;
    static char buf[1 << 20];
    len = fread(buf, 1, sizeof buf, f);
    fclose(f);
    const size_t cuts[] = {5, 19, 100, 5000, len - 1};
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        write_bytes("cut.glb", buf, cuts[i]);
        const char *e = load_error(util_temp_path("cut.glb"));
        CHECK(strstr(e, "cut.glb") && (strstr(e, "truncated") || strstr(e, "not a binary glTF")),
              "cut at %zu: \"%s\"", cuts[i], e);
    }
    (void)err;
}

TEST(gltf_texture_decode_limits_srgb_and_wrap) {
    size_t len;
    char err[512];
    FILE *f = fopen("scenes/gltf/arrow.png", "rb");
    CHECK(f, "scenes/gltf/arrow.png missing");
    if (!f) return;
    static uint8_t png[65536];
    len = fread(png, 1, sizeof png, f);
    fclose(f);
    texture t;
    CHECK(texture_decode(png, len, "arrow.png", &t, err, sizeof err) == 0, "%s", err);
    CHECK(t.width == 64 && t.height == 64, "%dx%d", t.width, t.height);
    t.srgb = 1;
    /* glTF orientation: v = 0 is the first row (the arrow's tip). */
    texel tip = texture_lookup(&t, 0.5f, 0.2f), corner = texture_lookup(&t, 0.9f, 0.9f), bl = texture_lookup(&t, 0.1f, 0.9f);
    CHECK(tip.rgb.x > 0.5f && tip.rgb.z < 0.1f, "(0.5, 0.2) should be the red arrow: %g %g %g", tip.rgb.x, tip.rgb.y, tip.rgb.z);
    CHECK(corner.rgb.z > 0.5f && corner.rgb.x < 0.1f, "(0.9, 0.9) should be the blue square");
    CHECK(bl.rgb.x > 0.9f && bl.rgb.z > 0.9f, "(0.1, 0.9) should be white");
    /* Wrap modes. */
    texel r = texture_lookup(&t, 1.9f, -0.1f);
    CHECK(fabsf(r.rgb.z - corner.rgb.z) < 1e-6f, "repeat: (1.9, -0.1) is (0.9, 0.9)");
    t.wrap_s = t.wrap_t = WRAP_MIRROR;
    texel m = texture_lookup(&t, 1.1f, 1.1f);
    CHECK(fabsf(m.rgb.z - corner.rgb.z) < 1e-6f && fabsf(m.rgb.x - corner.rgb.x) < 1e-6f, "mirror: (1.1, 1.1) is (0.9, 0.9)");
    t.wrap_s = t.wrap_t = WRAP_CLAMP;
    texel c = texture_lookup(&t, 7.0f, 7.0f), c0 = texture_lookup(&t, -3.0f, -3.0f);
    CHECK(c.rgb.z > 0.5f && c0.rgb.x > 0.9f, "clamp: far corners are the corner texels");
    /* sRGB: 8-bit values decode through the sRGB curve; data textures not. */
    CHECK(texture_srgb_to_linear(255) == 1.0f && texture_srgb_to_linear(0) == 0.0f, "sRGB end points");
    CHECK(fabsf(texture_srgb_to_linear(188) - 0.50289f) < 1e-4f, "sRGB 188 -> %g", texture_srgb_to_linear(188));
    t.srgb = 0;
    t.wrap_s = t.wrap_t = WRAP_REPEAT;
    texel lin = texture_lookup(&t, 0.9f, 0.9f);
    CHECK(fabsf(lin.rgb.z - 220 / 255.0f) < 1e-5f, "linear data texture: %g", lin.rgb.z);
    /* Bilinear: halfway between two texel centres is their mean. */
    texel a = texture_lookup(&t, 47.5f / 64, 60.5f / 64), b = texture_lookup(&t, 48.5f / 64, 60.5f / 64),
          mid = texture_lookup(&t, 48.0f / 64, 60.5f / 64);
    CHECK(fabsf(mid.rgb.x - 0.5f * (a.rgb.x + b.rgb.x)) < 1e-5f, "bilinear midpoint %g vs %g %g", mid.rgb.x, a.rgb.x, b.rgb.x);
    texture_free(&t);
    /* A JPEG whose frame header claims 50000 x 50000 is refused before decoding. */
    uint8_t rgb[8 * 8 * 3];
    memset(rgb, 128, sizeof rgb);
    size_t jl;
    uint8_t *jpg = codec_jpeg_encode(rgb, 8, 8, 90, &jl, err, sizeof err);
    CHECK(jpg, "%s", err);
    for (size_t i = 0; jpg && i + 9 < jl; i++)
        if (jpg[i] == 0xff && jpg[i + 1] == 0xc0) {
            jpg[i + 5] = 0xc3, jpg[i + 6] = 0x50, jpg[i + 7] = 0xc3, jpg[i + 8] = 0x50;
            break;
        }
    CHECK(jpg && texture_decode(jpg, jl, "big.jpg", &t, err, sizeof err) == -1 && strstr(err, "50000x50000"),
          "big JPEG: %s", err);
    free(jpg);
    /* A JPEG cut after its headers: libjpeg's fatal error comes back as a
     * message (jpeg_guard), not an exit of the process. */
    jpg = codec_jpeg_encode(rgb, 8, 8, 90, &jl, err, sizeof err);
    CHECK(jpg && texture_decode(jpg, 20, "cut.jpg", &t, err, sizeof err) == -1 && strstr(err, "cut.jpg: bad JPEG: "),
          "truncated JPEG: %s", err);
    free(jpg);
    CHECK(texture_decode((const uint8_t *)"GIF89a", 6, "x.gif", &t, err, sizeof err) == -1 && strstr(err, "not a PNG"),
          "GIF: %s", err);
}

/* The arrow texture on a plane facing the camera appears as in the file:
 * arrow up, blue square bottom right (UV orientation end to end). */
TEST(gltf_textured_plane_shows_the_arrow_the_right_way) {
    char err[1024];
    scene_overrides ov = {.width = 64, .height = 48, .spp = 16, .max_depth = -1};
    scene *s = scene_load("scenes/gltf/arrow-plane.gltf", &ov, err, sizeof err);
    CHECK(s, "%s", err);
    if (!s) return;
    CHECK(s->settings.width == 64 && s->settings.height == 48, "%dx%d", s->settings.width, s->settings.height);
    trace_stats st;
    float *img = util_render(s, 2, 16, 1, &st);
#define PX(x, y) (&img[3 * ((y) * 64 + (x))])
    /* The plane covers x 10..54, y 2..46 (camera and plane as exported). */
    const float *blue = PX(49, 41), *white = PX(15, 41), *red = PX(32, 15), *top_white = PX(15, 8);
    CHECK(blue[2] > 2 * blue[0], "bottom right should be blue: %g %g %g", blue[0], blue[1], blue[2]);
    CHECK(white[0] > 0.5f * white[2] && white[2] > 0.5f * white[0] && white[1] > 0.1f, "bottom left should be white");
    CHECK(red[0] > 2 * red[2], "the arrow head (top middle) should be red: %g %g %g", red[0], red[1], red[2]);
    CHECK(top_white[0] < 2 * top_white[2], "top left should be white");
#undef PX
    free(img);
    scene_free(s);
}

/* OBJ + MTL: a floor (Kd) and a panel (Ke) as a "model" shape render the
 * same bytes as the same quads written in the JSON format. */
TEST(gltf_obj_mtl_matches_the_json_scene) {
    util_write_temp("room.mtl", "newmtl floor\nKd 0.5 0.4 0.3\nKs 0 0 0\n\nnewmtl lamp\nKd 0 0 0\nKe 5 5 5\n");
    util_write_temp("room.obj", "mtllib room.mtl\n"
                                "v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\n"
                                "v -0.3 1 -0.3\nv 0.3 1 -0.3\nv 0.3 1 0.3\nv -0.3 1 0.3\n"
                                "usemtl floor\nf 1 2 3 4\nusemtl lamp\nf 5 6 7 8\n");
    static const char *cam = "\"render\": {\"width\": 24, \"height\": 24, \"spp\": 8, \"seed\": 3},"
                             " \"camera\": {\"type\": \"perspective\", \"position\": [0, 0.5, 2.5], \"look_at\": [0, 0.3, 0], \"fov\": 50},";
    char json[4096], err[1024];
    snprintf(json, sizeof json, "{%s \"shapes\": [{\"type\": \"model\", \"file\": \"room.obj\"}]}", cam);
    scene *a = scene_load(util_write_temp("obj.json", json), NULL, err, sizeof err);
    CHECK(a, "%s", err);
    snprintf(json, sizeof json,
             "{%s \"materials\": {\"floor\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.4, 0.3]}},"
             " \"shapes\": [{\"type\": \"quad\", \"vertices\": [[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]], \"material\": \"floor\"},"
             "  {\"type\": \"quad\", \"vertices\": [[-0.3, 1, -0.3], [0.3, 1, -0.3], [0.3, 1, 0.3], [-0.3, 1, 0.3]], \"emission\": [5, 5, 5]}]}",
             cam);
    scene *b = scene_load(util_write_temp("quads.json", json), NULL, err, sizeof err);
    CHECK(b, "%s", err);
    if (!a || !b) return;
    CHECK(a->triangle_count == 4 && a->light_count == 2, "%u triangles, %u lights", a->triangle_count, a->light_count);
    CHECK(a->materials[a->triangle_info[0].material].kind == MATERIAL_DIFFUSE, "Kd alone is Lambert");
    trace_stats st;
    float *ia = util_render(a, 1, 8, 1, &st), *ib = util_render(b, 1, 8, 1, &st);
    double sa = 0, sb = 0;
    for (int i = 0; i < 24 * 24 * 3; i++) sa += ia[i], sb += ib[i];
    CHECK(sa > 0 && memcmp(ia, ib, 24 * 24 * 3 * sizeof(float)) == 0, "OBJ+MTL scene (sum %g) differs from the "
          "JSON scene (sum %g)", sa, sb);
    free(ia), free(ib);
    scene_free(a), scene_free(b);
}

/* Same bytes for any number of workers, threads and tiles, with textures
 * (arrow plane: .gltf + .bin + .png, shipped in the bundle) and glTF PBR
 * (Suzanne). */
TEST(gltf_farm_same_bytes_any_workers_threads_tiles) {
    static const char *scenes[] = {"scenes/gltf/arrow-plane.gltf", "scenes/gltf/suzanne.glb"};
    static const struct {
        const char *workers, *threads, *tile;
    } runs[] = {{"0", "1", "64"}, {"1", "2", "7"}, {"3", "1", "13"}};
    for (size_t s = 0; s < 2; s++) {
        char first[256] = "";
        for (size_t i = 0; i < sizeof runs / sizeof runs[0]; i++) {
            char name[64], path[256], cmd[1024], out[8192];
            snprintf(name, sizeof name, "farm-gltf-%zu-%zu.pfm", s, i);
            snprintf(path, sizeof path, "%s", util_temp_path(name));
            snprintf(cmd, sizeof cmd, "%s render %s --width 48 --height 36 --spp 4 --workers %s --threads %s "
                     "--tile-size %s --no-progress -o %s", harness_tessera(), scenes[s], runs[i].workers,
                     runs[i].threads, runs[i].tile, path);
            int st = util_run(cmd, out, sizeof out);
            CHECK(st == 0, "%s failed (%d): %s", cmd, st, out);
            if (i == 0)
                snprintf(first, sizeof first, "%s", path);
            else
                CHECK(util_same_file(path, first), "%s: differs from %s", cmd, first);
        }
    }
}

/* tessera submit of a .gltf (with its .bin and .png, from a folder the
 * service and its worker never see) with --camera: the job service renders
 * the same bytes as tessera render. */
TEST(gltf_submit_to_the_service_same_bytes) {
    char port[16], addr[64], data[256], clog[256], wlog[256], out[256], local[256], cmd[2048], text[8192];
    snprintf(port, sizeof port, "%d", util_free_port());
    snprintf(addr, sizeof addr, "127.0.0.1:%s", port);
    snprintf(data, sizeof data, "%s", util_temp_path("svc-data"));
    snprintf(clog, sizeof clog, "%s", util_temp_path("svc-coord.log"));
    snprintf(wlog, sizeof wlog, "%s", util_temp_path("svc-worker.log"));
    snprintf(out, sizeof out, "%s", util_temp_path("svc-out.pfm"));
    snprintf(local, sizeof local, "%s", util_temp_path("svc-local.pfm"));
    char coord_bin[512], worker_bin[512];
    snprintf(coord_bin, sizeof coord_bin, "%s", util_bin("tessera-coordinator"));
    snprintf(worker_bin, sizeof worker_bin, "%s", util_bin("tessera-worker"));
    const char *cargv[] = {coord_bin, "--data-dir", data, "--listen", addr, NULL};
    pid_t c = util_spawn(cargv, clog);
    CHECK(util_wait_for_text(clog, "listening on", 30) == 0, "no coordinator; log %s", clog);
    const char *wargv[] = {worker_bin, "--connect", addr, NULL};
    pid_t w = util_spawn(wargv, wlog);
    snprintf(cmd, sizeof cmd, "mkdir -p %s && cp scenes/gltf/arrow-plane.gltf scenes/gltf/arrow-plane.bin "
             "scenes/gltf/arrow.png %s/", util_temp_path("svc-model"), util_temp_path("svc-model"));
    CHECK(util_run(cmd, text, sizeof text) == 0, "%s: %s", cmd, text);
    snprintf(cmd, sizeof cmd, "%s submit %s/arrow-plane.gltf --camera Camera --width 40 --spp 4 --wait -o %s "
             "--coordinator %s", harness_tessera(), util_temp_path("svc-model"), out, addr);
    int st = util_run(cmd, text, sizeof text);
    CHECK(st == 0, "%s failed (%d): %s", cmd, st, text);
    snprintf(cmd, sizeof cmd, "%s render scenes/gltf/arrow-plane.gltf --width 40 --spp 4 --workers 0 "
             "--no-progress -o %s", harness_tessera(), local);
    CHECK(util_run(cmd, text, sizeof text) == 0, "%s: %s", cmd, text);
    CHECK(util_same_file(out, local), "the service's image differs from tessera render's");
    snprintf(cmd, sizeof cmd, "%s submit %s/arrow-plane.gltf --camera NoSuchCamera --coordinator %s",
             harness_tessera(), util_temp_path("svc-model"), addr);
    st = util_run(cmd, text, sizeof text);
    CHECK(st != 0 && strstr(text, "no camera named \"NoSuchCamera\""), "a missing camera: %d %s", st, text);
    kill(w, SIGTERM);
    kill(c, SIGTERM);
    util_wait(w, 30, NULL);
    util_wait(c, 30, NULL);
}

/* KHR_lights_punctual spot: full intensity inside the inner cone, none
 * outside the outer one, the spec's smooth (squared) falloff between;
 * directional: the same irradiance everywhere. */
TEST(gltf_spot_and_directional_lights) {
    light spot = {.kind = LIGHT_SPOT, .intensity = {4, 4, 4}, .position = {0, 0, 0}, .direction = {0, -1, 0},
                  .cos_inner = cosf(0.2f), .cos_outer = cosf(0.4f), .select_pdf = 1};
    light_sample ls;
    CHECK(punctual_sample(&spot, vec3_make(0, -2, 0), &ls) && fabsf(ls.radiance.x - 1.0f) < 1e-6f && ls.is_delta,
          "on the axis at distance 2: I / 4 = 1, got %g", ls.radiance.x);
    CHECK(!punctual_sample(&spot, vec3_make(2, -2, 0), &ls), "45 degrees off the axis is outside the outer cone");
    CHECK(!punctual_sample(&spot, vec3_make(0, 2, 0), &ls), "behind the spot");
    float mid = 0.3f, cm = cosf(mid), a = (cm - cosf(0.4f)) / (cosf(0.2f) - cosf(0.4f));
    vec3 p = vec3_make(2 * sinf(mid), -2 * cosf(mid), 0);
    CHECK(punctual_sample(&spot, p, &ls) && fabsf(ls.radiance.x - a * a) < 1e-4f, "falloff %g, want %g", ls.radiance.x,
          a * a);
    light sun = {.kind = LIGHT_DIRECTIONAL, .intensity = {3, 3, 3}, .direction = {0, -1, 0}, .select_pdf = 1};
    CHECK(punctual_sample(&sun, vec3_make(0.3f, 0.1f, -0.5f), &ls) && ls.radiance.x == 3.0f && ls.wi.y == 1.0f,
          "directional: E = 3 from above");
}

/* The end of a glTF document: one buffer holding a unit quad in z = 0
 * facing +z (positions -1..1, normals +z, texture coordinates 0..1, two
 * triangles) with its buffer views and accessors 0 to 3 (POSITION,
 * NORMAL, TEXCOORD_0, indices). */
#define UNIT_QUAD_GLTF_DATA                                                                                               \
    " \"buffers\": [{\"byteLength\": 140, \"uri\": \"data:application/octet-stream;base64,"                                    \
    "AACAvwAAgL8AAAAAAACAPwAAgL8AAAAAAACAPwAAgD8AAAAAAACAvwAAgD8AAAAAAAAAAAAAAAAAAIA/AAAAAAAAAAAAAIA/AAAAAAAAAA"         \
    "AAAIA/AAAAAAAAAAAAAIA/AAAAAAAAgD8AAIA/AACAPwAAgD8AAAAAAAAAAAAAAAAAAAEAAgAAAAIAAwA=\"}],"                               \
    " \"bufferViews\": [{\"buffer\": 0, \"byteOffset\": 0, \"byteLength\": 48},"                                           \
    "  {\"buffer\": 0, \"byteOffset\": 48, \"byteLength\": 48}, {\"buffer\": 0, \"byteOffset\": 96, \"byteLength\": 32},"  \
    "  {\"buffer\": 0, \"byteOffset\": 128, \"byteLength\": 12}],"                                                       \
    " \"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": 4, \"type\": \"VEC3\", \"min\": [-1, -1, 0], \"max\": [1, 1, 0]}," \
    "  {\"bufferView\": 1, \"componentType\": 5126, \"count\": 4, \"type\": \"VEC3\"},"                                  \
    "  {\"bufferView\": 2, \"componentType\": 5126, \"count\": 4, \"type\": \"VEC2\"},"                                  \
    "  {\"bufferView\": 3, \"componentType\": 5123, \"count\": 6, \"type\": \"SCALAR\"}]}"

/* A model placed with a scale of 1024 (and its camera and point light
 * scaled alike) renders the same picture: glTF is in metres, the scene may
 * be in millimetres. */
TEST(gltf_model_scale_keeps_the_picture) {
    char json[2048], err[1024];
    static const double scales[] = {1, 1024};
    float *img[2] = {NULL, NULL};
    for (int i = 0; i < 2; i++) {
        double s = scales[i];
        snprintf(json, sizeof json,
                 "{\"render\": {\"width\": 32, \"height\": 24, \"spp\": 8},"
                 " \"camera\": {\"type\": \"perspective\", \"position\": [0, 0, %g], \"look_at\": [0, 0, 0], \"fov\": 30.2},"
                 " \"shapes\": [{\"type\": \"model\", \"file\": \"%s/scenes/gltf/arrow-plane.gltf\", \"scale\": %g}]}",
                 4 * s, getcwd((char[1024]){0}, 1024), s);
        scene *sc = scene_load(util_write_temp("scaled.json", json), NULL, err, sizeof err);
        CHECK(sc, "%s", err);
        if (!sc) return;
        trace_stats st;
        img[i] = util_render(sc, 1, 16, 1, &st);
        scene_free(sc);
    }
    double sa = 0, sb = 0;
    for (int k = 0; k < 32 * 24 * 3; k++) sa += img[0][k], sb += img[1][k];
    CHECK(sa > 0 && fabs(sa / sb - 1) < 1e-4, "scale 1: %g, scale 1024: %g", sa, sb);
    free(img[0]), free(img[1]);
}

/* Normal maps, glTF convention: tangent-space +X along increasing u, +Y
 * toward decreasing v (up the image), +Z the surface normal. A quad facing
 * the camera (+z), u to the right, v down, with a constant normal map, lit
 * by a directional light 45 degrees off the normal: a map tilted toward +X
 * is brighter lit from +x than from -x, one tilted toward +Y brighter lit
 * from +y (above); the flat map (128, 128, 255) is symmetric. */
static double normal_map_mean(const char *map_b64, const char *light_rotation) {
    static char text[8192];
    snprintf(text, sizeof text,
             "{\"asset\": {\"version\": \"2.0\"}, \"extensionsUsed\": [\"KHR_lights_punctual\"],"
             " \"extensions\": {\"KHR_lights_punctual\": {\"lights\": [{\"type\": \"directional\", \"intensity\": 683}]}},"
             " \"scenes\": [{\"nodes\": [0, 1, 2]}],"
             " \"nodes\": [{\"mesh\": 0}, {\"camera\": 0, \"translation\": [0, 0, 3]},"
             "  {\"rotation\": %s, \"extensions\": {\"KHR_lights_punctual\": {\"light\": 0}}}],"
             " \"cameras\": [{\"type\": \"perspective\", \"perspective\": {\"yfov\": 0.5, \"aspectRatio\": 1}}],"
             " \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0, \"NORMAL\": 1, \"TEXCOORD_0\": 2},"
             "  \"indices\": 3, \"material\": 0}]}],"
             " \"materials\": [{\"pbrMetallicRoughness\": {\"metallicFactor\": 0, \"roughnessFactor\": 1},"
             "  \"normalTexture\": {\"index\": 0}}],"
             " \"textures\": [{\"source\": 0, \"sampler\": 0}], \"samplers\": [{\"wrapS\": 33071, \"wrapT\": 33071}],"
             " \"images\": [{\"uri\": \"data:image/png;base64,%s\"}],"
             UNIT_QUAD_GLTF_DATA,
             light_rotation, map_b64);
    char err[1024];
    scene_overrides ov = {.width = 8, .height = 8, .spp = 4, .max_depth = 1}; /* direct light only */
    scene *s = scene_load(util_write_temp("nmap.gltf", text), &ov, err, sizeof err);
    CHECK(s, "%s", err);
    if (!s) return -1;
    trace_stats st;
    float *img = util_render(s, 1, 8, 1, &st);
    double sum = 0;
    for (int i = 0; i < 8 * 8 * 3; i++) sum += img[i];
    free(img);
    scene_free(s);
    return sum / (8 * 8 * 3);
}

TEST(gltf_normal_map_orientation) {
    static const char *flat = "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAIAAACQd1PeAAAADElEQVR4nGNoaPgPAAODAgAApfuJAAAAAElFTkSuQmCC";
    static const char *plus_x = "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAIAAACQd1PeAAAADElEQVR4nGP439AAAASBAgCFVE/wAAAAAElFTkSuQmCC";
    static const char *plus_y = "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAIAAACQd1PeAAAADElEQVR4nGNo+N8AAAQCAgCpSbOxAAAAAElFTkSuQmCC";
    /* Light travelling (-1, 0, -1) (from +x), (1, 0, -1) (from -x),
     * (0, -1, -1) (from +y) and (0, 1, -1) (from -y). */
    static const char *from_px = "[0, 0.3826834, 0, 0.9238795]", *from_mx = "[0, -0.3826834, 0, 0.9238795]";
    static const char *from_py = "[-0.3826834, 0, 0, 0.9238795]", *from_my = "[0.3826834, 0, 0, 0.9238795]";
    double fx = normal_map_mean(flat, from_px), fmx = normal_map_mean(flat, from_mx);
    /* 128 / 255 is 0.0039 off the middle: "flat" tilts by 0.2 degrees. */
    CHECK(fx > 0 && fabs(fx - fmx) < 0.02 * fx, "flat map: %g from +x, %g from -x", fx, fmx);
    double px = normal_map_mean(plus_x, from_px), pmx = normal_map_mean(plus_x, from_mx);
    CHECK(px > 1.5 * pmx, "+X map: %g lit from +x should beat %g from -x", px, pmx);
    double py = normal_map_mean(plus_y, from_py), pmy = normal_map_mean(plus_y, from_my);
    CHECK(py > 1.5 * pmy, "+Y map: %g lit from above should beat %g from below", py, pmy);
}

/* alphaMode MASK: a quad whose base colour texture has alpha 0 is cut out
 * (camera rays pass to the sky); the same quad OPAQUE is seen (red). */
static double quad_green_mean(const char *alpha_mode) {
    static char text[8192];
    snprintf(text, sizeof text,
             "{\"asset\": {\"version\": \"2.0\"}, \"scenes\": [{\"nodes\": [0, 1]}],"
             " \"nodes\": [{\"mesh\": 0}, {\"camera\": 0, \"translation\": [0, 0, 3]}],"
             " \"cameras\": [{\"type\": \"perspective\", \"perspective\": {\"yfov\": 0.5, \"aspectRatio\": 1}}],"
             " \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0, \"NORMAL\": 1, \"TEXCOORD_0\": 2},"
             "  \"indices\": 3, \"material\": 0}]}],"
             " \"materials\": [{\"pbrMetallicRoughness\": {\"metallicFactor\": 0, \"baseColorTexture\": {\"index\": 0}},"
             "  \"alphaMode\": \"%s\", \"doubleSided\": true}],"
             " \"textures\": [{\"source\": 0}],"
             " \"images\": [{\"uri\": \"data:image/png;base64,"
             "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR4nGP4z8DAAAAEAQEARwbK3gAAAABJRU5ErkJggg==\"}],"
             UNIT_QUAD_GLTF_DATA,
             alpha_mode);
    char err[1024];
    scene_overrides ov = {.width = 8, .height = 8, .spp = 4, .max_depth = 4};
    scene *s = scene_load(util_write_temp("alpha.gltf", text), &ov, err, sizeof err);
    CHECK(s, "%s", err);
    if (!s) return -1;
    CHECK((strcmp(alpha_mode, "MASK") == 0) == ((s->features & FEATURE_CUTOUT) != 0), "cutout feature bit");
    trace_stats st;
    float *img = util_render(s, 1, 8, 1, &st);
    double sum = 0;
    for (int i = 0; i < 8 * 8; i++) sum += img[3 * i + 1];
    free(img);
    scene_free(s);
    return sum / 64;
}

TEST(gltf_alpha_mask_cuts_out) {
    double masked = quad_green_mean("MASK"), opaque = quad_green_mean("OPAQUE");
    CHECK(fabs(masked - 1.0) < 1e-6, "MASK with alpha 0: the sky (1) everywhere, got %g", masked);
    CHECK(opaque < 0.5, "OPAQUE: the red quad covers the view, green %g", opaque);
}

/* model_references' collect callback: the names, space-separated. */
static int collect_ref(void *ctx, const char *name) {
    char *out = ctx;
    size_t n = strlen(out);
    snprintf(out + n, 1024 - n, "%s%s", n ? " " : "", name);
    return 0;
}

/* An OBJ's mtllib lines and an MTL's map_Kd lines, found wherever they are
 * (indented by spaces or tabs, last line without a newline), and nothing
 * else: not a keyword inside a line, after a comment mark, or run into
 * the next word; an OBJ line's letters m that are not a keyword's are
 * skipped (model_files.c scans for the letter, not every line). */
TEST(model_references_find_every_keyword_line) {
    static const char obj[] = "# mtllib commented.mtl\nmtllib a.mtl b.mtl\nv 1 2 3\nusemtl mtllib\n"
                              "mtllibx not.mtl\n \t mtllib\tc.mtl\r\nvm mtllib no.mtl\nmtllib\nf 1 2 3\n"
                              "m\nmtllib d/e.mtl";
    char got[1024] = "";
    CHECK(model_references("dir/m.obj", obj, sizeof obj - 1, collect_ref, got) == 0, "OBJ scan failed");
    CHECK(strcmp(got, "dir/a.mtl dir/b.mtl dir/c.mtl dir/d/e.mtl") == 0, "OBJ references: \"%s\"", got);
    static const char mtl[] = "newmtl x\nmap_Kd -s 1 1 1 tex.png\n  map_Kd\tother.png\nmap_Ka no.png\n"
                              "Kd 1 1 1 map_Kd no2.png\nmap_Kd last.png";
    got[0] = 0;
    CHECK(model_references("m.mtl", mtl, sizeof mtl - 1, collect_ref, got) == 0, "MTL scan failed");
    CHECK(strcmp(got, "tex.png other.png last.png") == 0, "MTL references: \"%s\"", got);
}

/* tessera render room.obj: an OBJ alone, with its MTL's Ke as the light (so
 * no sky), the automatic camera and a 4:3 image from --width alone. */
TEST(gltf_obj_alone_renders_with_its_lights) {
    util_write_temp("alone.mtl", "newmtl floor\nKd 0.5 0.4 0.3\n\nnewmtl lamp\nKd 0 0 0\nKe 5 5 5\n");
    const char *path = util_write_temp("alone.obj", "mtllib alone.mtl\nv -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\n"
                                                    "v -0.3 1 -0.3\nv 0.3 1 -0.3\nv 0.3 1 0.3\nv -0.3 1 0.3\n"
                                                    "usemtl floor\nf 1 2 3 4\nusemtl lamp\nf 5 6 7 8\n");
    char err[1024];
    scene_overrides ov = {.width = 160, .height = -1, .spp = 4, .max_depth = -1};
    scene *s = scene_load(path, &ov, err, sizeof err);
    CHECK(s, "%s", err);
    if (!s) return;
    CHECK(s->settings.width == 160 && s->settings.height == 120, "%dx%d", s->settings.width, s->settings.height);
    CHECK(s->light_count == 2 && !(s->features & FEATURE_BACKGROUND), "%u lights, background %d", s->light_count,
          !!(s->features & FEATURE_BACKGROUND));
    scene_free(s);
}

/* Material extensions read from the glTF JSON: emissive strength multiplies
 * the factor (one-sided unless doubleSided); transmission with an IOR maps
 * onto the smooth glass. */
TEST(gltf_material_extensions) {
    char err[1024];
    const char *path = tri_gltf("emit.gltf", "\"extensionsUsed\": [\"KHR_materials_emissive_strength\"],", 4,
                                "\"emissiveFactor\": [1, 0.5, 0.25], \"extensions\": {\"KHR_materials_emissive_strength\":"
                                " {\"emissiveStrength\": 8}}", "", TRI_DATA, 5123, 5126);
    scene *s = scene_load(path, NULL, err, sizeof err);
    CHECK(s, "%s", err);
    if (s) {
        CHECK(s->light_count == 1 && fabsf(s->lights[0].radiance.x - 8) < 1e-6f && fabsf(s->lights[0].radiance.z - 2) < 1e-6f &&
                  !s->lights[0].two_sided && !(s->features & FEATURE_BACKGROUND),
              "emissive triangle: %u lights, radiance %g %g", s->light_count, s->light_count ? s->lights[0].radiance.x : 0,
              s->light_count ? s->lights[0].radiance.z : 0);
        scene_free(s);
    }
    path = tri_gltf("emit2.gltf", "", 4, "\"emissiveFactor\": [1, 1, 1], \"doubleSided\": true", "", TRI_DATA, 5123, 5126);
    s = scene_load(path, NULL, err, sizeof err);
    CHECK(s && s->light_count == 1 && s->lights[0].two_sided, "doubleSided emitter emits from both faces");
    scene_free(s);
    path = tri_gltf("glass.gltf", "\"extensionsUsed\": [\"KHR_materials_transmission\", \"KHR_materials_ior\"],", 4,
                    "\"pbrMetallicRoughness\": {\"baseColorFactor\": [0.9, 1, 0.8, 1], \"metallicFactor\": 0},"
                    " \"extensions\": {\"KHR_materials_transmission\": {\"transmissionFactor\": 1},"
                    " \"KHR_materials_ior\": {\"ior\": 1.33}}", "", TRI_DATA, 5123, 5126);
    s = scene_load(path, NULL, err, sizeof err);
    CHECK(s, "%s", err);
    if (s) {
        const material *m = &s->materials[s->triangle_info[0].material];
        CHECK(m->kind == MATERIAL_GLASS && fabsf(m->ior - 1.33f) < 1e-6f && fabsf(m->kt.x - 0.9f) < 1e-6f,
              "transmission 1, ior 1.33: kind %d ior %g", m->kind, m->ior);
        scene_free(s);
    }
}

/* OBJ + MTL map_Kd: the texture on a quad with OBJ's v-up texture
 * coordinates appears upright (arrow up, blue square bottom right). */
TEST(gltf_obj_map_kd_the_right_way) {
    char cmd[1024], out[1024];
    snprintf(cmd, sizeof cmd, "cp scenes/gltf/arrow.png %s", util_temp_path("arrow.png"));
    CHECK(util_run(cmd, out, sizeof out) == 0, "%s", out);
    util_write_temp("tex.mtl", "newmtl arrow\nKd 1 1 1\nmap_Kd arrow.png\n");
    util_write_temp("tex.obj", "mtllib tex.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
                               "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl arrow\nf 1/1 2/2 3/3 4/4\n");
    const char *path = util_write_temp("tex.json",
        "{\"render\": {\"width\": 64, \"height\": 64, \"spp\": 4, \"max_depth\": 1}, \"background\": [1, 1, 1],"
        " \"camera\": {\"type\": \"perspective\", \"position\": [0, 0, 3], \"look_at\": [0, 0, 0], \"fov\": 38},"
        " \"shapes\": [{\"type\": \"model\", \"file\": \"tex.obj\"}]}");
    char err[1024];
    scene *s = scene_load(path, NULL, err, sizeof err);
    CHECK(s, "%s", err);
    if (!s) return;
    trace_stats st;
    float *img = util_render(s, 1, 16, 1, &st);
#define PX(x, y) (&img[3 * ((y) * 64 + (x))])
    const float *blue = PX(52, 52), *red = PX(32, 18), *white = PX(12, 52);
    CHECK(blue[2] > 2 * blue[0], "bottom right should be blue: %g %g %g", blue[0], blue[1], blue[2]);
    CHECK(red[0] > 2 * red[2], "top middle should be the red arrow head: %g %g %g", red[0], red[1], red[2]);
    CHECK(white[0] > 0.5f * white[2] && white[2] > 0.5f * white[0], "bottom left should be white");
#undef PX
    free(img);
    scene_free(s);
}

/* KHR_texture_transform on the base colour texture: uv' = T R S uv. */
TEST(gltf_texture_transform_is_read) {
    char cmd[1024], out[1024], err[1024];
    snprintf(cmd, sizeof cmd, "cp scenes/gltf/arrow.png %s", util_temp_path("arrow.png"));
    CHECK(util_run(cmd, out, sizeof out) == 0, "%s", out);
    const char *path = tri_gltf("xform.gltf", "\"extensionsUsed\": [\"KHR_texture_transform\"],", 4,
                                "\"pbrMetallicRoughness\": {\"baseColorTexture\": {\"index\": 0, \"extensions\":"
                                " {\"KHR_texture_transform\": {\"offset\": [0.5, 0.25], \"rotation\": 1.5707963,"
                                " \"scale\": [2, 3]}}}}",
                                "\"textures\": [{\"source\": 0}], \"images\": [{\"uri\": \"arrow.png\"}],", TRI_DATA,
                                5123, 5126);
    scene *s = scene_load(path, NULL, err, sizeof err);
    CHECK(s, "%s", err);
    if (!s) return;
    const material *m = &s->materials[s->triangle_info[0].material];
    /* rotation pi/2: cos 0, sin 1: M = [c sx, s sy, ox; -s sx, c sy, oy]. */
    const float want[6] = {0, 3, 0.5f, -2, 0, 0.25f};
    CHECK(m->has_uv_xform && m->tex_base, "transform and texture present");
    for (int i = 0; i < 6; i++) CHECK(fabsf(m->uv_xform[i] - want[i]) < 1e-6f, "M[%d] = %g, want %g", i, m->uv_xform[i], want[i]);
    scene_free(s);
}

/* A model shape's "rotate" (degrees, x then y then z) turns geometry and
 * shading normals: a triangle (and a quad with normals) facing +z turned 90
 * degrees about y faces +x. */
TEST(gltf_model_shape_rotates) {
    good("rot.gltf");
    char err[1024];
    const char *path = util_write_temp("rot.json",
        "{\"camera\": {\"type\": \"perspective\", \"position\": [5, 0, 0], \"look_at\": [0, 0, 0], \"fov\": 40},"
        " \"shapes\": [{\"type\": \"model\", \"file\": \"rot.gltf\", \"rotate\": [0, 90, 0]}]}");
    scene *s = scene_load(path, NULL, err, sizeof err);
    CHECK(s, "%s", err);
    if (!s) return;
    vec3 n = s->triangle_normals[0];
    CHECK(fabsf(n.x - 1) < 1e-5f && fabsf(n.y) < 1e-5f && fabsf(n.z) < 1e-5f, "normal %g %g %g", n.x, n.y, n.z);
    scene_free(s);
    /* The unit quad with its normals (+z at all 4 vertices): one shading
     * normal, stored once for the 6 corners, turned to +x. */
    util_write_temp("rotq.gltf", "{\"asset\": {\"version\": \"2.0\"}, \"scenes\": [{\"nodes\": [0]}], \"nodes\": [{\"mesh\": 0}],"
                                 " \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0, \"NORMAL\": 1},"
                                 " \"indices\": 3}]}]," UNIT_QUAD_GLTF_DATA);
    path = util_write_temp("rotq.json",
        "{\"camera\": {\"type\": \"perspective\", \"position\": [5, 0, 0], \"look_at\": [0, 0, 0], \"fov\": 40},"
        " \"shapes\": [{\"type\": \"model\", \"file\": \"rotq.gltf\", \"rotate\": [0, 90, 0]}]}");
    s = scene_load(path, NULL, err, sizeof err);
    CHECK(s, "%s", err);
    if (!s) return;
    CHECK(s->triangle_count == 2 && util_smooth_triangles(s) == 2 && util_distinct_corner_normals(s) == 1,
          "%u triangles, %zu with normals, %zu distinct normals", s->triangle_count, util_smooth_triangles(s),
          util_distinct_corner_normals(s));
    if (!util_corner_normal(s, 0, 0, &n)) n = vec3_splat(0);
    CHECK(fabsf(n.x - 1) < 1e-5f && fabsf(n.y) < 1e-5f && fabsf(n.z) < 1e-5f, "shading normal %g %g %g", n.x, n.y, n.z);
    scene_free(s);
    path = util_write_temp("rot2.json",
        "{\"camera\": {\"type\": \"perspective\", \"position\": [5, 0, 0], \"look_at\": [0, 0, 0], \"fov\": 40},"
        " \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [1, 1, 1]}},"
        " \"shapes\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"w\", \"rotate\": [0, 1, 0]}]}");
    s = scene_load(path, NULL, err, sizeof err);
    CHECK(!s && strstr(err, "shapes[0].rotate: only model shapes rotate"), "rotate on a sphere: %s", err);
    scene_free(s);
}

/* An OBJ whose material library is missing renders grey, as the importer
 * does, with one warning naming the file (once per command, not per
 * worker). */
TEST(gltf_obj_missing_material_library_is_one_warning) {
    const char *path = util_write_temp("nomtl.obj", "mtllib nomtl-gone.mtl\nv -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\n"
                                                    "usemtl floor\nf 1 2 3 4\n");
    char cmd[4096], out[8192], png[600];
    snprintf(png, sizeof png, "%s.png", path);
    snprintf(cmd, sizeof cmd, "%s render %s --width 32 --spp 2 --workers 2 -q -o %s 2>&1", harness_tessera(), path, png);
    int rc = util_run(cmd, out, sizeof out);
    const char *w = strstr(out, "warning: material library ");
    CHECK(rc == 0 && w && strstr(w, "nomtl-gone.mtl: cannot open: No such file or directory; its materials are "
                                    "rendered grey") && !strstr(w + 1, "warning:"),
          "a missing MTL (%d): %s", rc, out);
}

/* A model through stdin or a pipe, which has no name to tell its kind:
 * GLB by its magic, glTF by its "asset" object. It renders as the file
 * does (same bytes); a glTF's buffers resolve against the current folder. */
TEST(gltf_model_from_stdin_or_a_pipe) {
    char cmd[8192], out[8192], a[512], b[512], c[512], bin[PATH_MAX];
    CHECK(realpath(harness_tessera(), bin) != NULL, "cannot resolve %s", harness_tessera());
    snprintf(a, sizeof a, "%s", util_temp_path("stdin-file.pfm"));
    snprintf(b, sizeof b, "%s", util_temp_path("stdin-piped.pfm"));
    snprintf(c, sizeof c, "%s", util_temp_path("stdin-gltf.pfm"));
    static const char *const models[] = {"suzanne.glb", "arrow-plane.gltf"};
    for (int i = 0; i < 2; i++) {
        snprintf(cmd, sizeof cmd, "cd scenes/gltf && %s render %s --width 48 --spp 2 --workers 0 -q -o %s 2>&1", bin,
                 models[i], a);
        int rc = util_run(cmd, out, sizeof out);
        CHECK(rc == 0, "%s (%d): %s", models[i], rc, out);
        snprintf(cmd, sizeof cmd, "cd scenes/gltf && cat %s | %s render - --width 48 --spp 2 --workers 0 -q -o %s 2>&1",
                 models[i], bin, b);
        rc = util_run(cmd, out, sizeof out);
        CHECK(rc == 0 && util_same_file(a, b), "%s through stdin (%d): %s", models[i], rc, out);
    }
    snprintf(cmd, sizeof cmd, "cat scenes/gltf/arrow-plane.gltf | %s render - --width 48 --spp 2 --workers 0 -q -o %s 2>&1",
             harness_tessera(), c);
    int rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 1 && strstr(out, "<stdin>: import.file: stdin.gltf: buffers[0].uri: ./arrow-plane.bin: cannot open"),
          "a glTF on stdin whose buffer is not in the current folder (%d): %s", rc, out);
    snprintf(cmd, sizeof cmd, "cd scenes/gltf && %s render - --camera Nope --width 48 --spp 2 -q -o %s < "
             "arrow-plane.gltf 2>&1", bin, c);
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 1 && strstr(out, "<stdin>: import.camera: stdin.gltf: no camera named \"Nope\""),
          "--camera of a model on stdin (%d): %s", rc, out);
}
