/* tessera.c - the `tessera` command: `tessera render SCENE -o OUT [...]`.
 *
 * Parses the command line, loads the scene, renders it - on a local farm
 * of worker processes by default (local_farm.c), or in this process with a
 * thread pool (--workers 0) - saves the image and prints one summary line.
 * Exit status 0 on success, 1 on a runtime failure, 2 on a usage error. */
#define _GNU_SOURCE
#include <errno.h>
#include <signal.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "net/address.h"
#include "args.h"
#include "render/accel.h"
#include "image/image.h"
#include "image/image_compare.h"
#include "image/image_meta.h"
#include "render/render.h"
#include "render/model_files.h"
#include "render/scene.h"
#include "render/scene_memory.h"
#include "version.h"
#include "cli_util.h"
#include "client.h"
#include "local_fork.h"
#include "coordinator/local_farm.h"
#include "coordinator/service.h"
#include "coordinator/membudget.h"
#include "limit.h"
#include "memhint.h"

/* From this many primitives the default local farm gives way to rendering
 * in this process with a thread per core (bench/meshes.sh: at 655k
 * triangles and above two workers each loading the scene were slower than
 * one process). With the workers forked over this process's scene
 * (local_fork.h) the farm loads once too; against one process it was 4%
 * slower in one series at 164k and 655k and not in the next
 * (docs/meshes.md, twenty-seventh session), so the bound stays. */
#define LOCAL_FARM_ONE_WORKER_PRIMITIVES (1u << 19)

typedef struct {
    const char *scene_path;
    const char *out_path;
    scene_overrides ov;
    int threads, threads_given, workers, tile_size, verbose, progress, jpeg_quality, png16;
    int audit_given; /* --audit was on the command line (else the farm's default) */
    int aov_samples; /* --aov samples: also write the per-pixel sample counts */
    int quiet;       /* -q: errors and the summary line only */
    int interrupted; /* the signal that stopped a farm render, or 0 */
    cli_progress_state ps;
    int workers_defaulted; /* local farm sized by tessera, not by --workers */
    int insecure;    /* --insecure: listen beyond loopback without a token */
    const char *listen, *token_file;
    const char *camera; /* --camera NAME: a glTF's camera */
    char listen_host[256];
    const char *http; /* --http ADDR:PORT: watch the render in a browser (coordinator/dashboard.h) */
    dashboard_options web;
    char web_host[256];
    farm_options farm;
    codec_exr_options exr;
    render_options ro;
    tonemap_options tm;
    uint64_t max_memory; /* --max-memory; 0: membudget_default */
} render_args;

static void usage_render(FILE *f) {
    fprintf(f,
            "usage: tessera render SCENE.json|MODEL.glb|MODEL.gltf|MODEL.obj [-o OUT] [options]\n"
            "       tessera render - [-o OUT] [options]   (the scene from stdin; mesh paths\n"
            "                      relative to the current folder; default OUT stdin.png;\n"
            "                      SCENE may also be a pipe, e.g. <(sed ... scene.json);\n"
            "                      a .glb or .gltf through either is known by its content)\n"
            "\n"
            "Render a scene and save the image; the format follows OUT's extension:\n"
            "  .pfm .exr  linear float RGB (HDR); EXR records scene, spp, seed\n"
            "  .ppm .png .jpg .jpeg  8-bit sRGB, tone mapped\n"
            "\n"
            "options:\n"
            "  -o, --output PATH      image to write (default: SCENE's name with .png, in .)\n"
            "      --spp N            samples per pixel (overrides render.spp)\n"
            "      --width W          image width in pixels (overrides render.width)\n"
            "      --height H         image height in pixels (overrides render.height); given\n"
            "                         one of the two, the other keeps the scene's aspect ratio\n"
            "      --max-depth N      maximum bounces (overrides render.max_depth)\n"
            "      --roulette-depth N Russian roulette may end paths from vertex N on, 0 being\n"
            "                         the camera ray's hit (overrides render.roulette_depth,\n"
            "                         default 4; 1 is Cycles' rule)\n"
            "      --seed N           random seed (overrides render.seed)\n"
            "      --camera NAME      glTF: render from this camera (node or camera name; default: the first)\n"
            "      --max-memory SIZE  refuse up front a frame larger than this, e.g. 12G (default:\n"
            "                         3/4 of the RAM or of the cgroup's limit if lower)\n"
            "      --workers N        local worker processes (default: one per core, or none\n"
            "                         for scenes of 2^19 primitives or more: this process\n"
            "                         renders them with a thread per core; with --listen, 0);\n"
            "                         0 without --listen renders in this process\n"
            "      --threads N        threads per local worker (default 1), or render threads\n"
            "                         with --workers 0 (default: all cores)\n"
            "      --listen HOST:PORT also accept remote workers (tessera-worker --connect)\n"
            "      --http ADDR:PORT   watch the render in a browser while it runs (loopback unless\n"
            "                         --token-file or --insecure)\n"
            "                         here; port 0 picks a free one (printed on stderr)\n"
            "      --http-cert F, --http-key F  serve it over HTTPS with this PEM certificate\n"
            "                         chain and private key\n"
            "      --heartbeat S      farm heartbeat interval in seconds (default 1)\n"
            "      --worker-timeout S a silent worker's tiles go to others after S s (default 5)\n"
            "      --lease S          longest a worker may hold one tile (default 300)\n"
            "      --token-file F     workers must prove they know this secret (local ones get it)\n"
            "      --insecure         allow --listen beyond loopback without a token (frames in clear)\n"
            "      --audit FRACTION   render this fraction of tiles (0 to 1, chosen at random;\n"
            "                         default 0.02, 0: off) on two workers and compare the bytes\n"
            "                         (needs 2 workers, 3 to settle a mismatch); a worker that\n"
            "                         differs is quarantined for the job (docs/audit.md)\n"
            "      --blocklist-retry S  a worker that fails, crashes or times out 3 times on a\n"
            "                         job gets none of its tiles for S s (default 60, doubled\n"
            "                         each time it is blocklisted again)\n"
            "      --tile-size N      tile side in pixels (default 32)\n"
            "      --passes N         render each tile's samples in N sequential passes\n"
            "                         (the image is bit-identical for every N)\n"
            "      --tonemap NAME     8-bit outputs: reinhard (default), reinhard-extended,\n"
            "                         photographic, aces or clamp\n"
            "      --white L          white point of reinhard-extended and photographic\n"
            "                         (default: the image's brightest luminance)\n"
            "      --exposure STOPS   scale radiance by 2^STOPS before tone mapping\n"
            "      --quality Q        JPEG quality, 1 to 100 (default 92)\n"
            "      --png16            16-bit PNG instead of 8-bit\n"
            "      --exr-compression C  zip (default), piz or none\n"
            "      --exr-half         16-bit half channels instead of float32\n"
            "      --exr-alpha        add an A channel of 1\n"
            "      --no-nee           no light sampling (for comparisons)\n"
            "      --no-mis           light sampling without MIS (for comparisons)\n"
            "      --sampler S        sobol-global (the default: Owen-scrambled Sobol, jointly\n"
            "                         stratified for the camera and the first two bounces),\n"
            "                         sobol (padded pairs throughout), or random\n"
            "      --noise-threshold E  adaptive sampling: pixels stop once their estimated\n"
            "                         relative error (and their neighbours') is below E\n"
            "      --min-spp N        adaptive: samples every pixel takes first (default 16)\n"
            "      --aov samples      also write the per-pixel sample counts to OUT-stem.samples.pfm\n"
            "      --no-progress      no progress: no bar on a terminal, no lines elsewhere\n"
            "  -q, --quiet            print errors and the final summary line only\n"
            "  -v, --verbose          print scene and BVH statistics\n"
            "  -h, --help             this text\n"
            "\n"
            "Progress goes to stderr: a bar on a terminal, else one plain line every 5 s\n"
            "($TESSERA_PROGRESS_SECONDS). SIGINT or SIGTERM stops the render: the local\n"
            "workers are stopped, remote ones let go of their tiles, no image is written,\n"
            "and the exit status is 130 (143 for SIGTERM).\n");
}

