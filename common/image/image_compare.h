/* image_compare.h - how far an image is from a reference: the error
 * measures of the time-against-error benchmarks. */
#ifndef TESSERA_IMAGE_COMPARE_H
#define TESSERA_IMAGE_COMPARE_H

#include "image.h"

typedef struct {
    double rmse;     /* sqrt(mean (x - ref)^2) over pixels and channels */
    double relmse;   /* mean (x - ref)^2 / (ref^2 + 0.01), as Cycles' benchmark reports it */
    double max_abs;  /* largest |x - ref| */
    long nonfinite;  /* values of x that are NaN or infinite (left out of the means) */
} image_error;

/* Compare img with ref. Returns 0, or -1 when the sizes differ. */
int image_compare(const image *img, const image *ref, image_error *out);

#endif
