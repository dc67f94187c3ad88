/* tessera.c - the `tessera` command: `tessera render SCENE -o OUT [...]`.
 *
 * Parses the command line, loads the scene, renders it - on a local farm
 * of worker processes by default (local_farm.c), or in this process with a
 * thread pool (--workers 0) - saves the image and prints one summary line.
 * Exit status 0 on success, 1 on a runtime failure, 2 on a usage error. */
#define _GNU_SOURCE
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "../common/address.h"
#include "../common/args.h"
#include "../common/accel.h"
#include "../common/image.h"
#include "../common/image_compare.h"
#include "../common/render.h"
#include "../common/scene.h"
#include "../common/version.h"
#include "cli_util.h"
#include "client.h"
#include "local_farm.h"
#include "service.h"

/* From this many primitives the default local farm is one worker with a
 * thread per core (bench/meshes.sh: at 655k triangles and above two workers
 * each loading the scene were slower than one process). */
#define LOCAL_FARM_ONE_WORKER_PRIMITIVES (1u << 19)

typedef struct {
    const char *scene_path;
    const char *out_path;
    scene_overrides ov;
    int threads, threads_given, workers, tile_size, verbose, progress, jpeg_quality, png16;
    int aov_samples; /* --aov samples: also write the per-pixel sample counts */
    int workers_defaulted; /* local farm sized by tessera, not by --workers */
    const char *listen, *token_file;
    char listen_host[256];
    farm_options farm;
    codec_exr_options exr;
    render_options ro;
    tonemap_options tm;
} render_args;

static void usage_render(FILE *f) {
    fprintf(f,
            "usage: tessera render SCENE.json [-o OUT] [options]\n"
            "\n"
            "Render a scene and save the image; the format follows OUT's extension:\n"
            "  .pfm .exr  linear float RGB (HDR); EXR records scene, spp, seed\n"
            "  .ppm .png .jpg .jpeg  8-bit sRGB, tone mapped\n"
            "\n"
            "options:\n"
            "  -o, --output PATH      image to write (default: SCENE's name with .png, in .)\n"
            "      --spp N            samples per pixel (overrides render.spp)\n"
            "      --width W          image width in pixels (overrides render.width)\n"
            "      --height H         image height in pixels (overrides render.height)\n"
            "      --max-depth N      maximum bounces (overrides render.max_depth)\n"
            "      --seed N           random seed (overrides render.seed)\n"
            "      --workers N        local worker processes (default: one per core, or one\n"
            "                         with a thread per core for scenes of 2^19 primitives\n"
            "                         or more; with --listen, 0); 0 without --listen\n"
            "                         renders in this process\n"
            "      --threads N        threads per local worker (default 1), or render threads\n"
            "                         with --workers 0 (default: all cores)\n"
            "      --listen HOST:PORT also accept remote workers (tessera-worker --connect)\n"
            "                         here; port 0 picks a free one (printed on stderr)\n"
            "      --heartbeat S      farm heartbeat interval in seconds (default 1)\n"
            "      --worker-timeout S a silent worker's tiles go to others after S s (default 5)\n"
            "      --lease S          longest a worker may hold one tile (default 300)\n"
            "      --token-file F     workers must prove they know this secret (local ones get it)\n"
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
            "      --sampler S        sobol (Owen-scrambled, the default) or random\n"
            "      --noise-threshold E  adaptive sampling: pixels stop once their estimated\n"
            "                         relative error (and their neighbours') is below E\n"
            "      --min-spp N        adaptive: samples every pixel takes first (default 16)\n"
            "      --aov samples      also write the per-pixel sample counts to OUT-stem.samples.pfm\n"
            "      --no-progress      no progress bar even on a terminal\n"
            "  -v, --verbose          print scene and BVH statistics\n"
            "  -h, --help             this text\n");
}

static long parse_int(const char *opt, const char *s, long lo, long hi) { return args_long("tessera", opt, s, lo, hi); }

