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
 * first touch back (scene_render_is_long in render/scene.h), and every
 * big buffer, the loader's temporaries too, asks for them where they are
 * cheaper to fault in (memhint_huge_is_cheap): docs/meshes.md, "The goal,
 * per size" (nineteenth and twenty-ninth sessions).
 *
 * Both answers come from two figures, the milliseconds a first touch of
 * MEMHINT_PROBE_BYTES takes on each page size: 4 KiB pages' from a probe
 * (timed once per process), huge pages' from the probe and then from the
 * first MEMHINT_PROBE_BYTES of every big buffer about to go on them
 * (MEMHINT_SAMPLE_MIN_BYTES), the latest figure standing. A probe alone can
 * be fooled: a VM's kernel keeps a few huge pages it got back from the
 * host a moment ago, and 4 MiB of them fault in at 8 GB/s while the next
 * hundred megabytes come at 0.4 GB/s (docs/meshes.md). */
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
 * their latest figure (above) under 3/4 of the 4 KiB pages'. The first
 * call (thread-safe) runs the probe: a first touch of MEMHINT_PROBE_BYTES
 * each way in fresh mappings, about 2-20 ms. TESSERA_HUGE_PAGES=1 or 0 in
 * the environment decides instead (looked up on every call; tests). Can't
 * fail: a probe that cannot map says no. */
#define MEMHINT_PROBE_BYTES ((size_t)4 << 20)
int memhint_huge_is_cheap(void);

/* The figures, in milliseconds per MEMHINT_PROBE_BYTES: the probe's two,
 * and huge pages' latest from a buffer (each -1 when there is none: the
 * probe has not run, could not map, or no buffer was sampled). */
void memhint_probe_ms(double *small_pages, double *huge_pages);
double memhint_sampled_ms(void);

/* For tests: the probe run if it has not, then its figures and huge
 * pages' latest replaced by these (negative: none). */
void memhint_set_figures(double small_ms, double huge_ms, double sampled);

/* memhint_huge_is_cheap's rule applied to figures (negative: none).
 * Pure; for tests and the function itself. */
int memhint_rule_cheap(double small_ms, double huge_ms);

/* Buffers of at least this many bytes are sampled before they are given
 * huge pages (memhint_fresh_huge): their first MEMHINT_PROBE_BYTES go on
 * huge pages, are faulted in at once (MADV_POPULATE_WRITE, which leaves
 * the contents as they are: zero) and timed, and that time becomes huge
 * pages' latest figure, which then decides for the rest of the buffer.
 * Only where none of those pages is resident yet (a grown buffer's front
 * is not a first touch), and not when TESSERA_HUGE_PAGES decides. Smaller
 * buffers follow the figure without a sample. */
#define MEMHINT_SAMPLE_MIN_BYTES ((size_t)16 << 20)

/* A big buffer about to be written for the first time, all of it: on huge
 * pages if memhint_fresh_wants_huge says so, before and after its sample
 * (above). Returns 1 if [p, p + bytes) asked for huge pages, else 0 (then
 * at most its sampled front is on them). Can't fail; p may be NULL (0). */
int memhint_fresh_huge(void *p, size_t bytes);

/* Whether a buffer of `bytes` that no long render reads at random should
 * still ask for huge pages: one big enough for a hint (MEMHINT_MIN_BYTES)
 * on a host where they are cheaper to fault in. Probes on first need only:
 * small buffers never pay for the probe. */
static inline int memhint_fresh_wants_huge(size_t bytes) {
    return bytes >= MEMHINT_MIN_BYTES && memhint_huge_is_cheap();
}

/* memhint_fresh_huge without its answer. */
static inline void memhint_fresh(void *p, size_t bytes) { (void)memhint_fresh_huge(p, bytes); }

#endif
