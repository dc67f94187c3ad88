/* memhint.h - hints to the kernel about big buffers (no effect on results).
 *
 * Transparent huge pages (where /sys/kernel/mm/transparent_hugepage/enabled
 * is always or madvise; elsewhere, or for small buffers, nothing happens)
 * put a buffer in fewer TLB entries and fault it in once per 2 MiB instead
 * of per 4 KiB. What a first touch costs depends on the host, and by
 * more than either rule could absorb:
 * - on a VM that hands freed memory back to its host, fresh huge pages
 *   are slow to get (a 512 MB buffer's first touch 1.18-1.29 s against
 *   0.20-0.23 s on 4 KiB pages, an Intel host, 2026-11-28);
 * - on a VM that traps every 4 KiB fault (a PVM guest), the reverse: 1.48
 *   s on 4 KiB pages against 0.71-0.92 s on huge ones (an AMD Zen 5
 *   host, the same day).
 * So what a render reads at random (the wide BVH's arena, the triangle
 * records) asks for huge pages for a render long enough to win their
 * first touch back (scene_render_is_long in render/scene.h), and every big
 * buffer, the loader's temporaries too, asks for them where a probe of
 * this host (memhint_huge_is_cheap, memhint.c) finds them cheaper to fault
 * in: docs/meshes.md, "The goal, per size" (nineteenth session). */
#ifndef TESSERA_MEMHINT_H
#define TESSERA_MEMHINT_H

#include <stddef.h>
#include <stdint.h>
#include <sys/mman.h>

#define MEMHINT_MIN_BYTES (4u << 20) /* smaller buffers: not worth a system call */

/* Ask for huge pages over the 2 MiB-aligned part of [p, p + bytes). Can't
 * fail (a refusal is ignored); p may be NULL. */
static inline void memhint_huge(void *p, size_t bytes) {
#ifdef MADV_HUGEPAGE
    if (!p || bytes < MEMHINT_MIN_BYTES) return;
    uintptr_t huge = (uintptr_t)2 << 20, lo = ((uintptr_t)p + huge - 1) & ~(huge - 1),
              hi = ((uintptr_t)p + bytes) & ~(huge - 1);
    if (hi > lo) (void)madvise((void *)lo, hi - lo, MADV_HUGEPAGE);
#else
    (void)p;
    (void)bytes;
#endif
}

/* Whether fresh huge pages are cheaper to fault in here than 4 KiB ones:
 * the first call (thread-safe) times a first touch of MEMHINT_PROBE_BYTES
 * each way in fresh mappings, about 2-20 ms, and the answer is kept for
 * the process. TESSERA_HUGE_PAGES=1 or 0 in the environment decides
 * instead (looked up on every call; tests). Huge pages count as cheaper
 * when their touch took under 3/4 of the other's. Can't fail: a probe
 * that cannot map says no. */
#define MEMHINT_PROBE_BYTES ((size_t)4 << 20)
int memhint_huge_is_cheap(void);

/* The probe's figures, in milliseconds (each -1 when it could not map, or
 * both -1 when the probe has not run: the environment decided, or nobody
 * asked). */
void memhint_probe_ms(double *small_pages, double *huge_pages);

/* Whether a buffer of `bytes` that no long render reads at random should
 * still ask for huge pages: one big enough for a hint (MEMHINT_MIN_BYTES)
 * on a host where they are cheaper to fault in. Probes on first need only:
 * small buffers never pay for the probe. */
static inline int memhint_fresh_wants_huge(size_t bytes) {
    return bytes >= MEMHINT_MIN_BYTES && memhint_huge_is_cheap();
}

/* A big buffer about to be written for the first time: huge pages for it
 * where memhint_fresh_wants_huge says so. Can't fail; p may be NULL. */
static inline void memhint_fresh(void *p, size_t bytes) {
    if (p && memhint_fresh_wants_huge(bytes)) memhint_huge(p, bytes);
}

#endif
