/* fuzz_image.c - libFuzzer target: the image readers (PFM, PPM, EXR through
 * OpenEXRCore) on any file. The first byte picks the extension. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "image/image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1) return 0;
    static const char *const ext[] = {"pfm", "ppm", "exr"};
    char path[64];
    snprintf(path, sizeof path, "/tmp/tessera-fuzz-%d.%s", (int)getpid(), ext[data[0] % 3]);
    FILE *f = fopen(path, "wb");
    if (!f) return 0;
    fwrite(data + 1, 1, size - 1, f);
    fclose(f);
    image img;
    char err[512];
    if (image_read(path, &img, err, sizeof err) == 0) {
        if (img.width <= 0 || img.height <= 0) abort();
        image_free(&img);
    } else if (!err[0]) {
        abort();
    }
    unlink(path);
    return 0;
}