static double parse_double(const char *opt, const char *s, double lo, double hi) {
    return args_double("tessera", opt, s, lo, hi);
}

/* Parse a --tonemap operator name; exits with status 2 if unknown. */
static void parse_tonemap(const char *s, tonemap_kind *out) {
    if (tonemap_parse(s, out) == 0) return;
    fprintf(stderr, "tessera: --tonemap: unknown operator \"%s\" (known: %s)\n", s, TONEMAP_NAMES);
    exit(2);
}

enum { OPT_SPP = 256, OPT_WIDTH, OPT_HEIGHT, OPT_DEPTH, OPT_SEED, OPT_THREADS, OPT_WORKERS, OPT_TILE,
       OPT_PASSES, OPT_TONEMAP, OPT_EXPOSURE, OPT_WHITE, OPT_QUALITY, OPT_EXR_COMPRESSION, OPT_EXR_HALF, OPT_EXR_ALPHA, OPT_PNG16, OPT_NO_NEE, OPT_NO_MIS, OPT_SAMPLER, OPT_NOISE_THRESHOLD, OPT_MIN_SPP, OPT_AOV, OPT_NO_PROGRESS, OPT_LISTEN, OPT_HEARTBEAT, OPT_WORKER_TIMEOUT, OPT_LEASE, OPT_TOKEN };

