/* test_layers.c - the layering rule of README "Where things are", checked
 * over the #include lines by tests/layers.sh: the real tree passes, and a
 * tree with a net file that includes a render header fails, naming it. */
#include <stdio.h>
#include <string.h>

#include "harness.h"
#include "util.h"

TEST(layers_every_include_stays_within_its_layer) {
    char out[4096];
    int rc = util_run("tests/layers.sh 2>&1", out, sizeof out);
    CHECK(rc == 0, "tests/layers.sh found crossings:\n%s", out);
}

TEST(layers_check_catches_net_including_render) {
    char dir[512], cmd[4096], out[4096];
    snprintf(dir, sizeof dir, "%s", util_temp_path("layers-tree"));
    snprintf(cmd, sizeof cmd,
             "mkdir -p %s/common/net %s/common/render && echo '#include \"render/scene.h\"' > %s/common/net/x.c && "
             "touch %s/common/render/scene.h && tests/layers.sh %s 2>&1",
             dir, dir, dir, dir, dir);
    int rc = util_run(cmd, out, sizeof out);
    CHECK(rc != 0, "a net file including render/scene.h passed the check");
    CHECK(strstr(out, "common/net/x.c:1: net may not include \"render/scene.h\""), "unexpected report: %s", out);
}
