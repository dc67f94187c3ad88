/* image_compare.c - error of an image against a reference (image_compare.h). */
#include "image_compare.h"

#include <math.h>
#include <string.h>

int image_compare(const image *img, const image *ref, image_error *out) {
    memset(out, 0, sizeof *out);
    if (img->width != ref->width || img->height != ref->height) return -1;
    size_t n = (size_t)img->width * (size_t)img->height * 3, used = 0;
    double se = 0, rel = 0;
    for (size_t i = 0; i < n; i++) {
        double x = img->rgb[i], r = ref->rgb[i];
        if (!isfinite(x)) {
            out->nonfinite++;
            continue;
        }
        double d = x - r;
        se += d * d;
        rel += d * d / (r * r + 0.01);
        if (fabs(d) > out->max_abs) out->max_abs = fabs(d);
        used++;
    }
    out->rmse = used ? sqrt(se / (double)used) : 0;
    out->relmse = used ? rel / (double)used : 0;
    return 0;
}
