/* jpeg_guard.h - libjpeg error handling that returns instead of exiting.
 *
 * libjpeg reports a fatal error by calling error_exit, which must not
 * return; its default prints and exits the process. A jpeg_guard jumps back
 * to the caller's setjmp with the message instead, and silences libjpeg's
 * warnings (a corrupt-data warning is followed by an error or by usable
 * pixels). Used by the image codecs (encoding) and the render layer's
 * texture decoder. Base layer: knows libjpeg, nothing of Tessera. */
#ifndef TESSERA_JPEG_GUARD_H
#define TESSERA_JPEG_GUARD_H

#include <setjmp.h>
#include <stdio.h>

#include <jpeglib.h>

/* Plain struct, owned by the caller (usually on the stack beside the
 * libjpeg (de)compress struct). After a fatal libjpeg error, control returns
 * from setjmp(guard.escape) with a non-zero value and guard.message holds
 * libjpeg's text. */
typedef struct {
    struct jpeg_error_mgr mgr;
    jmp_buf escape;
    char message[JMSG_LENGTH_MAX];
} jpeg_guard;

/* Set up *g and return the error manager to store in cinfo.err. The caller
 * must then call setjmp(g->escape) before any other libjpeg call. Can't
 * fail. */
struct jpeg_error_mgr *jpeg_guard_init(jpeg_guard *g);

#endif