/* arg_spec parsers (args.h) for the options whose values are names. */
static int parse_tonemap_arg(const char *v, void *dest, char *err, size_t n) {
    if (tonemap_parse(v, dest) == 0) return 0;
    snprintf(err, n, "unknown operator \"%s\" (known: %s)", v, TONEMAP_NAMES);
    return -1;
}

static int parse_sampler_arg(const char *v, void *dest, char *err, size_t n) {
    if (sampler_parse(v, dest) == 0) return 0;
    snprintf(err, n, "expected sobol, random or sobol-global, got \"%s\"", v);
    return -1;
}

static int parse_exr_compression_arg(const char *v, void *dest, char *err, size_t n) {
    static const char *const names[] = {"zip", "piz", "none"};
    for (int i = 0; i < 3; i++)
        if (strcmp(v, names[i]) == 0) {
            *(codec_exr_compression *)dest = (codec_exr_compression)i;
            return 0;
        }
    snprintf(err, n, "unknown \"%s\" (known: zip, piz, none)", v);
    return -1;
}

static int parse_aov_arg(const char *v, void *dest, char *err, size_t n) {
    if (strcmp(v, "samples") == 0) return *(int *)dest = 1, 0;
    snprintf(err, n, "the one output on offer is \"samples\", not \"%s\"", v);
    return -1;
}

/* The defaults of `tessera render`, before its options. */
static void render_args_default(render_args *a) {
    memset(a, 0, sizeof *a);
    a->ov.width = a->ov.height = a->ov.spp = a->ov.max_depth = -1;
    a->threads = (int)sysconf(_SC_NPROCESSORS_ONLN);
    a->workers = -1;
    farm_options_default(&a->farm);
    a->tile_size = 32;
    a->ro.passes = 1;
    a->ro.min_spp = 16;
    a->progress = 1;
    a->tm.kind = TONEMAP_REINHARD;
}

/* Refuse output options that do not apply to the output's format (they
 * would be silently ignored). Exits with status 2. */
static void render_args_check_output(const render_args *a) {
    const char *out = a->out_path ? a->out_path : "x.png", *dot = strrchr(out, '.');
    const char *ext = dot ? dot + 1 : "";
    int png = strcasecmp(ext, "png") == 0, jpg = strcasecmp(ext, "jpg") == 0 || strcasecmp(ext, "jpeg") == 0;
    int exr = strcasecmp(ext, "exr") == 0;
    if (a->png16 && !png) args_usage_error("tessera render", "--png16 applies to .png output, not \"%s\"", out);
    if (a->jpeg_quality && !jpg)
        args_usage_error("tessera render", "--quality applies to .jpg output, not \"%s\"", out);
    if ((a->exr.half || a->exr.alpha || a->exr.compression != CODEC_EXR_ZIP) && !exr)
        args_usage_error("tessera render", "--exr-half, --exr-alpha and --exr-compression apply to .exr output, "
                         "not \"%s\"", out);
}

/* Check and complete parsed render options: the listen address, the token,
 * worker count and farm timings. A usage error exits with status 2. */
static void render_args_check(render_args *a) {
    if (a->listen) {
        char err[300];
        if (address_parse(a->listen, a->listen_host, sizeof a->listen_host, &a->farm.port, err, sizeof err))
            args_usage_error("tessera render", "--listen %s", err);
        a->farm.host = a->listen_host;
    }
    a->workers_defaulted = a->workers < 0 && !a->listen;
    char herr[300];
    if (a->http && dashboard_parse_address(a->http, &a->web, a->web_host, sizeof a->web_host, herr, sizeof herr))
        args_usage_error("tessera render", "--http %s", herr);
    if (!a->http && (a->web.tls_cert || a->web.tls_key))
        args_usage_error("tessera render", "--http-cert and --http-key serve --http: give --http ADDR:PORT");
    if (a->workers < 0) a->workers = a->listen ? 0 : (int)sysconf(_SC_NPROCESSORS_ONLN);
    if (a->http && !a->listen && a->workers == 0)
        args_usage_error("tessera render", "--http watches a farm render: not with --workers 0 and no --listen");
    char terr[300];
    if (a->token_file && auth_keyring_load(&a->farm.auth, a->token_file, NULL, NULL, NULL, terr, sizeof terr))
        args_usage_error("tessera render", "--token-file %s", terr);
    if (!(a->farm.heartbeat_s < a->farm.timeout_s))
        args_usage_error("tessera render", "--worker-timeout (%g s) must be longer than --heartbeat (%g s)",
                         a->farm.timeout_s, a->farm.heartbeat_s);
    if (a->listen && !a->token_file && !a->insecure && !address_is_loopback(a->listen_host))
        args_usage_error("tessera render", "--listen %s without --token-file: links would be in clear beyond "
                         "this machine; add --token-file F, or --insecure on a network you trust", a->listen);
    if (a->farm.audit > 0 && !a->listen && a->workers < 2) { /* nothing to compare a tile with */
        if (a->audit_given || a->verbose)
            fprintf(stderr, "tessera render: no audit: %s (--audit needs two workers or more)\n",
                    a->workers ? "one worker leaves no second one to render a tile again"
                               : "--workers 0 renders in this process");
        a->farm.audit = 0;
    }
    render_args_check_output(a);
    if (a->farm.drop_s < 6 * a->farm.timeout_s) a->farm.drop_s = 6 * a->farm.timeout_s;
    if (a->tile_size > a->farm.max_tile_side) a->farm.max_tile_side = a->tile_size;
}


/* Parse `tessera render`'s arguments (argv[0] is "render") into a; a usage
 * error exits with status 2 (args.h). */
