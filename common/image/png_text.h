/* png_text.h - tEXt chunks added to an encoded PNG file in memory, so that
 * a PNG carries the same tessera:* attributes as an EXR header. */
#ifndef TESSERA_PNG_TEXT_H
#define TESSERA_PNG_TEXT_H

#include <stddef.h>
#include <stdint.h>

#include "image_codecs.h"

/* Insert one tEXt chunk per attribute (keyword = name, text = value) right
 * after png's IHDR chunk. png is malloc'd, *len bytes; it is consumed: the
 * result is a new malloc'd buffer (the caller frees it) with *len updated,
 * or NULL with the reason in err (not a PNG, a name that is not a 1-79
 * byte keyword, out of memory). With count 0 png is returned unchanged. */
uint8_t *png_text_insert(uint8_t *png, size_t *len, const codec_attribute *attrs, int count, char *err,
                         size_t err_len);

#endif