static void parse_render_args(int argc, char **argv, render_args *a) {
    static const struct option opts[] = {
        {"output", required_argument, 0, 'o'}, {"spp", required_argument, 0, OPT_SPP},
        {"width", required_argument, 0, OPT_WIDTH}, {"height", required_argument, 0, OPT_HEIGHT},
        {"max-depth", required_argument, 0, OPT_DEPTH}, {"seed", required_argument, 0, OPT_SEED},
        {"threads", required_argument, 0, OPT_THREADS}, {"workers", required_argument, 0, OPT_WORKERS},
        {"tile-size", required_argument, 0, OPT_TILE}, {"passes", required_argument, 0, OPT_PASSES},
        {"tonemap", required_argument, 0, OPT_TONEMAP}, {"exposure", required_argument, 0, OPT_EXPOSURE},
        {"quality", required_argument, 0, OPT_QUALITY}, {"white", required_argument, 0, OPT_WHITE},
        {"exr-compression", required_argument, 0, OPT_EXR_COMPRESSION},
        {"png16", no_argument, 0, OPT_PNG16}, {"exr-half", no_argument, 0, OPT_EXR_HALF}, {"exr-alpha", no_argument, 0, OPT_EXR_ALPHA},
        {"no-nee", no_argument, 0, OPT_NO_NEE}, {"no-mis", no_argument, 0, OPT_NO_MIS},
        {"sampler", required_argument, 0, OPT_SAMPLER},
        {"noise-threshold", required_argument, 0, OPT_NOISE_THRESHOLD},
        {"min-spp", required_argument, 0, OPT_MIN_SPP}, {"aov", required_argument, 0, OPT_AOV},
        {"no-progress", no_argument, 0, OPT_NO_PROGRESS}, {"verbose", no_argument, 0, 'v'},
        {"listen", required_argument, 0, OPT_LISTEN}, {"heartbeat", required_argument, 0, OPT_HEARTBEAT},
        {"worker-timeout", required_argument, 0, OPT_WORKER_TIMEOUT}, {"lease", required_argument, 0, OPT_LEASE},
        {"token-file", required_argument, 0, OPT_TOKEN},
        {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
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
    int c;
    optind = 1;
    while ((c = getopt_long(argc, argv, "o:vh", opts, NULL)) != -1) {
        switch (c) {
        case 'o': a->out_path = optarg; break;
        case OPT_SPP: a->ov.spp = (int)parse_int("--spp", optarg, 1, 1 << 24); break;
        case OPT_WIDTH: a->ov.width = (int)parse_int("--width", optarg, 1, 32768); break;
        case OPT_HEIGHT: a->ov.height = (int)parse_int("--height", optarg, 1, 32768); break;
        case OPT_DEPTH: a->ov.max_depth = (int)parse_int("--max-depth", optarg, 1, 1024); break;
        case OPT_SEED:
            a->ov.seed = (uint64_t)parse_int("--seed", optarg, 0, LONG_MAX);
            a->ov.has_seed = 1;
            break;
        case OPT_THREADS:
            a->threads = (int)parse_int("--threads", optarg, 1, 1024);
            a->threads_given = 1;
            break;
        case OPT_LISTEN: a->listen = optarg; break;
        case OPT_TOKEN: a->token_file = optarg; break;
        case OPT_HEARTBEAT: a->farm.heartbeat_s = parse_double("--heartbeat", optarg, 0.01, 3600); break;
        case OPT_WORKER_TIMEOUT: a->farm.timeout_s = parse_double("--worker-timeout", optarg, 0.05, 86400); break;
        case OPT_LEASE: a->farm.lease_s = parse_double("--lease", optarg, 0.1, 1e7); break;
        case OPT_WORKERS: a->workers = (int)parse_int("--workers", optarg, 0, 4096); break;
        case OPT_TILE: a->tile_size = (int)parse_int("--tile-size", optarg, 1, 4096); break;
        case OPT_PASSES: a->ro.passes = (int)parse_int("--passes", optarg, 1, 1 << 24); break;
        case OPT_TONEMAP:
            parse_tonemap(optarg, &a->tm.kind);
            break;
        case OPT_WHITE: a->tm.white = (float)parse_double("--white", optarg, 1e-6, 1e30); break;
        case OPT_EXPOSURE: a->tm.exposure_stops = (float)parse_double("--exposure", optarg, -64, 64); break;
        case OPT_QUALITY: a->jpeg_quality = (int)parse_int("--quality", optarg, 1, 100); break;
        case OPT_EXR_COMPRESSION: {
            static const char *const names[] = {"zip", "piz", "none"};
            int found = -1;
            for (int i = 0; i < 3; i++)
                if (strcmp(optarg, names[i]) == 0) found = i;
            if (found < 0) {
                fprintf(stderr, "tessera: --exr-compression: unknown \"%s\" (known: zip, piz, none)\n", optarg);
                exit(2);
            }
            a->exr.compression = (codec_exr_compression)found;
            break;
        }
        case OPT_EXR_HALF: a->exr.half = 1; break;
        case OPT_PNG16: a->png16 = 1; break;
        case OPT_EXR_ALPHA: a->exr.alpha = 1; break;
        case OPT_NO_NEE: a->ro.integrator.no_nee = 1; break;
        case OPT_NO_MIS: a->ro.integrator.no_mis = 1; break;
        case OPT_NOISE_THRESHOLD:
            a->ro.noise_threshold = parse_double("--noise-threshold", optarg, 1e-6, 1e6);
            break;
        case OPT_MIN_SPP: a->ro.min_spp = (int)parse_int("--min-spp", optarg, 2, 1 << 24); break;
        case OPT_AOV:
            if (strcmp(optarg, "samples") != 0) {
                fprintf(stderr, "tessera: --aov: the one output on offer is \"samples\", not \"%s\"\n", optarg);
                exit(2);
            }
            a->aov_samples = 1;
            break;
        case OPT_SAMPLER:
            if (sampler_parse(optarg, &a->ro.integrator.sampler) != 0) {
                fprintf(stderr, "tessera: --sampler: expected sobol or random, got \"%s\"\n", optarg);
                exit(2);
            }
            break;
        case OPT_NO_PROGRESS: a->progress = 0; break;
        case 'v': a->verbose = 1; break;
        case 'h': usage_render(stdout); exit(0);
        default: usage_render(stderr); exit(2);
        }
    }
    if (optind != argc - 1) {
        fprintf(stderr, "tessera render: expected exactly one scene file\n");
        usage_render(stderr);
        exit(2);
    }
    a->scene_path = argv[optind];
    if (a->listen) {
        char err[300];
        if (address_parse(a->listen, a->listen_host, sizeof a->listen_host, &a->farm.port, err, sizeof err)) {
            fprintf(stderr, "tessera: --listen %s\n", err);
            exit(2);
        }
        a->farm.host = a->listen_host;
    }
    a->workers_defaulted = a->workers < 0 && !a->listen;
    if (a->workers < 0) a->workers = a->listen ? 0 : (int)sysconf(_SC_NPROCESSORS_ONLN);
    char terr[300];
    if (a->token_file && auth_key_load(a->token_file, &a->farm.auth, terr, sizeof terr)) {
        fprintf(stderr, "tessera: --token-file %s\n", terr);
        exit(2);
    }
    if (!(a->farm.heartbeat_s < a->farm.timeout_s)) {
        fprintf(stderr, "tessera: --worker-timeout (%g s) must be longer than --heartbeat (%g s)\n",
                a->farm.timeout_s, a->farm.heartbeat_s);
        exit(2);
    }
    if (a->farm.drop_s < 6 * a->farm.timeout_s) a->farm.drop_s = 6 * a->farm.timeout_s;
    if (a->tile_size > a->farm.max_tile_side) a->farm.max_tile_side = a->tile_size;
}

static double now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct {
    double start;
    uint64_t total_samples;
} progress_state;

/* The threaded renderer's progress: tiles, samples/s, ETA. */
static void show_progress(void *ctx, int done, int total, const trace_stats *so_far) {
    progress_state *p = ctx;
    double el = now_seconds() - p->start;
    double rate = el > 0 ? (double)so_far->samples / el : 0;
    double eta = rate > 0 ? (double)(p->total_samples - so_far->samples) / rate : 0;
    cli_progress(done, total, rate, -1, eta, done == total);
}

static void print_scene_info(const scene *s) {
    bvh_stats bs;
    accel_embree_stats es;
    char features[256];
    scene_feature_names(s->features, features, sizeof features);
    fprintf(stderr, "scene %s: %u triangles, %u spheres, %u lights, %u materials, %zu degenerate triangles skipped\n",
            s->path, s->triangle_count, s->sphere_count, s->light_count, s->material_count - 1,
            s->degenerate_triangles);
    fprintf(stderr, "features: %s\n", features);
    if (!s->accel)
        fprintf(stderr, "intersector: built by each worker (workers print theirs with -v)\n");
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
    fprintf(stderr, "render: %dx%d, %d spp, max depth %d, seed %llu\n", s->settings.width, s->settings.height,
            s->settings.spp, s->settings.max_depth, (unsigned long long)s->settings.seed);
}

/* Render in this process with a thread pool. Returns 0 or -1 (printed). */
static int render_in_process(render_args *a, const scene *s, image *img, trace_stats *st) {
    progress_state ps = {now_seconds(),
                         (uint64_t)s->settings.width * (uint64_t)s->settings.height * (uint64_t)s->settings.spp};
    a->ro.threads = a->threads;
    a->ro.tile_size = a->tile_size;
    if (a->progress && isatty(STDERR_FILENO)) {
        a->ro.progress = show_progress;
        a->ro.progress_ctx = &ps;
    }
    if (render_frame(s, &a->ro, img->rgb, st) == 0) return 0;
    fprintf(stderr, "tessera: could not start %d render threads\n", a->threads);
    return -1;
}

/* Render on a farm: local worker processes and/or remote ones. Returns 0 or
 * -1 (printed). */
static int render_on_farm(render_args *a, const scene *s, const scene_bundle *b, image *img, trace_stats *st) {
    size_t len;
    uint8_t *bytes = scene_bundle_serialise(b, &len);
    if (!bytes) {
        fprintf(stderr, "tessera: %s: the scene and its meshes are too large to send (over %u MiB)\n",
                a->scene_path, SCENE_BUNDLE_MAX_BYTES >> 20);
        return -1;
    }
    proto_job job = {.id = 1, .width = s->settings.width, .height = s->settings.height, .spp = s->settings.spp,
                     .max_depth = s->settings.max_depth, .seed = s->settings.seed,
                     .integrator = a->ro.integrator, .adaptive = a->ro.noise_threshold > 0};
    scene_bundle_hash(bytes, len, job.scene_hash);
    local_farm_options lo = {.workers = a->workers, .threads_per_worker = a->threads_given ? a->threads : 1,
                             .tile_size = a->tile_size, .farm = a->farm, .listening = a->listen != NULL,
                             .token_file = a->token_file,
                             .progress = a->progress && isatty(STDERR_FILENO), .verbose = a->verbose,
                             .noise_threshold = a->ro.noise_threshold, .min_spp = a->ro.min_spp,
                             .samples = a->ro.samples};
    lo.farm.verbose = a->verbose;
    local_farm_report rep;
    char err[700];
    int rc = local_farm_render(&lo, &job, bytes, len, img->rgb, &rep, err, sizeof err);
    free(bytes);
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

static int save_image(const render_args *a, const scene *s, const image *img) {
    /* No time or host in the file: the same render gives the same bytes. */
    char spp[32], seed[32], err[1024];
    snprintf(spp, sizeof spp, "%d", s->settings.spp);
    snprintf(seed, sizeof seed, "%llu", (unsigned long long)s->settings.seed);
    codec_attribute attrs[] = {{"tessera:scene", a->scene_path}, {"tessera:spp", spp}, {"tessera:seed", seed},
                               {"tessera:version", TESSERA_VERSION}};
    image_write_options wo = {.tonemap = a->tm, .jpeg_quality = a->jpeg_quality, .png16 = a->png16, .exr = a->exr};
    wo.exr.attrs = attrs;
    wo.exr.attr_count = 4;
    if (image_write(a->out_path, img, &wo, err, sizeof err) == 0) return 0;
    fprintf(stderr, "tessera: %s\n", err);
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

static int cmd_render(int argc, char **argv) {
    render_args a;
    char err[1024], out_default[512];
    parse_render_args(argc, argv, &a);
    if (!a.out_path) {
        cli_default_output(a.scene_path, out_default, sizeof out_default);
        a.out_path = out_default;
    }
    scene_bundle b;
    if (scene_bundle_read(a.scene_path, &b, err, sizeof err)) {
        fprintf(stderr, "tessera: %s\n", err);
        return 1;
    }
    a.ov.no_accel = a.listen || a.workers > 0; /* the workers build their own */
    scene *s = scene_load_bundle(&b, &a.ov, err, sizeof err);
    if (!s) {
        fprintf(stderr, "tessera: %s\n", err);
        scene_bundle_free(&b);
        return 1;
    }
    if (a.verbose) print_scene_info(s);
    /* A big scene costs every local worker its own load, build and memory;
     * one worker with a thread per core loads it once (same bytes). */
    if (a.workers_defaulted && !a.threads_given && a.workers > 1 &&
        s->triangle_count + s->sphere_count >= LOCAL_FARM_ONE_WORKER_PRIMITIVES) {
        a.threads = a.workers;
        a.threads_given = 1;
        a.workers = 1;
        if (a.verbose)
            fprintf(stderr, "local farm: 1 worker with %d threads (%u primitives: loaded once, not per core)\n",
                    a.threads, s->triangle_count + s->sphere_count);
    }
    image img;
    int rc = image_alloc(&img, s->settings.width, s->settings.height);
    if (rc) fprintf(stderr, "tessera: out of memory for a %dx%d image\n", s->settings.width, s->settings.height);
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
    int farm_mode = a.listen || a.workers > 0;
    if (rc == 0) rc = farm_mode ? render_on_farm(&a, s, &b, &img, &st) : render_in_process(&a, s, &img, &st);
    double secs = now_seconds() - t0;
    if (rc == 0) rc = save_image(&a, s, &img);
    char aov_path[600] = "";
    if (rc == 0 && a.aov_samples) rc = save_samples_aov(&a, s, samples, aov_path, sizeof aov_path);
    if (rc == 0)
        printf("rendered %s: %.2f s, %.3f Msamples/s, %.2f Mrays/s, %llu NaN/Inf samples, image: %s%s%s\n",
               a.scene_path, secs, (double)st.samples / secs / 1e6,
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
    return rc ? 1 : 0;
}

static void usage_tonemap(FILE *f) {
    fprintf(f,
            "usage: tessera tonemap IN.exr|IN.pfm -o OUT [--tonemap NAME] [--exposure STOPS] [--white L] [--quality Q]\n"
            "\n"
            "Tone map a saved HDR image (.exr, .pfm) again without rendering; OUT's extension\n"
            "names the format (.png .jpg .jpeg .ppm, or .pfm/.exr to convert).\n"
            "Operators: %s.\n", TONEMAP_NAMES);
}

/* `tessera tonemap`: read an HDR image, write it with new tone mapping. */
static int cmd_tonemap(int argc, char **argv) {
    static const struct option opts[] = {
        {"output", required_argument, 0, 'o'}, {"tonemap", required_argument, 0, OPT_TONEMAP},
        {"exposure", required_argument, 0, OPT_EXPOSURE}, {"white", required_argument, 0, OPT_WHITE},
        {"quality", required_argument, 0, OPT_QUALITY}, {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    image_write_options wo = {.tonemap = {.kind = TONEMAP_REINHARD}};
    const char *out = NULL;
    int c;
    optind = 1;
    while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
        switch (c) {
        case 'o': out = optarg; break;
        case OPT_TONEMAP:
            parse_tonemap(optarg, &wo.tonemap.kind);
            break;
        case OPT_EXPOSURE: wo.tonemap.exposure_stops = (float)parse_double("--exposure", optarg, -64, 64); break;
        case OPT_WHITE: wo.tonemap.white = (float)parse_double("--white", optarg, 1e-6, 1e30); break;
        case OPT_QUALITY: wo.jpeg_quality = (int)parse_int("--quality", optarg, 1, 100); break;
        case 'h': usage_tonemap(stdout); return 0;
        default: usage_tonemap(stderr); return 2;
        }
    }
    if (optind != argc - 1 || !out) {
        fprintf(stderr, "tessera tonemap: expected one input image and -o OUT\n");
        usage_tonemap(stderr);
        return 2;
    }
    char err[1024];
    image img;
    if (image_read(argv[optind], &img, err, sizeof err) != 0 || image_write(out, &img, &wo, err, sizeof err) != 0) {
        fprintf(stderr, "tessera: %s\n", err);
        image_free(&img);
        return 1;
    }
    printf("tone mapped %s: %zu NaN/Inf pixels written black, image: %s\n", argv[optind], wo.bad_pixels, out);
    image_free(&img);
    return 0;
}

/* `tessera compare IMAGE REFERENCE`: error measures for benchmarks. */
static int cmd_compare(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: tessera compare IMAGE REFERENCE   (.pfm, .exr or .ppm)\n"
                        "prints rmse, relmse = mean (x-ref)^2/(ref^2+0.01), max |x-ref|\n");
        return 2;
    }
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
            "      --max-upload MIB     largest scene plus meshes a client may send (default 256)\n"
            "      --max-jobs N         queued and running jobs at once (default 100)\n"
            "      --keep-hours H       delete finished jobs after H hours (default 24)\n"
            "      --token-file F       workers and clients must prove they know this secret\n"
            "      --heartbeat S, --worker-timeout S, --lease S   as for tessera render\n"
            "  -v, --verbose            log every worker event\n");
}

enum { S_LISTEN = 400, S_DATA, S_TILE, S_UPLOAD, S_JOBS, S_KEEP, S_HB, S_TIMEOUT, S_LEASE, S_TOKEN };

/* `tessera-coordinator`: the long-running service (service.c). */
static int cmd_coordinator(int argc, char **argv) {
    static const struct option opts[] = {
        {"listen", required_argument, 0, S_LISTEN}, {"data-dir", required_argument, 0, S_DATA},
        {"tile-size", required_argument, 0, S_TILE}, {"max-upload", required_argument, 0, S_UPLOAD},
        {"max-jobs", required_argument, 0, S_JOBS}, {"keep-hours", required_argument, 0, S_KEEP},
        {"heartbeat", required_argument, 0, S_HB}, {"worker-timeout", required_argument, 0, S_TIMEOUT},
        {"lease", required_argument, 0, S_LEASE}, {"verbose", no_argument, 0, 'v'},
        {"token-file", required_argument, 0, S_TOKEN}, {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    service_options o = {.tile_size = 32, .max_upload = (size_t)256 << 20, .max_jobs = 100, .keep_s = 86400};
    farm_options_default(&o.farm);
    const char *listen = "127.0.0.1:7000", *token = NULL;
    char host[256], err[300];
    int c;
    optind = 1;
    while ((c = getopt_long(argc, argv, "vh", opts, NULL)) != -1) {
        switch (c) {
        case S_LISTEN: listen = optarg; break;
        case S_DATA: o.data_dir = optarg; break;
        case S_TILE: o.tile_size = (int)parse_int("--tile-size", optarg, 1, 4096); break;
        case S_UPLOAD: o.max_upload = (size_t)parse_int("--max-upload", optarg, 1, 512) << 20; break;
        case S_JOBS: o.max_jobs = (int)parse_int("--max-jobs", optarg, 1, 100000); break;
        case S_KEEP: o.keep_s = 3600 * parse_double("--keep-hours", optarg, 0, 1e6); break;
        case S_HB: o.farm.heartbeat_s = parse_double("--heartbeat", optarg, 0.01, 3600); break;
        case S_TIMEOUT: o.farm.timeout_s = parse_double("--worker-timeout", optarg, 0.05, 86400); break;
        case S_LEASE: o.farm.lease_s = parse_double("--lease", optarg, 0.1, 1e7); break;
        case S_TOKEN: token = optarg; break;
        case 'v': o.farm.verbose = 1; break;
        case 'h': usage_coordinator(stdout); return 0;
        default: usage_coordinator(stderr); return 2;
        }
    }
    if (optind != argc || !o.data_dir) {
        fprintf(stderr, "tessera-coordinator: %s\n", o.data_dir ? "unexpected arguments" : "--data-dir DIR is required");
        usage_coordinator(stderr);
        return 2;
    }
    if (address_parse(listen, host, sizeof host, &o.farm.port, err, sizeof err)) {
        fprintf(stderr, "tessera-coordinator: --listen %s\n", err);
        return 2;
    }
    o.farm.host = host;
    if (token && auth_key_load(token, &o.farm.auth, err, sizeof err)) {
        fprintf(stderr, "tessera-coordinator: --token-file %s\n", err);
        return 2;
    }
    if (!(o.farm.heartbeat_s < o.farm.timeout_s)) {
        fprintf(stderr, "tessera-coordinator: --worker-timeout must be longer than --heartbeat\n");
        return 2;
    }
    if (o.farm.drop_s < 6 * o.farm.timeout_s) o.farm.drop_s = 6 * o.farm.timeout_s;
    if (o.tile_size > o.farm.max_tile_side) o.farm.max_tile_side = o.tile_size;
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
            "                             fetch JOB -o OUT talk to it too (see tessera submit --help)\n"
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
    static const char *const client_cmds[] = {"submit", "status", "workers", "cancel", "fetch"};
    for (int i = 0; i < 5; i++)
        if (strcmp(argv[1], client_cmds[i]) == 0) return client_main(argc - 1, argv + 1);
    if (strcmp(argv[1], "version") == 0) {
        printf("tessera %s (build %s, protocol %d)\n", TESSERA_VERSION, protocol_build_id(), PROTOCOL_VERSION);
        return 0;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0) {
        usage(stdout);
        return 0;
    }
    fprintf(stderr, "tessera: unknown command \"%s\"\n", argv[1]);
    usage(stderr);
    return 2;
}
