/* test_scene.c - the scene format: every refusal names file and field; OBJ
 * meshes; the CLI's exit statuses and summary line. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "util.h"

#define CAM "\"camera\": {\"type\": \"perspective\", \"position\": [0,0,-5], \"look_at\": [0,0,0], \"fov\": 40}"
#define MATS "\"materials\": {\"white\": {\"type\": \"diffuse\", \"albedo\": [0.5,0.5,0.5]}}"
#define TRI "{\"type\": \"triangle\", \"vertices\": [[0,0,0],[1,0,0],[0,1,0]], \"material\": \"white\"}"

static const struct {
    const char *json;
    const char *expect;
} bad[] = {
    {"{" CAM ",\n  \"shapes\": [ }", "scene.json:2:15: syntax error near '}'"},
    {"{" CAM "," MATS ", \"shapes\": [" TRI ", " TRI ", " TRI ", {\"type\": \"triangle\", \"vertices\": [[0,0,0],[1,0,0],[0,1,0]], \"material\": \"whte\"}]}",
     "scene.json: shapes[3].material: unknown material \"whte\""},
    {"{" CAM "," MATS ", \"shapes\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": -1, \"material\": \"white\"}]}",
     "shapes[0].radius: expected a number from 0 to"},
    {"{" CAM "," MATS ", \"shapes\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 0, \"material\": \"white\"}]}",
     "shapes[0].radius: must be greater than 0"},
    {"{\"render\": {\"width\": 40000}," CAM "}", "render.width: expected an integer from 1 to 32768, got 40000"},
    {"{\"render\": {\"height\": 0}," CAM "}", "render.height: expected an integer from 1 to 32768, got 0"},
    {"{\"render\": {\"spp\": 1.5}," CAM "}", "render.spp: expected an integer"},
    {"{\"render\": {\"roulette_depth\": -1}," CAM "}", "render.roulette_depth: expected an integer from 0 to 1024, got -1"},
    {"{\"render\": {\"roulette_depth\": \"4\"}," CAM "}", "render.roulette_depth: expected an integer"},
    {"{" CAM ", \"background\": [1, 1e999, 0]}", "background: element 1 is not finite"},
    {"{\"camera\": {\"type\": \"perspective\", \"position\": [0,0,0], \"look_at\": [0,0,0], \"fov\": 40}}",
     "camera.look_at: equals the position"},
    {"{\"camera\": {\"type\": \"perspective\", \"position\": [0,0,0], \"look_at\": [0,1,0], \"fov\": 40}}",
     "camera.up: parallel to the view direction"},
    {"{\"camera\": {\"type\": \"perspective\", \"position\": [0,0,0], \"look_at\": [0,0,1], \"up\": [0,0,0], \"fov\": 40}}",
     "camera.up: zero vector cannot be normalised"},
    {"{\"camera\": {\"type\": \"perspective\", \"position\": [0,0,0], \"look_at\": [0,0,1], \"fov\": 180}}",
     "camera.fov: expected degrees between"},
    {"{\"camera\": {\"type\": \"fisheye\", \"position\": [0,0,0]}}", "camera.type: unknown camera type \"fisheye\""},
    {"{\"shapes\": []}", "camera: missing"},
    {"{" CAM ", \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 1.2, 0.5]}}}",
     "materials.m.albedo: element 1 is 1.2, expected a value from 0 to 1"},
    {"{" CAM ", \"materials\": {\"m\": {\"type\": \"glossy\", \"diffuse\": [0.6,0.6,0.6], \"specular\": [0.5,0.5,0.5], \"exponent\": 10}}}",
     "materials.m.specular: diffuse + specular exceeds 1"},
    {"{" CAM ", \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5,0.5,0.5], \"ior\": 1.5}}}",
     "materials.m.ior: not a field of a diffuse material"},
    {"{" CAM ", \"materials\": {\"m\": {\"type\": \"plastic\"}}}", "materials.m.type: unknown material type \"plastic\""},
    {"{" CAM "," MATS ", \"shapes\": [{\"type\": \"triangle\", \"vertices\": [[0,0,0],[1,0,0],[2,0,0]], \"material\": \"white\"}]}",
     "shapes[0].vertices: degenerate triangle (zero area)"},
    {"{" CAM "," MATS ", \"shapes\": [{\"type\": \"quad\", \"vertices\": [[0,0,0],[1,0,0],[1,1,0],[0,1,1]], \"material\": \"white\"}]}",
     "shapes[0].vertices: quad is not planar"},
    {"{" CAM "," MATS ", \"shapes\": [{\"type\": \"quad\", \"vertices\": [[0,0,0],[1,1,0],[1,0,0],[0,1,0]], \"material\": \"white\"}]}",
     "shapes[0].vertices: quad is not convex"},
    {"{" CAM "," MATS ", \"shapes\": [{\"type\": \"triangle\", \"vertices\": [[0,0,0],[1,0,0]], \"material\": \"white\"}]}",
     "shapes[0].vertices: expected an array of 3 points"},
    {"{" CAM "," MATS ", \"shapes\": [{\"type\": \"triangle\", \"vertices\": [[0,0,0],[1,0,0],[0,1,0]]}]}",
     "shapes[0].material: missing (a shape that emits nothing needs a material)"},
    {"{" CAM "," MATS ", \"shapes\": [{\"type\": \"cone\", \"material\": \"white\"}]}", "shapes[0].type: unknown shape type \"cone\""},
    {"{" CAM "," MATS ", \"shapes\": [{\"type\": \"mesh\", \"file\": \"nowhere.obj\", \"material\": \"white\"}]}",
     "shapes[0].file: "},
    {"{" CAM ", \"shapes\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"emission\": [1,-1,1]}]}",
     "shapes[0].emission: element 1 is -1, expected a value from 0 to"},
    {"{" CAM ", \"lights\": [{\"type\": \"spot\", \"position\": [0,0,0], \"intensity\": [1,1,1]}]}",
     "lights[0].type: unknown light type \"spot\""},
    {"{" CAM ", \"lights\": [{\"type\": \"point\", \"position\": [0,0,0]}]}", "lights[0].intensity: missing"},
    {"{" CAM ", \"emission\": 3}", "scene.json: emission: unknown field"},
    {"{\"render\": {\"widht\": 64}," CAM "}", "scene.json: render.widht: unknown field (did you mean render.width?)"},
    {"{\"cammera\": {}}", "scene.json: cammera: unknown field (did you mean camera?)"},
    {"[1, 2]", "(top level): expected an object"},
};

TEST(scene_errors_name_file_and_field) {
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char err[1024] = "";
        scene *s = util_scene_from_text(bad[i].json, err, sizeof err);
        CHECK(s == NULL, "case %zu was accepted", i);
        CHECK(strstr(err, bad[i].expect) != NULL, "case %zu: got \"%s\", want \"%s\"", i, err, bad[i].expect);
        CHECK(strstr(err, "scene.json") != NULL, "case %zu: message does not name the file: %s", i, err);
        scene_free(s);
    }
}

TEST(scene_obj_mesh_and_degenerates) {
    util_write_temp("m.obj", "# a quad, a sliver and a zero-area face\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
                             "vt 0 0\nvn 0 0 1\nvn 0 0 1\nf 1 2 3 4\nf 1/1/1 2/1/2 -1/-1/-1\nf 1 1 2\n");
    char err[512];
    scene *s = util_scene_from_text("{" CAM "," MATS ", \"shapes\": [{\"type\": \"mesh\", \"file\": \"m.obj\", "
                                    "\"material\": \"white\", \"scale\": 2, \"translate\": [1, 0, 0]}]}",
                                    err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    CHECK(s->triangle_count == 2, "want the quad's 2 triangles, got %u", s->triangle_count);
    CHECK(s->degenerate_triangles == 2, "want 2 degenerate triangles skipped, got %zu", s->degenerate_triangles);
    scene_free(s);
    util_write_temp("bad.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n");
    s = util_scene_from_text("{" CAM "," MATS ", \"shapes\": [{\"type\": \"mesh\", \"file\": \"bad.obj\", \"material\": \"white\"}]}",
                             err, sizeof err);
    CHECK(s == NULL && strstr(err, "bad.obj:3: face refers to a vertex that does not exist"), "got: %s", err);
    scene_free(s);
}

TEST(scene_units_are_normalised) {
    /* The same triangle in millimetres and 1e5 units away lands on the same
     * internal coordinates. */
    char err[512];
    scene *a = util_scene_from_text("{" CAM "," MATS ", \"shapes\": [{\"type\": \"triangle\", \"vertices\": "
                                    "[[0,0,0],[100,0,0],[0,100,0]], \"material\": \"white\"}]}", err, sizeof err);
    scene *b = util_scene_from_text("{" CAM "," MATS ", \"shapes\": [{\"type\": \"triangle\", \"vertices\": "
                                    "[[100000,0,0],[100100,0,0],[100000,100,0]], \"material\": \"white\"}]}", err, sizeof err);
    CHECK(a && b, "%s", err);
    if (a && b) CHECK(memcmp(a->triangles, b->triangles, sizeof(triangle)) == 0, "internal geometry differs");
    scene_free(a);
    scene_free(b);
}

