/* list.h - the one kind of intrusive list in Tessera: BSD <sys/queue.h>
 * (shipped with glibc), for every list and queue of the coordinator, the job
 * service and the worker. An element embeds its links (LIST_ENTRY,
 * TAILQ_ENTRY, ...), so adding or removing it never allocates.
 *
 * glibc's copy lacks the _SAFE iterators of FreeBSD's, which let the body
 * remove (or free) the element in hand; they are added here, as FreeBSD
 * defines them. */
#ifndef TESSERA_LIST_H
#define TESSERA_LIST_H

#include <sys/queue.h>

#ifndef LIST_FOREACH_SAFE
#define LIST_FOREACH_SAFE(var, head, field, tvar) \
    for ((var) = LIST_FIRST((head)); (var) && ((tvar) = LIST_NEXT((var), field), 1); (var) = (tvar))
#endif

#ifndef TAILQ_FOREACH_SAFE
#define TAILQ_FOREACH_SAFE(var, head, field, tvar) \
    for ((var) = TAILQ_FIRST((head)); (var) && ((tvar) = TAILQ_NEXT((var), field), 1); (var) = (tvar))
#endif

#ifndef STAILQ_FOREACH_SAFE
#define STAILQ_FOREACH_SAFE(var, head, field, tvar) \
    for ((var) = STAILQ_FIRST((head)); (var) && ((tvar) = STAILQ_NEXT((var), field), 1); (var) = (tvar))
#endif

#endif
