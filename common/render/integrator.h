/* integrator.h - the path tracer: radiance arriving along one camera ray.
 *
 * Unidirectional path tracing with next-event estimation at every non-delta
 * vertex, both strategies combined with the power heuristic, and Russian
 * roulette after the third bounce (unbiased: survivors are divided by the
 * survival probability). */
#ifndef TESSERA_INTEGRATOR_H
#define TESSERA_INTEGRATOR_H

#include <stdint.h>

#include "intersect.h"
#include "sampler.h"
#include "scene.h"

/* Counters one thread accumulates; plain struct, summed by the caller. */
typedef struct {
    uint64_t samples;     /* camera samples traced */
    uint64_t rays;        /* closest-hit rays */
    uint64_t shadow_rays; /* occlusion rays */
    uint64_t bad_samples; /* samples whose radiance came out NaN or Inf (dropped) */
} trace_stats;

/* a += b, counter by counter. Can't fail. */
static inline void trace_stats_add(trace_stats *a, const trace_stats *b) {
    a->samples += b->samples;
    a->rays += b->rays;
    a->shadow_rays += b->shadow_rays;
    a->bad_samples += b->bad_samples;
}

/* Integrator switches, for benchmarks that show what each feature buys. */
typedef struct {
    int no_nee; /* no light sampling: emitters found only by BSDF sampling */
    int no_mis; /* light sampling only for direct light (no BSDF-hit weighting) */
    int no_pair; /* each shadow ray traced at once, not alongside the next ray (same bytes; benchmarks) */
    sampler_kind sampler; /* SAMPLER_SOBOL (the default, 0) or SAMPLER_RANDOM */
} integrator_options;

/* Random-number dimensions used by one camera sample: two for the pixel
 * jitter, then INTEGRATOR_DIMS_PER_BOUNCE for every bounce, at fixed offsets
 * (so that dimension k always means the same decision). */
#define INTEGRATOR_CAMERA_DIMS 2
#define INTEGRATOR_DIMS_PER_BOUNCE 6

/* Radiance along r (a camera ray) in the scene s. The random numbers come
 * from rng (dimension 2 onwards). Never returns NaN or Inf: such a sample is
 * counted in stats->bad_samples and returned as black. Can't fail. */
vec3 integrator_radiance(const scene *s, const integrator_options *opt, const ray *r, const sampler_stream *rng,
                         trace_stats *stats);

#endif