static void parse_render_args(int argc, char **argv, render_args *a) {
    int no_progress = 0;
    render_args_default(a);
    const arg_spec opts[] = {
        {.name = "output", .short_name = 'o', .kind = ARG_STRING, .dest = &a->out_path},
        {.name = "spp", .kind = ARG_INT, .dest = &a->ov.spp, .lo = 1, .hi = LIMIT_SPP},
        {.name = "width", .kind = ARG_INT, .dest = &a->ov.width, .lo = 1, .hi = LIMIT_SIDE},
        {.name = "height", .kind = ARG_INT, .dest = &a->ov.height, .lo = 1, .hi = LIMIT_SIDE},
        {.name = "max-depth", .kind = ARG_INT, .dest = &a->ov.max_depth, .lo = 1, .hi = LIMIT_DEPTH},
        {.name = "roulette-depth", .kind = ARG_INT, .dest = &a->ov.roulette_depth, .lo = 0, .hi = LIMIT_DEPTH,
         .given = &a->ov.has_roulette_depth},
        {.name = "seed", .kind = ARG_U64, .dest = &a->ov.seed, .given = &a->ov.has_seed},
        {.name = "threads", .kind = ARG_INT, .dest = &a->threads, .lo = 1, .hi = 1024, .given = &a->threads_given},
        {.name = "workers", .kind = ARG_INT, .dest = &a->workers, .lo = 0, .hi = 4096},
        {.name = "max-memory", .kind = ARG_CUSTOM, .dest = &a->max_memory, .parse = membudget_parse},
        {.name = "listen", .kind = ARG_STRING, .dest = &a->listen},
        {.name = "http", .kind = ARG_STRING, .dest = &a->http},
        {.name = "http-cert", .kind = ARG_STRING, .dest = &a->web.tls_cert},
        {.name = "http-key", .kind = ARG_STRING, .dest = &a->web.tls_key},
        {.name = "token-file", .kind = ARG_STRING, .dest = &a->token_file},
        {.name = "camera", .kind = ARG_STRING, .dest = &a->camera},
        {.name = "audit", .kind = ARG_DOUBLE, .dest = &a->farm.audit, .lo = 0, .hi = 1, .given = &a->audit_given},
        {.name = "blocklist-retry", .kind = ARG_DOUBLE, .dest = &a->farm.blocklist_s, .lo = 0.1, .hi = 1e7},
        {.name = "insecure", .kind = ARG_FLAG, .dest = &a->insecure},
        {.name = "heartbeat", .kind = ARG_DOUBLE, .dest = &a->farm.heartbeat_s, .lo = 0.01, .hi = 3600},
        {.name = "worker-timeout", .kind = ARG_DOUBLE, .dest = &a->farm.timeout_s, .lo = 0.05, .hi = 86400},
        {.name = "lease", .kind = ARG_DOUBLE, .dest = &a->farm.lease_s, .lo = 0.1, .hi = 1e7},
        {.name = "tile-size", .kind = ARG_INT, .dest = &a->tile_size, .lo = 1, .hi = 4096},
        {.name = "passes", .kind = ARG_INT, .dest = &a->ro.passes, .lo = 1, .hi = LIMIT_SPP},
        {.name = "tonemap", .kind = ARG_CUSTOM, .dest = &a->tm.kind, .parse = parse_tonemap_arg},
        {.name = "white", .kind = ARG_FLOAT, .dest = &a->tm.white, .lo = 1e-6, .hi = 1e30},
        {.name = "exposure", .kind = ARG_FLOAT, .dest = &a->tm.exposure_stops, .lo = -64, .hi = 64},
        {.name = "quality", .kind = ARG_INT, .dest = &a->jpeg_quality, .lo = 1, .hi = 100},
        {.name = "png16", .kind = ARG_FLAG, .dest = &a->png16},
        {.name = "exr-compression", .kind = ARG_CUSTOM, .dest = &a->exr.compression, .parse = parse_exr_compression_arg},
        {.name = "exr-half", .kind = ARG_FLAG, .dest = &a->exr.half},
        {.name = "exr-alpha", .kind = ARG_FLAG, .dest = &a->exr.alpha},
        {.name = "no-nee", .kind = ARG_FLAG, .dest = &a->ro.integrator.no_nee},
        {.name = "no-mis", .kind = ARG_FLAG, .dest = &a->ro.integrator.no_mis},
        {.name = "sampler", .kind = ARG_CUSTOM, .dest = &a->ro.integrator.sampler, .parse = parse_sampler_arg},
        {.name = "noise-threshold", .kind = ARG_DOUBLE, .dest = &a->ro.noise_threshold, .lo = 1e-6, .hi = 1e6},
        {.name = "min-spp", .kind = ARG_INT, .dest = &a->ro.min_spp, .lo = 2, .hi = LIMIT_SPP},
        {.name = "aov", .kind = ARG_CUSTOM, .dest = &a->aov_samples, .parse = parse_aov_arg},
        {.name = "no-progress", .kind = ARG_FLAG, .dest = &no_progress},
        {.name = "verbose", .short_name = 'v', .kind = ARG_FLAG, .dest = &a->verbose},
        {.name = "quiet", .short_name = 'q', .kind = ARG_FLAG, .dest = &a->quiet},
        {NULL}};
    const char *scene[1];
    if (args_parse("tessera render", argc, argv, opts, usage_render, scene, 1) != 1)
        args_usage_error("tessera render", "expected exactly one scene file");
    a->scene_path = scene[0];
    a->progress = !no_progress && !a->quiet;
    a->web.insecure = a->insecure; /* one --insecure for the farm and the dashboard */
    if (a->quiet) a->verbose = 0;
    cli_progress_init(&a->ps);
    render_args_check(a);
}

static double now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct {
    double start;
    uint64_t total_samples;
    cli_progress_state *ps;
} progress_state;

/* The threaded renderer's progress: tiles, samples/s, ETA. */
static void show_progress(void *ctx, int done, int total, const trace_stats *so_far) {
    progress_state *p = ctx;
    double el = now_seconds() - p->start;
    double rate = el > 0 ? (double)so_far->samples / el : 0;
    double eta = rate > 0 ? (double)(p->total_samples - so_far->samples) / rate : 0;
    cli_progress_show(p->ps, done, total, rate, -1, eta, done == total);
}

/* -v's line for the wide BVH: its walk, who built it, its size. */
static void print_wide_stats(const accel_wide_stats *ws) {
    char how[192];
    if (ws->build_threads)
        snprintf(how, sizeof how, "Tessera's %s build on %d thread%s", ws->builder, ws->build_threads,
                 ws->build_threads == 1 ? "" : "s");
    else
        snprintf(how, sizeof how, "Embree's %s build, device \"%s\"", ws->builder, ws->config);
    char spare[96] = "";
    if (ws->spare_bytes)
        snprintf(spare, sizeof spare, " (%.1f MiB of the loader's freed buffers offered)",
                 (double)ws->spare_bytes / 1048576.0);
    fprintf(stderr, "intersector: wide (%d-wide BVH, Tessera's %s walk and tests; %s), %zu nodes (%zu of %d slots), "
            "%zu leaves, %.1f KiB%s%s, peak %.1f KiB while building, built in %.3f ms\n", ws->node_width, ws->walk_isa,
            how, ws->node_count, ws->wide_node_count, ws->node_width, ws->leaf_count, (double)ws->memory_bytes / 1024.0,
            ws->huge_pages ? " on huge pages" : "", spare, (double)ws->peak_bytes / 1024.0, ws->build_seconds * 1e3);
}

/* -v's line for the page figures (memhint.h), when a big buffer asked for them. */
static void print_page_probe(void) {
    double small, huge, sampled = memhint_sampled_ms();
    memhint_probe_ms(&small, &huge);
    if (small < 0.0 && huge < 0.0) return;
    char latest[96] = "";
    if (sampled >= 0.0) snprintf(latest, sizeof latest, ", %.1f ms on huge pages in the latest big buffer", sampled);
    fprintf(stderr, "pages: a first touch of %zu MiB took %.1f ms on 4 KiB pages, %.1f ms on huge pages%s: big "
            "buffers %s\n", MEMHINT_PROBE_BYTES >> 20, small, huge, latest,
            memhint_huge_is_cheap() ? "on huge pages" : "on huge pages only for a long render");
}

