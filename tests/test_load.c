/* test_load.c - loading on several threads gives what one thread gives:
 * an OBJ text parsed in spans equals the one-pass parse bit for bit (every
 * record form, negative indices, attributes in some spans only, spans cut
 * at different lines) and gives up on every text the one pass refuses,
 * whose message stays the one pass's; a scene loaded with 1 or 3 loader
 * threads has the same triangles, normals, frame and skipped count. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/obj.h"
#include "render/scene.h"
#include "harness.h"
#include "util.h"

/* A growing text. */
typedef struct {
    char *s;
    size_t len, cap;
} text;

static void add(text *t, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void add(text *t, const char *fmt, ...) {
    char line[256];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    if (t->len + (size_t)n + 1 > t->cap) {
        t->cap = 2 * (t->len + (size_t)n + 1);
        t->s = realloc(t->s, t->cap);
    }
    memcpy(t->s + t->len, line, (size_t)n + 1);
    t->len += (size_t)n;
}

/* An OBJ text of `rows` rows of 4 vertices, faces between a row and the one
 * before: triangles, quads and pentagons, plain, negative, v/t/n and v//n
 * corners, comments, groups, blank and CRLF lines; one normal and one uv
 * per row from row attr_from on; every 97th face degenerate (a corner
 * twice) when `degenerate`. No '\n' after the last line when `open_end`. */
static text strips(int rows, int attr_from, int degenerate, int open_end) {
    text t = {0};
    add(&t, "# strips\ng all\n");
    for (int r = 0; r < rows; r++) {
        for (int c = 0; c < 4; c++) add(&t, "v %d.%d %d -0.%03d\n", c, r % 10, r, (r * 7 + c) % 1000);
        if (r >= attr_from) add(&t, "vn 0 %d %d\r\nvt 0.%d %d\n", r % 3, r % 11 != 0, r % 10, r % 2); /* some (0, 0, 0) */
        if (r == 0) continue;
        if (degenerate && r % 97 == 0) add(&t, "f %d %d %d\n", 4 * r, 4 * r, 4 * r + 1);
        else if (r % 5 == 0) add(&t, "f -8 -7 -3 -4\n");
        else if (r % 5 == 1) add(&t, "\tf %d %d %d\n", 4 * r - 3, 4 * r - 2, 4 * r + 1);
        else if (r % 5 == 2) add(&t, "usemtl m%d\n\nf -4 -3 -2 -1 -5\n", r);
        else if (r >= attr_from + 1) add(&t, "f -8/-1/-1 -7/-2/-1 -3/-1/-2 # fan\n");
        else add(&t, "f %d %d %d  \n", 4 * r, 4 * r - 1, 4 * r + 3);
        if (r >= attr_from + 1 && r % 7 == 0) add(&t, "f -1//-1 -2//-1 -5//-2\n");
    }
    add(&t, "f 1 2 3%s", open_end ? "" : "\n");
    return t;
}

static int same_array(const void *a, const void *b, size_t bytes) {
    if (!a || !b) return a == b;
    return memcmp(a, b, bytes) == 0;
}

/* Whether two parsed meshes are the same, array by array. */
static int same_mesh(const obj_mesh *a, const obj_mesh *b) {
    return a->vertex_count == b->vertex_count && a->triangle_count == b->triangle_count &&
           a->normal_count == b->normal_count && a->uv_count == b->uv_count &&
           same_array(a->positions, b->positions, 3 * a->vertex_count * sizeof(double)) &&
           same_array(a->indices, b->indices, 3 * a->triangle_count * sizeof(uint32_t)) &&
           same_array(a->normals, b->normals, 3 * a->normal_count * sizeof(float)) &&
           same_array(a->uvs, b->uvs, 2 * a->uv_count * sizeof(float)) &&
           same_array(a->normal_indices, b->normal_indices, 3 * a->triangle_count * sizeof(uint32_t)) &&
           same_array(a->uv_indices, b->uv_indices, 3 * a->triangle_count * sizeof(uint32_t));
}

/* Parse t in one pass (one loader thread). */
static int parse_one_pass(const text *t, obj_mesh *m, char *err, size_t err_len) {
    setenv("TESSERA_LOAD_THREADS", "1", 1);
    int rc = obj_parse(t->s, t->len, "strips.obj", m, err, err_len);
    unsetenv("TESSERA_LOAD_THREADS");
    return rc;
}

TEST(load_obj_spans_equal_one_pass) {
    static const int attr_from[] = {0, 700, 2000}; /* all rows, the later ones, none */
    for (int a = 0; a < 3; a++)
        for (int open_end = 0; open_end < 2; open_end++) {
            text t = strips(2000, attr_from[a], 0, open_end);
            obj_mesh one, spans;
            char err[256];
            CHECK(parse_one_pass(&t, &one, err, sizeof err) == 0, "%s", err);
            CHECK((one.normal_indices != NULL) == (attr_from[a] < 2000), "normal indices %p", (void *)one.normal_indices);
            for (int parts = 1; parts <= 8; parts++) {
                int rc = obj_parse_spans(t.s, t.len, "strips.obj", parts, &spans);
                CHECK(rc == 0, "attributes from row %d, %d spans: refused", attr_from[a], parts);
                if (rc) continue;
                CHECK(same_mesh(&one, &spans), "attributes from row %d, open end %d, %d spans: %zu/%zu vertices, "
                      "%zu/%zu triangles, not the same mesh", attr_from[a], open_end, parts, spans.vertex_count,
                      one.vertex_count, spans.triangle_count, one.triangle_count);
                obj_mesh_free(&spans);
            }
            obj_mesh_free(&one);
            free(t.s);
        }
}

/* A bad line late in a text (in the last span): the spans give up, and
 * obj_parse on several threads reports the one pass's message. Among them
 * indices that only the counts of the spans before can judge. */
TEST(load_obj_spans_refuse_what_one_pass_refuses) {
    text good = strips(2000, 0, 0, 0);
    size_t cut = good.len * 9 / 10;
    while (good.s[cut - 1] != '\n') cut++;
    size_t v = 0, vn = 0; /* records before the cut */
    for (size_t i = 0; i < cut; i++)
        if (i == 0 || good.s[i - 1] == '\n') v += good.s[i] == 'v' && good.s[i + 1] == ' ', vn += good.s[i] == 'v' && good.s[i + 1] == 'n';
    char bad[8][128];
    snprintf(bad[0], sizeof bad[0], "f 1 2 %zu\n", v + 1);          /* one past the last vertex */
    snprintf(bad[1], sizeof bad[1], "f -%zu 1 2\n", v + 1);         /* one before the first */
    snprintf(bad[2], sizeof bad[2], "f 1//%zu 2//1 3//1\n", vn + 1); /* one past the last normal */
    snprintf(bad[3], sizeof bad[3], "v 1 2\n");
    snprintf(bad[4], sizeof bad[4], "vn 0 inf 1\n");
    snprintf(bad[5], sizeof bad[5], "f 1//1 2 3//1\n");
    snprintf(bad[6], sizeof bad[6], "f 1 2\n");
    snprintf(bad[7], sizeof bad[7], "f 1 2 3 \v\n");
    for (int k = 0; k < 8; k++) {
        text t = {malloc(good.len + 200), 0, good.len + 200};
        memcpy(t.s, good.s, cut);
        t.len = cut + (size_t)sprintf(t.s + cut, "%s", bad[k]);
        memcpy(t.s + t.len, good.s + cut, good.len - cut);
        t.len += good.len - cut;
        obj_mesh m;
        char want[256] = "", got[256] = "";
        int one = parse_one_pass(&t, &m, want, sizeof want);
        if (one == 0) obj_mesh_free(&m);
        CHECK(one == -1 && strstr(want, "strips.obj:"), "bad line %d: one pass says %d \"%s\"", k, one, want);
        int spans = obj_parse_spans(t.s, t.len, "strips.obj", 3, &m);
        if (spans == 0) obj_mesh_free(&m);
        CHECK(spans == -1, "bad line %d (%s): the spans accepted it", k, bad[k]);
        setenv("TESSERA_LOAD_THREADS", "3", 1);
        int par = obj_parse(t.s, t.len, "strips.obj", &m, got, sizeof got);
        unsetenv("TESSERA_LOAD_THREADS");
        if (par == 0) obj_mesh_free(&m);
        CHECK(par == -1 && strcmp(got, want) == 0, "bad line %d: \"%s\" on 3 threads, \"%s\" in one pass", k, got, want);
        free(t.s);
    }
    free(good.s);
}

/* Load `json` with `threads` loader threads. */
static scene *load_with(const char *path, const char *threads, char *err, size_t err_len) {
    setenv("TESSERA_LOAD_THREADS", threads, 1);
    scene_overrides ov = {.width = -1, .height = -1, .spp = -1, .max_depth = -1, .no_accel = 1};
    scene *s = scene_load(path, &ov, err, err_len);
    unsetenv("TESSERA_LOAD_THREADS");
    return s;
}

/* Two instances of a mesh without attributes, one of it smoothed
 * (`smooth_angle`), one of a mesh with normals (some unusable: zero) and
 * uvs from its middle on, all with skipped degenerate faces, and a quad: the scene on 3 loader threads (the
 * loader's ranges) is the scene on 1 (one by one), bit for bit. */
TEST(load_scene_same_on_any_threads) {
    text plain = strips(30000, 30000, 1, 0), attr = strips(30000, 15000, 1, 0);
    util_write_temp("strips-plain.obj", plain.s);
    util_write_temp("strips-attr.obj", attr.s);
    const char *path = util_write_temp(
        "strips.json",
        "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -90], \"look_at\": [0, 0, 0], \"fov\": 40}, "
        "\"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, \"shapes\": ["
        "{\"type\": \"quad\", \"material\": \"m\", \"vertices\": [[-9, -9, 5], [9, -9, 5], [9, 9, 5], [-9, 9, 5]]},"
        "{\"type\": \"mesh\", \"file\": \"strips-plain.obj\", \"material\": \"m\", \"scale\": 0.01},"
        "{\"type\": \"mesh\", \"file\": \"strips-attr.obj\", \"material\": \"m\", \"translate\": [-0.0, 3, 0]},"
        "{\"type\": \"mesh\", \"file\": \"strips-plain.obj\", \"material\": \"m\", \"scale\": 0.02, "
        "\"translate\": [-1, 0, 0.5], \"emission\": [1, 1, 1]},"
        "{\"type\": \"mesh\", \"file\": \"strips-plain.obj\", \"material\": \"m\", \"smooth_angle\": 50, "
        "\"translate\": [2, 0, 0]}]}");
    char err[512];
    scene *a = load_with(path, "1", err, sizeof err), *b = a ? load_with(path, "3", err, sizeof err) : NULL;
    CHECK(a && b, "%s", err);
    if (a && b) {
        size_t n = a->triangle_count;
        CHECK(n > 3 * (1u << 14) && a->degenerate_triangles > 0, "%zu triangles, %zu skipped: too few to split", n,
              a->degenerate_triangles);
        CHECK(a->triangle_count == b->triangle_count && a->degenerate_triangles == b->degenerate_triangles &&
                  a->light_count == b->light_count,
              "%u/%u triangles, %zu/%zu skipped, %u/%u lights", b->triangle_count, a->triangle_count,
              b->degenerate_triangles, a->degenerate_triangles, b->light_count, a->light_count);
        if (a->triangle_count == b->triangle_count)
            CHECK(memcmp(a->triangles, b->triangles, n * sizeof(triangle)) == 0 &&
                      memcmp(a->triangle_normals, b->triangle_normals, n * sizeof(vec3)) == 0 &&
                      memcmp(a->triangle_info, b->triangle_info, n * sizeof(prim_info)) == 0 &&
                      memcmp(a->world_center, b->world_center, sizeof a->world_center) == 0 &&
                      a->world_scale == b->world_scale &&
                      a->corner_normals && a->triangle_uvs &&
                      a->corner_normals_first == b->corner_normals_first &&
                      a->corner_normal_tris == b->corner_normal_tris &&
                      same_array(a->corner_normals, b->corner_normals, 3 * (size_t)a->corner_normal_tris * sizeof(vec3)) &&
                      same_array(a->triangle_uvs, b->triangle_uvs, 3 * n * sizeof(uint32_t)) &&
                      a->uv_count == b->uv_count &&
                      memcmp(a->uvs, b->uvs, a->uv_count * 2 * sizeof(float)) == 0,
                  "the scenes loaded on 1 and 3 threads differ");
    }
    scene_free(a);
    scene_free(b);
    free(plain.s);
    free(attr.s);
}
