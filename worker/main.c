/* main.c - `tessera-worker --connect HOST:PORT [--threads N] [--name NAME] [--idle-exit S]`:
 * command-line parsing for a farm worker (worker.c does the work). */
#define _GNU_SOURCE
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "net/address.h"
#include "args.h"
#include "net/protocol.h"
#include "version.h"
#include "worker.h"

static void usage(FILE *f) {
    fprintf(f,
            "usage: tessera-worker --connect HOST:PORT [options]\n"
            "\n"
            "Join a Tessera farm: render the tiles the coordinator hands out and send\n"
            "them back; reconnect with backoff whenever the coordinator goes away.\n"
            "\n"
            "options:\n"
            "  -c, --connect HOST:PORT  the coordinator (required)\n"
            "  -t, --threads N          render threads (default: all cores)\n"
            "  -n, --name NAME          name in the coordinator's logs (default: HOST-PID)\n"
            "      --prefetch N         tiles held beyond one per thread (default 1)\n"
            "      --retry-max S        longest wait between connection attempts (default 5)\n"
            "      --once               exit when the connection ends (local farms)\n"
            "      --idle-exit S        leave (status 0) after S seconds with no tile in hand:\n"
            "                           no coordinator reachable, or none that gives work\n"
            "                           (batch schedulers: frees the allocation; default: never)\n"
            "      --keep-scene S       keep a loaded scene S seconds after its last job, for the\n"
            "                           next job of the same scene (an adaptive render's next\n"
            "                           round, a preview's final; default 30; 0: free it at once)\n"
            "      --throttle-ms MS     sleep after each tile: simulates a slow machine (tests)\n"
            "      --token-file F       prove this worker token to the coordinator; links are then\n"
            "                           encrypted (default: $TESSERA_WORKER_TOKEN_FILE, else\n"
            "                           $TESSERA_TOKEN_FILE; none: no authentication)\n"
            "      --insecure           allow a coordinator beyond loopback without a token\n"
            "  -v, --verbose            log jobs and totals\n"
            "  -q, --quiet              log errors only\n"
            "      --version            print the version and build id\n"
            "  -h, --help               this text\n"
            "\n"
            "SIGTERM or SIGINT: abandon the tiles in hand (the coordinator hands them to\n"
            "others) and exit with status 0.\n");
}

/* getopt_long found a bad option (c is '?' or ':', getopt's optopt and
 * optind as it left them): one line naming it, with the nearest long
 * option for a near miss, then "see tessera-worker --help"; exit(2). */
static void bad_option(const struct option *opts, int c, char **argv) {
    const char *arg = argv[optind - 1], *names[32];
    if (c == ':') args_usage_error("tessera-worker", "%s needs a value", arg);
    if (optopt) args_usage_error("tessera-worker", "unknown option -%c", optopt);
    int n = 0;
    for (; opts[n].name && n < 31; n++) names[n] = opts[n].name;
    names[n] = NULL;
    char want[100];
    const char *eq = strchr(arg, '=');
    snprintf(want, sizeof want, "%.*s", eq ? (int)(eq - arg - 2) : (int)strlen(arg + 2), arg + 2);
    const char *near = args_closest(want, names);
    if (near) args_usage_error("tessera-worker", "unknown option --%s (did you mean --%s?)", want, near);
    args_usage_error("tessera-worker", "unknown option %s", arg);
}

static long parse_long(const char *opt, const char *s, long lo, long hi) {
    return args_long("tessera-worker", opt, s, lo, hi);
}

enum { OPT_PREFETCH = 256, OPT_ONCE, OPT_THROTTLE, OPT_RETRY, OPT_VERSION, OPT_TOKEN, OPT_IDLE_EXIT, OPT_INSECURE, OPT_KEEP_SCENE };