TEST(cli_render_and_errors) {
    char out[4096], cmd[1024];
    snprintf(cmd, sizeof cmd, "%s render tests/scenes/cornell-small.json --spp 2 --width 16 --height 16 --workers 0 "
             "-o /tmp/tessera-cli-test.pfm", harness_tessera());
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 0, "render failed (%d): %s", st, out);
    CHECK(strstr(out, "image: /tmp/tessera-cli-test.pfm") && strstr(out, "Msamples/s") && strstr(out, "NaN/Inf"),
          "summary line missing: %s", out);
    CHECK(!strchr(out, '\r'), "a progress bar was drawn without a terminal (plain lines are expected): %s", out);
    const struct {
        const char *args;
        int status;
        const char *expect;
    } cases[] = {
        {"render tests/scenes/nope.json -o /tmp/x.pfm", 1, "nope.json: cannot open"},
        {"render tests/scenes/cornell-small.json -o /tmp/x.bmp --spp 1", 1, "unknown image format \"bmp\""},
        {"render tests/scenes/cornell-small.json -o /nonexistent-dir/x.pfm --spp 1", 1, "/nonexistent-dir/x.pfm: cannot write"},
        {"render tests/scenes/cornell-small.json --spp 0", 2, "--spp: expected an integer from 1"},
        {"render tests/scenes/cornell-small.json --width 40000", 2, "--width: expected an integer from 1 to 32768"},
        {"render", 2, "expected exactly one scene file"},
        {"frobnicate", 2, "unknown command"},
        {"render --help", 0, "--workers N"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        snprintf(cmd, sizeof cmd, "%s %s", harness_tessera(), cases[i].args);
        st = util_run(cmd, out, sizeof out);
        CHECK(st == cases[i].status, "`%s`: status %d, want %d", cases[i].args, st, cases[i].status);
        CHECK(strstr(out, cases[i].expect) != NULL, "`%s`: output lacks \"%s\": %s", cases[i].args, cases[i].expect, out);
    }
}
