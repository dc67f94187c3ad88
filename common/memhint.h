/* memhint.h - hints to the kernel about big buffers (no effect on results).
 *
 * A buffer of hundreds of megabytes that is about to be written once, in
 * order, costs one page fault (and one cleared page) per 4 KiB; asking for
 * transparent huge pages makes that one fault per 2 MiB where the kernel
 * allows it (/sys/kernel/mm/transparent_hugepage/enabled: always or
 * madvise). Elsewhere, or for small buffers, nothing happens. */
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
