/* limit.h - the sizes Tessera accepts, in one place for the command line,
 * the scene loader, the wire format and the coordinator, so that what the
 * CLI lets through the coordinator takes, and the other way round. */
#ifndef TESSERA_LIMIT_H
#define TESSERA_LIMIT_H

#define LIMIT_SIDE 32768        /* image width or height, pixels */
#define LIMIT_SPP (1 << 24)     /* samples per pixel */
#define LIMIT_DEPTH 1024        /* path vertices (max_depth) */
#define LIMIT_PRIORITY 1000000  /* a job's priority: -LIMIT_PRIORITY to LIMIT_PRIORITY */
#define LIMIT_BUNDLE_BYTES (512u << 20)    /* a scene and every file it names */
#define LIMIT_BUNDLE_FILES 4096            /* files in one bundle */
#define LIMIT_UPLOAD_DEFAULT_MIB 64        /* tessera-coordinator --max-upload default: taken in (one copy on the loop) without a stall over 100 ms */
#define LIMIT_UPLOAD_MAX_MIB 512           /* ...and the most it may be set to */
#define LIMIT_ANSWER_BYTES ((size_t)2 << 30) /* the largest answer a client reads */

#endif