static void print_scene_info(const scene *s) {
    bvh_stats bs;
    accel_embree_stats es;
    accel_wide_stats ws;
    char features[256];
    scene_feature_names(s->features, features, sizeof features);
    fprintf(stderr, "scene %s: %u triangles, %u spheres, %u lights, %u materials, %zu degenerate triangles skipped\n",
            s->path, s->triangle_count, s->sphere_count, s->light_count, s->material_count - 1,
            s->degenerate_triangles);
    fprintf(stderr, "features: %s\n", features);
    if (!s->accel)
        fprintf(stderr, "intersector: built by each worker (their \"scene ... loaded\" lines below name it)\n");
    else if (accel_get_wide_stats(s->accel, &ws) == 0)
        print_wide_stats(&ws), print_page_probe();
    else if (accel_get_embree_stats(s->accel, &es) == 0)
        fprintf(stderr, "intersector: embree (Tessera's tests at the leaves; device \"%s\"), %.1f KiB, peak %.1f KiB "
                "while building, built in %.3f ms\n", es.config, (double)es.final_bytes / 1024.0,
                (double)es.memory_bytes / 1024.0, es.build_seconds * 1e3);
    else if (accel_get_bvh_stats(s->accel, &bs) == 0)
        fprintf(stderr, "intersector: bvh, %zu nodes, %zu leaves, depth %zu, %.1f KiB, built in %.3f ms\n",
                bs.node_count, bs.leaf_count, bs.max_depth, (double)bs.memory_bytes / 1024.0,
                bs.build_seconds * 1e3);
    else
        fprintf(stderr, "intersector: flat (every triangle, %d at a time; no tree for %u triangles)\n", accel_flat_lanes(s->accel),
                s->triangle_count);
    fprintf(stderr, "render: %dx%d, %d spp, max depth %d, roulette from vertex %d, seed %llu\n", s->settings.width,
            s->settings.height, s->settings.spp, s->settings.max_depth, s->settings.roulette_depth,
            (unsigned long long)s->settings.seed);
}

/* Render in this process with a thread pool. Returns 0 or -1 (printed). */
static int render_in_process(render_args *a, const scene *s, image *img, trace_stats *st) {
    progress_state ps = {now_seconds(),
                         (uint64_t)s->settings.width * (uint64_t)s->settings.height * (uint64_t)s->settings.spp,
                         &a->ps};
    a->ro.threads = a->threads;
    a->ro.tile_size = a->tile_size;
    if (a->progress) {
        a->ro.progress = show_progress;
        a->ro.progress_ctx = &ps;
    }
    if (render_frame(s, &a->ro, img->rgb, st) == 0) return 0;
    fprintf(stderr, "tessera: could not start %d render threads\n", a->threads);
    return -1;
}

/* local_farm_options.progress: the bar on stderr. */
static void farm_progress(void *ctx, int done, int total, double samples_per_s, int workers, double eta_s,
                          int final) {
    cli_progress_show(ctx, done, total, samples_per_s, workers, eta_s, final);
}

/* Render on a farm: local worker processes and/or remote ones. Returns 0 or
 * -1 (printed). */
static int render_on_farm(render_args *a, scene *s, const scene_bundle *b, image *img, trace_stats *st) {
    size_t len;
    uint8_t *bytes = scene_bundle_serialise(b, &len);
    if (!bytes) {
        fprintf(stderr, "tessera: %s: the scene and its meshes are too large to send (over %u MiB)\n",
                a->scene_path, SCENE_BUNDLE_MAX_BYTES >> 20);
        return -1;
    }
    proto_job job = {.id = 1, .width = s->settings.width, .height = s->settings.height, .spp = s->settings.spp,
                     .max_depth = s->settings.max_depth, .roulette_depth = s->settings.roulette_depth,
                     .seed = s->settings.seed,
                     .integrator = a->ro.integrator, .adaptive = a->ro.noise_threshold > 0};
    scene_bundle_hash(bytes, len, job.scene_hash);
    local_farm_options lo = {.workers = a->workers, .threads_per_worker = a->threads_given ? a->threads : 1,
                             .tile_size = a->tile_size, .farm = a->farm, .listening = a->listen != NULL,
                             .token_file = a->token_file,
                             .progress = a->progress ? farm_progress : NULL, .progress_ctx = &a->ps,
                             .verbose = a->verbose,
                             .noise_threshold = a->ro.noise_threshold, .min_spp = a->ro.min_spp,
                             .samples = a->ro.samples};
    lo.farm.verbose = a->verbose;
    if (a->http) lo.http = &a->web;
    local_farm_report rep = {0};
    char err[700];
    /* This process built the intersector (local_fork_wanted): the local
     * workers start as forks of it, holding both. */
    local_farm_forked *forked = s->accel && a->workers > 0 ? calloc((size_t)a->workers, sizeof *forked) : NULL;
    if (forked) {
        local_fork_options fo = {.workers = a->workers, .threads = lo.threads_per_worker, .verbose = a->verbose,
                                 .quiet = !a->verbose, .token_file = a->token_file};
        if (local_fork_workers(&fo, s, job.scene_hash, forked, err, sizeof err) == 0) {
            lo.forked = forked;
            if (a->verbose)
                fprintf(stderr, "local workers: %d forked from this process, holding its scene and intersector "
                        "(shared pages, not loaded again)\n", a->workers);
        } else {
            fprintf(stderr, "tessera: %s; starting tessera-worker instead\n", err);
        }
    }
    int rc = local_farm_render(&lo, &job, bytes, len, img->rgb, &rep, err, sizeof err);
    free(forked);
    free(bytes);
    if (rc && rep.interrupted) {
        a->interrupted = rep.interrupted;
        fprintf(stderr, "tessera: %s: the workers were stopped; no image written\n", err);
        return -1;
    }
    if (rc) {
        fprintf(stderr, "tessera: %s\n", err);
        return -1;
    }
    *st = rep.stats;
    if (a->verbose)
        fprintf(stderr,
                "farm: %d tiles, coordinator CPU %.3f s, %.0f bytes in and %.0f out per tile, "
                "%llu requeued, %llu backups, %llu duplicates dropped\n",
                rep.tiles, rep.coordinator_cpu_s, (double)rep.bytes_in / rep.tiles,
                (double)rep.bytes_out / rep.tiles, (unsigned long long)rep.requeued,
                (unsigned long long)rep.backups, (unsigned long long)rep.duplicates);
    return 0;
}

/* What a render of s needs (the frame, its saved copy, adaptive counts,
 * and scene_bytes for the scene's load and build) and, in *budget, what
 * --max-memory or the machine allows (how: which, for messages). */
static uint64_t render_memory_need(const render_args *a, const scene *s, uint64_t scene_bytes, uint64_t *budget,
                                   char *how, size_t how_len) {
    *budget = a->max_memory ? a->max_memory : membudget_default(how, how_len);
    uint64_t px = (uint64_t)s->settings.width * (uint64_t)s->settings.height;
    return membudget_job_bytes(s->settings.width, s->settings.height, 0, scene_bytes) +
           (a->ro.noise_threshold > 0 ? px * sizeof(float) : 0);
}

