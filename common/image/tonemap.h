/* tonemap.h - from linear radiance to display values in [0, 1].
 *
 * Operators work on luminance L = 0.2126 R + 0.7152 G + 0.0722 B and rescale
 * the colour by L_out / L, so hue is kept; where L <= 0 (black, or negative
 * input) the pixel maps to black instead of dividing by zero. NaN and Inf
 * pixels map to black and are counted. */
#ifndef TESSERA_TONEMAP_H
#define TESSERA_TONEMAP_H

#include <stddef.h>
#include <stdint.h>

typedef enum {
    TONEMAP_REINHARD,          /* L / (1 + L) */
    TONEMAP_REINHARD_EXTENDED, /* L (1 + L / Lw^2) / (1 + L) */
    TONEMAP_PHOTOGRAPHIC,      /* Reinhard et al. 2002: key 0.18 on the log-average, then extended */
    TONEMAP_ACES,              /* Narkowicz's fit of the ACES filmic curve, per channel */
    TONEMAP_CLAMP              /* no curve */
} tonemap_kind;

typedef struct {
    tonemap_kind kind;
    float exposure_stops; /* input is multiplied by 2^exposure_stops first */
    float white;          /* extended/photographic white point; <= 0: the image's maximum */
} tonemap_options;

/* Parse an operator name ("reinhard", "reinhard-extended", "photographic",
 * "aces", "clamp"). Returns 0, or -1 for an unknown name. */
int tonemap_parse(const char *name, tonemap_kind *out);

/* The names tonemap_parse accepts, for messages. */
#define TONEMAP_NAMES "reinhard, reinhard-extended, photographic, aces, clamp"

/* Reinhard 2002, simple form: L_out = L / (1 + L). */
float tonemap_reinhard(float L);

/* Extended form with white point Lw: maps Lw to exactly 1. */
float tonemap_reinhard_extended(float L, float Lw);

/* Narkowicz 2015 ACES fit for one channel, clamped to [0, 1]. */
float tonemap_aces(float x);

/* The sRGB transfer function (IEC 61966-2-1) for a linear value in [0, 1]. */
float tonemap_srgb_encode(float linear);

/* Tone map and sRGB-encode count pixels of rgb (3 floats each) to 8 bits.
 * Returns the number of pixels that were NaN or Inf (written black). */
size_t tonemap_to_8bit(const float *rgb, size_t count, const tonemap_options *opt, uint8_t *out);

/* The same with bits = 8 (out: uint8_t) or 16 (out: uint16_t, host order). */
size_t tonemap_encode(const float *rgb, size_t count, const tonemap_options *opt, int bits, void *out);

#endif
