/* seal_speed.c - what sealing costs per frame, in CPU time (robust on a
 * busy machine, unlike wall time): seal_wrap then seal_open of frames of
 * the given sizes, many times each, the best of five rounds.
 *
 *   seal_speed [BYTES...]   (default: a 32x32 tile of means, a JSON message) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "net/seal.h"
#include "net/wire.h"

static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* CPU seconds per wrap + open of one frame of len body bytes. */
static double cost(size_t len, int reps) {
    size_t flen, slen, plen;
    uint8_t *frame = wire_frame_new(WIRE_KIND_TILE, len, &flen), *plain;
    unsigned char key[SEAL_KEY_BYTES] = {1, 2, 3};
    memset(frame + WIRE_HEADER_BYTES, 0x5a, len);
    seal_dir tx, rx;
    seal_init(&tx, key);
    seal_init(&rx, key);
    char err[200];
    double best = 1e9;
    for (int round = 0; round < 5; round++) {
        double t0 = cpu_now();
        for (int i = 0; i < reps; i++) {
            uint8_t *s = seal_wrap(&tx, frame, flen, &slen);
            if (!s || seal_open(&rx, s[4], s + WIRE_HEADER_BYTES, slen - WIRE_HEADER_BYTES, &plain, &plen, err,
                                sizeof err)) {
                fprintf(stderr, "seal_speed: %s\n", s ? err : "out of memory");
                exit(1);
            }
            free(plain);
            free(s);
        }
        double t = (cpu_now() - t0) / reps;
        best = t < best ? t : best;
    }
    free(frame);
    return best;
}

int main(int argc, char **argv) {
    size_t def[] = {20 + 32 * 32 * 3 * 4, 64};
    int n = argc > 1 ? argc - 1 : 2;
    for (int i = 0; i < n; i++) {
        size_t len = argc > 1 ? (size_t)strtoull(argv[i + 1], NULL, 10) : def[i];
        double c = cost(len, len > 4096 ? 20000 : 200000);
        printf("seal_speed: %zu-byte frame: %.2f us of CPU to seal and open (%.0f MB/s)\n", len, c * 1e6,
               (double)len / c / 1e6);
    }
    return 0;
}