/* Whether the local workers are to be forked from this process over the
 * scene and an intersector it builds: a farm with local workers, the
 * worker program not named ($TESSERA_WORKER: that program is run), not
 * turned off ($TESSERA_LOCAL_FORK=0), and the scene passing a worker's
 * memory check and the build fitting --max-memory (if not, each worker
 * loads and checks for itself, and says why it cannot). */
static int local_fork_wanted(const render_args *a, const scene_bundle *b, const scene *s) {
    const char *exe = getenv("TESSERA_WORKER"), *off = getenv("TESSERA_LOCAL_FORK");
    char why[300];
    if (a->workers <= 0 || (exe && *exe) || (off && strcmp(off, "0") == 0)) return 0;
    if (scene_memory_check(b, why, sizeof why)) return 0; /* what a worker checks: let each say so */
    char how[160];
    uint64_t tris, budget;
    return render_memory_need(a, s, scene_memory_estimate_loaded(b, s->triangle_count, &tris), &budget, how,
                              sizeof how) <= budget;
}

/* The image could not be written to OUT (a full disk, a folder removed
 * while rendering): keep the render as a linear EXR with the header saved
 * (the attributes of `saved`) in $TMPDIR (else /tmp), then in the current
 * folder, and say where, so the work is not lost. Prints what it did;
 * can't fail otherwise. */
static void keep_unsaved_render(const render_args *a, const image *img, const image_write_options *saved) {
    const char *tmpdir = getenv("TMPDIR"), *base = strrchr(a->out_path, '/');
    const char *folders[2] = {tmpdir && tmpdir[0] ? tmpdir : "/tmp", "."};
    base = base ? base + 1 : a->out_path;
    const char *dot = strrchr(base, '.');
    int stem = dot ? (int)(dot - base) : (int)strlen(base);
    for (int i = 0; i < 2; i++) {
        char path[1024], err[1024];
        snprintf(path, sizeof path, "%s/%.*s-unsaved-%ld.exr", folders[i], stem, base, (long)getpid());
        /* float32, ZIP, whatever OUT asked for */
        image_write_options wo = {.exr = {.attrs = saved->exr.attrs, .attr_count = saved->exr.attr_count}};
        if (image_write(path, img, &wo, err, sizeof err) == 0) {
            fprintf(stderr, "tessera: the render is kept in %s (linear); `tessera tonemap %s -o OUT` writes it out\n",
                    path, path);
            return;
        }
        fprintf(stderr, "tessera: %s\n", err);
    }
    fprintf(stderr, "tessera: the render could not be kept anywhere\n");
}

static int save_image(const render_args *a, const scene *s, const image *img) {
    /* No time or host in the file: the same render gives the same bytes. */
    char err[1024];
    image_write_options wo = {.tonemap = a->tm, .jpeg_quality = a->jpeg_quality, .png16 = a->png16, .exr = a->exr};
    image_meta meta;
    image_meta_apply(&meta, strcmp(a->scene_path, "-") ? a->scene_path : "<stdin>", s->settings.spp, s->settings.seed,
                     &wo);
    if (image_write(a->out_path, img, &wo, err, sizeof err) == 0) return 0;
    fprintf(stderr, "tessera: %s\n", err);
    keep_unsaved_render(a, img, &wo);
    return -1;
}

/* Write the per-pixel sample counts next to the image, as OUT-stem.samples.pfm
 * (counts in all three channels). Returns 0 or -1 (printed); the path goes
 * to path. */
static int save_samples_aov(const render_args *a, const scene *s, const float *samples, char *path, size_t len) {
    const char *dot = strrchr(a->out_path, '.'), *slash = strrchr(a->out_path, '/');
    int stem = dot && (!slash || dot > slash) ? (int)(dot - a->out_path) : (int)strlen(a->out_path);
    snprintf(path, len, "%.*s.samples.pfm", stem, a->out_path);
    image img;
    char err[1024];
    if (image_alloc(&img, s->settings.width, s->settings.height)) {
        fprintf(stderr, "tessera: out of memory for the samples image\n");
        return -1;
    }
    for (size_t i = 0; i < (size_t)s->settings.width * (size_t)s->settings.height; i++)
        img.rgb[3 * i] = img.rgb[3 * i + 1] = img.rgb[3 * i + 2] = samples[i];
    image_write_options wo = {.tonemap = {.kind = TONEMAP_CLAMP}}; /* PFM: not tone mapped */
    int rc = image_write(path, &img, &wo, err, sizeof err);
    if (rc) fprintf(stderr, "tessera: %s\n", err);
    image_free(&img);
    return rc ? -1 : 0;
}

/* Refuse up front a render this process cannot hold: its frame, the image
 * encoder's copy (membudget_job_bytes), the per-pixel sample counts of an
 * adaptive render and, rendering here, the scene (scene_bytes:
 * scene_memory.h's estimate of the load and build of its `triangles`; 0
 * on a farm, whose workers check their own), against --max-memory or the
 * default budget (membudget.h). Returns 0, or 1 (printed, with the
 * figures). */
static int render_fits_memory(const render_args *a, const scene *s, uint64_t scene_bytes, uint64_t triangles) {
    char how[160] = "--max-memory", need_s[32], budget_s[32], what[160] = "";
    uint64_t budget, need = render_memory_need(a, s, scene_bytes, &budget, how, sizeof how);
    if (need <= budget) return 0;
    membudget_format(need, need_s, sizeof need_s);
    membudget_format(budget, budget_s, sizeof budget_s);
    if (triangles)
        snprintf(what, sizeof what, " and the scene's %llu triangles (their load and build, estimated) need",
                 (unsigned long long)triangles);
    fprintf(stderr, "tessera: a %dx%d frame%s %s (with the saved image's copy), --max-memory is %s%s%s%s; render "
            "a smaller frame or raise --max-memory\n", s->settings.width, s->settings.height,
            triangles ? what : " needs", need_s, budget_s, a->max_memory ? "" : " (", a->max_memory ? "" : how,
            a->max_memory ? "" : ")");
    return 1;
}