int main(int argc, char **argv) {
    static const struct option opts[] = {
        {"connect", required_argument, 0, 'c'}, {"threads", required_argument, 0, 't'},
        {"name", required_argument, 0, 'n'}, {"prefetch", required_argument, 0, OPT_PREFETCH},
        {"retry-max", required_argument, 0, OPT_RETRY}, {"once", no_argument, 0, OPT_ONCE},
        {"idle-exit", required_argument, 0, OPT_IDLE_EXIT}, {"keep-scene", required_argument, 0, OPT_KEEP_SCENE},
        {"throttle-ms", required_argument, 0, OPT_THROTTLE}, {"verbose", no_argument, 0, 'v'},
        {"quiet", no_argument, 0, 'q'}, {"token-file", required_argument, 0, OPT_TOKEN}, {"insecure", no_argument, 0, OPT_INSECURE}, {"version", no_argument, 0, OPT_VERSION}, {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    signal(SIGPIPE, SIG_IGN); /* a vanished coordinator is an error to handle, not a reason to die */
    worker_config cfg = worker_config_default();
    const char *connect = NULL, *token = getenv("TESSERA_WORKER_TOKEN_FILE");
    if (!token || !*token) token = getenv("TESSERA_TOKEN_FILE");
    char host[256], name[128], err[256] = "";
    int c, insecure = 0;
    opterr = 0; /* bad_option says it in one line */
    while ((c = getopt_long(argc, argv, ":c:t:n:vqhV", opts, NULL)) != -1) {
        switch (c) {
        case 'c': connect = optarg; break;
        case 't': cfg.threads = (int)parse_long("--threads", optarg, 1, 1024); break;
        case 'n': cfg.name = optarg; break;
        case OPT_PREFETCH: cfg.prefetch = (int)parse_long("--prefetch", optarg, 0, 1024); break;
        case OPT_RETRY: cfg.retry_max_s = (double)parse_long("--retry-max", optarg, 1, 3600); break;
        case OPT_ONCE: cfg.once = 1; break;
        case OPT_IDLE_EXIT: cfg.idle_exit_s = args_double("tessera-worker", "--idle-exit", optarg, 0.1, 1e7); break;
        case OPT_KEEP_SCENE: cfg.keep_scene_s = args_double("tessera-worker", "--keep-scene", optarg, 0, 1e7); break;
        case OPT_THROTTLE: cfg.throttle_ms = (int)parse_long("--throttle-ms", optarg, 0, 600000); break;
        case 'v': cfg.verbose = 1; break;
        case 'q': cfg.quiet = 1; break;
        case OPT_TOKEN: token = optarg; break;
        case OPT_VERSION:
        case 'V':
            printf("tessera-worker %s (build %s, protocol %d)\n", TESSERA_VERSION, protocol_build_id(), PROTOCOL_VERSION);
            return 0;
        case OPT_INSECURE: insecure = 1; break;
        case 'h': usage(stdout); return 0;
        default: bad_option(opts, c, argv);
        }
    }
    if (optind != argc) args_usage_error("tessera-worker", "unexpected argument \"%s\"", argv[optind]);
    if (!connect) args_usage_error("tessera-worker", "--connect HOST:PORT is required");
    if (address_parse(connect, host, sizeof host, &cfg.port, err, sizeof err) || cfg.port == 0) {
        fprintf(stderr, "tessera-worker: --connect %s\n", cfg.port == 0 && !err[0] ? "port 0" : err);
        return 2;
    }
    cfg.host = host;
    if (!(token && *token) && !insecure && !address_is_loopback(host)) {
        fprintf(stderr, "tessera-worker: --connect %s without --token-file: scenes and tiles would cross the network "
                        "in clear; add --token-file F, or --insecure on a network you trust\n", connect);
        return 2;
    }
    if (token && *token && auth_key_load(token, &cfg.auth, err, sizeof err)) {
        fprintf(stderr, "tessera-worker: %s\n", err);
        return 2;
    }
    if (!cfg.name) {
        char hn[64] = "worker";
        gethostname(hn, sizeof hn - 1);
        hn[sizeof hn - 1] = '\0';
        snprintf(name, sizeof name, "%s-%d", hn, (int)getpid());
        cfg.name = name;
    }
    return worker_run(&cfg);
}
