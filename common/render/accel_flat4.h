/* accel_flat4.h - the flat kernel (accel_flat.h) at 4 lanes: SSE2, which
 * every x86-64 has (elsewhere, whatever the compiler makes of 16-byte
 * vectors). Define FLAT(name) before including; accel.c's flat intersector
 * and accel_wide.c's leaves include it. Not a public header. */
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define FLAT_LANES 4
#define FLAT_TARGET
#define FLAT_SPLAT(x) {x, x, x, x}
#define FLAT_LANE_IDS {0, 1, 2, 3}
#ifdef __SSE2__
#define FLAT_BITS(m) _mm_movemask_ps((__m128)(m))
#else
#define FLAT_BITS(m) (((m)[0] & 1) | ((m)[1] & 2) | ((m)[2] & 4) | ((m)[3] & 8))
#endif
#include "accel_flat.h"
