/* jpeg_guard.c - libjpeg errors as a longjmp with the message (see
 * jpeg_guard.h). */
#include "jpeg_guard.h"

static void guard_error_exit(j_common_ptr cinfo) {
    jpeg_guard *g = (jpeg_guard *)cinfo->err;
    cinfo->err->format_message(cinfo, g->message);
    longjmp(g->escape, 1);
}

static void guard_emit_message(j_common_ptr cinfo, int level) {
    (void)cinfo;
    (void)level;
}

struct jpeg_error_mgr *jpeg_guard_init(jpeg_guard *g) {
    g->message[0] = '\0';
    struct jpeg_error_mgr *mgr = jpeg_std_error(&g->mgr);
    mgr->error_exit = guard_error_exit;
    mgr->emit_message = guard_emit_message;
    return mgr;
}