static int cmd_render(int argc, char **argv) {
    render_args a;
    char err[1024], out_default[512];
    parse_render_args(argc, argv, &a);
    if (!a.out_path) {
        cli_default_output(a.scene_path, out_default, sizeof out_default);
        a.out_path = out_default;
    }
    /* Before any work: a render whose image has nowhere to go is lost. */
    if (image_check_path(a.out_path, err, sizeof err)) {
        fprintf(stderr, "tessera: %s (nothing rendered)\n", err);
        return 1;
    }
    scene_bundle b;
    cli_note_terminal_scene(a.scene_path);
    if (scene_bundle_read(a.scene_path, &b, err, sizeof err) ||
        (a.camera && model_bundle_select_camera(&b, a.camera, err, sizeof err))) {
        fprintf(stderr, "tessera: %s\n", err);
        if (a.camera) scene_bundle_free(&b);
        return 1;
    }
    a.ov.no_accel = 1; /* the workers build their own; this process, below, if it renders */
    a.ov.keep_spare = 1; /* for that build; released below when there is none */
    scene *s = scene_load_bundle(&b, &a.ov, err, sizeof err);
    if (!s) {
        fprintf(stderr, "tessera: %s\n", err);
        scene_bundle_free(&b);
        return 1;
    }
    if (a.verbose && (a.ov.width > 0) != (a.ov.height > 0))
        fprintf(stderr, "size: %dx%d: --%s given alone, so the %s keeps the scene's aspect ratio\n",
                s->settings.width, s->settings.height, a.ov.width > 0 ? "width" : "height",
                a.ov.width > 0 ? "height" : "width");
    /* A big scene renders in this process with a thread per core (same
     * bytes): faster than the farm's processes, even forked. A farm that
     * was asked for (--workers, --threads, --listen, --http) stays one. */
    int rc = 0;
    if (a.workers_defaulted && !a.threads_given && !a.http && a.workers > 1 &&
        s->triangle_count + s->sphere_count >= LOCAL_FARM_ONE_WORKER_PRIMITIVES) {
        a.threads = a.workers;
        a.threads_given = 1;
        a.workers = 0;
        if (a.verbose)
            fprintf(stderr, "no local farm: %u primitives are rendered in this process with %d threads (the scene "
                    "is loaded once, not again by a worker)\n", s->triangle_count + s->sphere_count, a.threads);
    }
    int farm_mode = a.listen || a.workers > 0;
    /* Rendering here: the frame and the scene's build must fit, checked
     * before the build (the load's peak) rather than found by the kernel. */
    uint64_t scene_tris = 0, scene_bytes = farm_mode ? 0 : scene_memory_estimate_loaded(&b, s->triangle_count, &scene_tris);
    if (!farm_mode && render_fits_memory(&a, s, scene_bytes, scene_tris)) rc = -1;
    if (!farm_mode && rc == 0) {
        scene_bundle_free_keeping(&b, s); /* the scene has what it needs: the mesh files' text goes before the build */
        if (scene_build_accel(s, err, sizeof err)) {
            fprintf(stderr, "tessera: %s\n", err);
            rc = -1;
        }
    }
    if (rc == 0 && farm_mode && local_fork_wanted(&a, &b, s) && scene_build_accel(s, err, sizeof err)) {
        fprintf(stderr, "tessera: %s\n", err);
        rc = -1;
    }
    scene_release_spare(s); /* no build here (a farm's workers build theirs), or done */
    if (a.verbose) print_scene_info(s);
    image img = {0};
    if (rc == 0 && farm_mode) rc = render_fits_memory(&a, s, 0, 0);
    if (rc == 0 && image_alloc(&img, s->settings.width, s->settings.height)) {
        fprintf(stderr, "tessera: out of memory for a %dx%d image\n", s->settings.width, s->settings.height);
        rc = -1;
    }
    trace_stats st = {0};
    float *samples = NULL;
    if (rc == 0 && a.ro.noise_threshold > 0) {
        samples = calloc((size_t)s->settings.width * (size_t)s->settings.height, sizeof *samples);
        if (!samples) rc = -1;
        a.ro.samples = samples;
    } else if (a.aov_samples) {
        fprintf(stderr, "tessera: --aov samples needs --noise-threshold (without it every pixel takes %d)\n",
                s->settings.spp);
        rc = -1;
    }
    double t0 = now_seconds();
    if (rc == 0) rc = farm_mode ? render_on_farm(&a, s, &b, &img, &st) : render_in_process(&a, s, &img, &st);
    double secs = now_seconds() - t0;
    if (rc == 0) rc = save_image(&a, s, &img);
    char aov_path[600] = "";
    if (rc == 0 && a.aov_samples) rc = save_samples_aov(&a, s, samples, aov_path, sizeof aov_path);
    if (rc == 0)
        printf("rendered %s: %.2f s, %.3f Msamples/s, %.2f Mrays/s, %llu NaN/Inf samples, image: %s%s%s\n",
               strcmp(a.scene_path, "-") ? a.scene_path : "<stdin>", secs, (double)st.samples / secs / 1e6,
               (double)(st.rays + st.shadow_rays) / secs / 1e6, (unsigned long long)st.bad_samples, a.out_path,
               aov_path[0] ? ", samples: " : "", aov_path);
    if (rc == 0 && samples)
        printf("adaptive: %.1f samples per pixel on average (%d to %d), threshold %g\n",
               (double)st.samples / ((double)s->settings.width * s->settings.height),
               a.ro.min_spp < s->settings.spp ? a.ro.min_spp : s->settings.spp, s->settings.spp,
               a.ro.noise_threshold);
    free(samples);
    if (img.rgb) image_free(&img);
    scene_free(s);
    scene_bundle_free(&b);
    return a.interrupted ? 128 + a.interrupted : rc ? 1 : 0;
}

static void usage_tonemap(FILE *f) {
    fprintf(f,
            "usage: tessera tonemap IN.exr|IN.pfm -o OUT [--tonemap NAME] [--exposure STOPS] [--white L] [--quality Q]\n"
            "                       [--png16]\n"
            "\n"
            "Tone map a saved HDR image (.exr, .pfm) again without rendering; OUT's extension\n"
            "names the format (.png .jpg .jpeg .ppm, or .pfm/.exr to convert).\n"
            "Operators: %s.\n", TONEMAP_NAMES);
}

/* `tessera tonemap`: read an HDR image, write it with new tone mapping. */
static int cmd_tonemap(int argc, char **argv) {
    image_write_options wo = {.tonemap = {.kind = TONEMAP_REINHARD}};
    const char *out = NULL, *in[1];
    const arg_spec opts[] = {
        {.name = "output", .short_name = 'o', .kind = ARG_STRING, .dest = &out},
        {.name = "tonemap", .kind = ARG_CUSTOM, .dest = &wo.tonemap.kind, .parse = parse_tonemap_arg},
        {.name = "exposure", .kind = ARG_FLOAT, .dest = &wo.tonemap.exposure_stops, .lo = -64, .hi = 64},
        {.name = "white", .kind = ARG_FLOAT, .dest = &wo.tonemap.white, .lo = 1e-6, .hi = 1e30},
        {.name = "quality", .kind = ARG_INT, .dest = &wo.jpeg_quality, .lo = 1, .hi = 100},
        {.name = "png16", .kind = ARG_FLAG, .dest = &wo.png16},
        {NULL}};
    if (args_parse("tessera tonemap", argc, argv, opts, usage_tonemap, in, 1) != 1 || !out)
        args_usage_error("tessera tonemap", "expected one input image and -o OUT");
    char err[1024];
    image img;
    image_meta meta; /* an EXR input's tessera:* header goes to the output too */
    int read_rc = image_read(in[0], &img, err, sizeof err);
    if (read_rc == 0) image_meta_from_exr(&meta, in[0], &wo);
    if (read_rc != 0 || image_write(out, &img, &wo, err, sizeof err) != 0) {
        fprintf(stderr, "tessera: %s\n", err);
        image_free(&img);
        return 1;
    }
    printf("tone mapped %s: %zu NaN/Inf pixels written black, image: %s\n", in[0], wo.bad_pixels, out);
    image_free(&img);
    return 0;
}

