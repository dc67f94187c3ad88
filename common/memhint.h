/* memhint.h - hints to the kernel about big buffers (no effect on results).
 *
 * Transparent huge pages (where /sys/kernel/mm/transparent_hugepage/enabled
 * is always or madvise; elsewhere, or for small buffers, nothing happens)
 * put a buffer in fewer TLB entries and fault it in once per 2 MiB instead
 * of per 4 KiB. On a VM that hands freed memory back to its host, fresh
 * huge pages are slow to get (a 512 MB buffer's first touch 1.18-1.29 s
 * against 0.20-0.23 s on 4 KiB pages, 2026-11-28), so only what a render
 * reads at random asks for them, the wide BVH's arena and the triangle
 * records, and only for a render long enough to win that back
 * (scene_render_is_long in render/scene.h). The loader's temporaries,
 * written once and read a few times, never do: with every loader array on
 * huge pages (the records too) a 10.5M-triangle render at 256x256x16 took
 * 3.98-4.23 s against 3.55-3.98 s with none (docs/meshes.md). */
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

#endif
