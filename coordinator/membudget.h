/* membudget.h - how much memory jobs may take (issue 20): the default
 * budget from the machine's RAM and the cgroup's limit, a job's need from
 * its frame and scene, sizes as people write and read them. The job
 * service admits a job only when its need fits beside the jobs already
 * admitted (--max-memory); `tessera render` refuses up front a frame it
 * cannot hold. */
#ifndef TESSERA_MEMBUDGET_H
#define TESSERA_MEMBUDGET_H

#include <stddef.h>
#include <stdint.h>

/* Per tile, what the farm keeps (rect, flags, queue slot, lease start). */
#define MEMBUDGET_TILE_BYTES 48

/* Three quarters of the smaller of physical RAM and the cgroup memory
 * limit (cgroup v2 memory.max or v1 memory.limit_in_bytes, when set).
 * how receives where the figure came from ("3/4 of 24.0 GiB of RAM").
 * Can't fail (1 GiB when nothing can be read). */
uint64_t membudget_default(char *how, size_t how_len);

/* What a job holds at its peak: its frame (width * height * 3 floats) and
 * the image encoder's copy of it when it is saved (image.h encodes whole
 * files in memory: 24 bytes a pixel in all), the farm's per-tile state and
 * its scene bundle. */
uint64_t membudget_job_bytes(int width, int height, int tiles, uint64_t scene_bytes);

/* "12.0 GiB", "640.0 MiB", "512 bytes" into out. Can't fail. */
void membudget_format(uint64_t bytes, char *out, size_t len);

/* An ARG_CUSTOM parser (args.h) for --max-memory into a uint64_t: a
 * number with an optional binary unit K, M, G or T (no unit: MiB), e.g.
 * "12G", "512M", "2048". Returns 0, or -1 with the fault in err. */
int membudget_parse(const char *value, void *dest, char *err, size_t err_len);

#endif