/* `tessera compare IMAGE REFERENCE`: error measures for benchmarks. */
static void usage_compare(FILE *f) {
    fprintf(f, "usage: tessera compare IMAGE REFERENCE   (.pfm, .exr or .ppm)\n"
               "prints rmse, relmse = mean (x-ref)^2/(ref^2+0.01), max |x-ref|\n");
}

static int cmd_compare(int argc, char **argv) {
    const arg_spec none[] = {{NULL}};
    const char *files[2];
    if (args_parse("tessera compare", argc, argv, none, usage_compare, files, 2) != 2)
        args_usage_error("tessera compare", "expected an image and a reference");
    argv[1] = (char *)files[0], argv[2] = (char *)files[1];
    image a = {0}, r = {0};
    image_error e;
    char err[1024];
    int rc = image_read(argv[1], &a, err, sizeof err) || image_read(argv[2], &r, err, sizeof err);
    if (rc) fprintf(stderr, "tessera: %s\n", err);
    if (!rc && image_compare(&a, &r, &e)) {
        fprintf(stderr, "tessera: %s is %dx%d but %s is %dx%d\n", argv[1], a.width, a.height, argv[2], r.width,
                r.height);
        rc = 1;
    }
    if (!rc)
        printf("rmse %.6g relmse %.6g max %.6g nonfinite %ld\n", e.rmse, e.relmse, e.max_abs, e.nonfinite);
    if (a.rgb) image_free(&a);
    if (r.rgb) image_free(&r);
    return rc ? 1 : 0;
}

static void usage_coordinator(FILE *f) {
    fprintf(f,
            "usage: tessera-coordinator --data-dir DIR [--listen HOST:PORT] [options]\n"
            "       (or: tessera coordinator ...)\n"
            "\n"
            "Run the render service until SIGINT/SIGTERM: workers (tessera-worker --connect)\n"
            "and clients (tessera submit/status/workers/cancel/fetch) connect to HOST:PORT.\n"
            "Jobs and finished tiles are journaled in DIR; a restarted service resumes them.\n"
            "\n"
            "options:\n"
            "      --listen HOST:PORT   where to listen (default 127.0.0.1:7000)\n"
            "      --data-dir DIR       journal, uploaded scenes and results (required)\n"
            "      --tile-size N        tile side in pixels (default 32)\n"
            "      --max-upload MIB     largest scene plus meshes a client may send (default 64)\n"
            "      --max-jobs N         queued and running jobs at once (default 100)\n"
            "      --keep-hours H       delete finished jobs after H hours (default 24)\n"
            "      --keep-jobs N        keep at most N finished jobs, oldest deleted first (default 1000)\n"
            "      --client-timeout S   close a client that sends nothing for S s (default 30), and a\n"
            "                           connection without a hello after S s or 10 s if sooner\n"
            "      --max-memory SIZE    memory for admitted jobs' frames and scenes, e.g. 12G; a job\n"
            "                           waits until it fits, or is refused if it never can (default:\n"
            "                           3/4 of the RAM or of the cgroup's limit if lower)\n"
            "      --max-connections N  connections at once, workers and clients (default: the\n"
            "                           descriptor limit less a reserve for files, at most 10000)\n"
            "      --max-per-address N  connections from one address before a worker hello or as\n"
            "                           clients (default: an eighth of the total, 16 to 1024)\n"
            "      --max-workers-per-address N  workers from one address (default: half the total)\n"
            "      --token-file F       workers and clients must prove they know this secret\n"
            "      --worker-token-file F, --client-token-file F\n"
            "                           separate secrets: a worker token only renders tiles, a client\n"
            "                           token only submits, watches, fetches and cancels its own jobs\n"
            "      --admin-token-file F a client with this one may cancel and fetch any job\n"
            "      --client-tokens DIR  a token per user: DIR/NAME.token lets its holder, and only\n"
            "                           its holder, act as client NAME (--client-name NAME)\n"
            "                           (SIGHUP re-reads every token file; docs/security.md)\n"
            "      --worker-drop S      disconnect a worker silent (or trickling a frame) for S s\n"
            "                           (default 30, or 6 x --worker-timeout if longer)\n"
            "      --heartbeat S, --worker-timeout S, --lease S, --audit FRACTION (default 0.02),\n"
            "      --blocklist-retry S, --insecure\n"
            "                           as for tessera render\n"
            "      --http ADDR:PORT     serve the web dashboard and /metrics there (loopback unless\n"
            "                           a token is set or --insecure); --http-read-only: no cancel\n"
            "      --http-cert F, --http-key F  serve it over HTTPS with this PEM certificate chain\n"
            "                           and private key (SIGHUP re-reads them)\n"
            "  -v, --verbose            log every worker event\n");
}


/* `tessera-coordinator`: the long-running service (service.c). */
/* `tessera version` (also --version, -V, tessera-coordinator --version). */
static int print_version(void) {
    printf("tessera %s (build %s, protocol %d)\n", TESSERA_VERSION, protocol_build_id(), PROTOCOL_VERSION);
    return 0;
}

static int cmd_coordinator(int argc, char **argv) {
    service_options o = {.tile_size = 32, .max_upload = (size_t)LIMIT_UPLOAD_DEFAULT_MIB << 20, .max_jobs = 100,
                         .keep_s = 86400, .client_timeout_s = 30, .keep_jobs = 1000};
    farm_options_default(&o.farm);
    const char *listen = "127.0.0.1:7000", *token = NULL, *worker_token = NULL, *client_token = NULL,
               *admin_token = NULL, *users_dir = NULL;
    char host[256], err[300];
    int upload_mib = LIMIT_UPLOAD_DEFAULT_MIB, version = 0, insecure = 0, drop_given = 0;
    double keep_hours = 24;
    const char *http = NULL; /* --http ADDR:PORT: the dashboard (coordinator/dashboard.h) */
    dashboard_options web = {0};
    char web_host[256];
    const arg_spec opts[] = {
        {.name = "listen", .kind = ARG_STRING, .dest = &listen},
        {.name = "http", .kind = ARG_STRING, .dest = &http},
        {.name = "http-read-only", .kind = ARG_FLAG, .dest = &web.read_only},
        {.name = "http-cert", .kind = ARG_STRING, .dest = &web.tls_cert},
        {.name = "http-key", .kind = ARG_STRING, .dest = &web.tls_key},
        {.name = "data-dir", .kind = ARG_STRING, .dest = &o.data_dir},
        {.name = "tile-size", .kind = ARG_INT, .dest = &o.tile_size, .lo = 1, .hi = 4096},
        {.name = "max-upload", .kind = ARG_INT, .dest = &upload_mib, .lo = 1, .hi = LIMIT_UPLOAD_MAX_MIB},
        {.name = "max-jobs", .kind = ARG_INT, .dest = &o.max_jobs, .lo = 1, .hi = 100000},
        {.name = "keep-hours", .kind = ARG_DOUBLE, .dest = &keep_hours, .lo = 0, .hi = 1e6},
        {.name = "keep-jobs", .kind = ARG_INT, .dest = &o.keep_jobs, .lo = 1, .hi = 10000000},
        {.name = "client-timeout", .kind = ARG_DOUBLE, .dest = &o.client_timeout_s, .lo = 0.1, .hi = 86400},
        {.name = "max-memory", .kind = ARG_CUSTOM, .dest = &o.max_memory, .parse = membudget_parse},
        {.name = "max-connections", .kind = ARG_INT, .dest = &o.farm.limits.max_total, .lo = 1, .hi = 1000000},
        {.name = "max-per-address", .kind = ARG_INT, .dest = &o.farm.limits.max_open, .lo = 1, .hi = 1000000},
        {.name = "max-workers-per-address", .kind = ARG_INT, .dest = &o.farm.limits.max_workers, .lo = 1, .hi = 1000000},
        {.name = "heartbeat", .kind = ARG_DOUBLE, .dest = &o.farm.heartbeat_s, .lo = 0.01, .hi = 3600},
        {.name = "worker-timeout", .kind = ARG_DOUBLE, .dest = &o.farm.timeout_s, .lo = 0.05, .hi = 86400},
        {.name = "lease", .kind = ARG_DOUBLE, .dest = &o.farm.lease_s, .lo = 0.1, .hi = 1e7},
        {.name = "worker-drop", .kind = ARG_DOUBLE, .dest = &o.farm.drop_s, .lo = 0.1, .hi = 1e7, .given = &drop_given},
        {.name = "token-file", .kind = ARG_STRING, .dest = &token},
        {.name = "worker-token-file", .kind = ARG_STRING, .dest = &worker_token},
        {.name = "client-token-file", .kind = ARG_STRING, .dest = &client_token},
        {.name = "admin-token-file", .kind = ARG_STRING, .dest = &admin_token},
        {.name = "client-tokens", .kind = ARG_STRING, .dest = &users_dir},
        {.name = "audit", .kind = ARG_DOUBLE, .dest = &o.farm.audit, .lo = 0, .hi = 1},
        {.name = "blocklist-retry", .kind = ARG_DOUBLE, .dest = &o.farm.blocklist_s, .lo = 0.1, .hi = 1e7},
        {.name = "insecure", .kind = ARG_FLAG, .dest = &insecure},
        {.name = "verbose", .short_name = 'v', .kind = ARG_FLAG, .dest = &o.farm.verbose},
        {.name = "version", .kind = ARG_FLAG, .dest = &version},
        {NULL}};
    const char *none[1];
    args_parse("tessera-coordinator", argc, argv, opts, usage_coordinator, none, 0);
    web.insecure = insecure; /* one --insecure for the farm and the dashboard */
    if (version) return print_version();
    if (!o.data_dir) args_usage_error("tessera-coordinator", "--data-dir DIR is required");
    o.max_upload = (size_t)upload_mib << 20;
    o.keep_s = 3600 * keep_hours;
    if (address_parse(listen, host, sizeof host, &o.farm.port, err, sizeof err))
        args_usage_error("tessera-coordinator", "--listen %s", err);
    o.farm.host = host;
    if ((worker_token || client_token || admin_token) && !((token || worker_token) && (token || client_token || users_dir)))
        args_usage_error("tessera-coordinator", "--worker-token-file and --client-token-file (or --client-tokens) go "
                         "together (or with --token-file for the other class); --admin-token-file needs them too");
    if (users_dir && !token && !worker_token)
        args_usage_error("tessera-coordinator", "--client-tokens needs --worker-token-file (or --token-file)");
    if (!token && !worker_token && !insecure && !address_is_loopback(host))
        args_usage_error("tessera-coordinator", "--listen %s without --token-file: links would be in clear beyond "
                         "this machine; add --token-file F, or --insecure on a network you trust", listen);
    if (auth_keyring_load(&o.farm.auth, token, worker_token, client_token, admin_token, err, sizeof err))
        args_usage_error("tessera-coordinator", "token file %s", err);
    if (users_dir && auth_keyring_set_users(&o.farm.auth, users_dir, err, sizeof err))
        args_usage_error("tessera-coordinator", "--client-tokens %s", err);
    if (!(o.farm.heartbeat_s < o.farm.timeout_s))
        args_usage_error("tessera-coordinator", "--worker-timeout must be longer than --heartbeat");
    if (drop_given && !(o.farm.drop_s > o.farm.timeout_s))
        args_usage_error("tessera-coordinator", "--worker-drop must be longer than --worker-timeout");
    if (!drop_given && o.farm.drop_s < 6 * o.farm.timeout_s) o.farm.drop_s = 6 * o.farm.timeout_s;
    if (o.tile_size > o.farm.max_tile_side) o.farm.max_tile_side = o.tile_size;
    if (http && dashboard_parse_address(http, &web, web_host, sizeof web_host, err, sizeof err))
        args_usage_error("tessera-coordinator", "--http %s", err);
    if (!http && (web.tls_cert || web.tls_key))
        args_usage_error("tessera-coordinator", "--http-cert and --http-key serve --http: give --http ADDR:PORT");
    if (http) o.http = &web;
    return service_run(&o);
}

static void usage(FILE *f) {
    fprintf(f,
            "usage: tessera COMMAND [options]\n"
            "\n"
            "commands:\n"
            "  render SCENE.json -o OUT   render a scene to an image (see tessera render --help)\n"
            "  tonemap IN.exr -o OUT      tone map a saved HDR image again (see tessera tonemap --help)\n"
            "  compare IMAGE REFERENCE    rmse and relative MSE of an HDR image against another\n"
            "  coordinator --data-dir D   run the render service (also installed as tessera-coordinator)\n"
            "  submit SCENE.json [--wait] send a job to the service; status, workers, cancel JOB,\n"
            "                             fetch JOB -o OUT, priority JOB P, logs JOB talk to it too\n"
            "                             (see tessera submit --help)\n"
            "  version                    print the version\n");
}

int main(int argc, char **argv) {
    signal(SIGPIPE, SIG_IGN); /* a vanished worker is an error to handle, not a reason to die */
    const char *self = strrchr(argv[0], '/');
    if (strcmp(self ? self + 1 : argv[0], "tessera-coordinator") == 0) return cmd_coordinator(argc, argv);
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (strcmp(argv[1], "render") == 0) return cmd_render(argc - 1, argv + 1);
    if (strcmp(argv[1], "tonemap") == 0) return cmd_tonemap(argc - 1, argv + 1);
    if (strcmp(argv[1], "coordinator") == 0) return cmd_coordinator(argc - 1, argv + 1);
    if (strcmp(argv[1], "compare") == 0) return cmd_compare(argc - 1, argv + 1);
    static const char *const client_cmds[] = {"submit", "status", "workers", "cancel", "fetch", "priority", "logs"};
    for (int i = 0; i < 7; i++)
        if (strcmp(argv[1], client_cmds[i]) == 0) return client_main(argc - 1, argv + 1);
    if (strcmp(argv[1], "version") == 0 || strcmp(argv[1], "--version") == 0 || strcmp(argv[1], "-V") == 0)
        return print_version();
    if (strcmp(argv[1], "help") == 0 || strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0) {
        usage(stdout);
        return 0;
    }
    static const char *const commands[] = {"render", "tonemap", "coordinator", "compare", "submit", "status",
                                           "workers", "cancel", "fetch", "priority", "logs", "version", "help", NULL};
    const char *near = args_closest(argv[1], commands);
    if (near) args_usage_error("tessera", "unknown command \"%s\" (did you mean \"%s\"?)", argv[1], near);
    args_usage_error("tessera", "unknown command \"%s\"", argv[1]);
}
