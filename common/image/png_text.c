/* png_text.c - tEXt chunks for an encoded PNG (see png_text.h).
 *
 * A chunk is: u32 length (big-endian), 4-byte type, data, u32 CRC-32 of
 * type and data (PNG specification, section 5.3). A tEXt chunk's data is
 * a keyword of 1 to 79 bytes, a zero byte, then the text (section 11.3.4.3).
 * IHDR is always the first chunk, at byte 8, 25 bytes long. */
#include "png_text.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PNG_SIGNATURE_BYTES 8
#define PNG_IHDR_END (PNG_SIGNATURE_BYTES + 4 + 4 + 13 + 4)

/* CRC-32 (ISO-HDLC, reflected polynomial 0xedb88320), the PNG chunk check. */
static uint32_t crc32_update(uint32_t crc, const uint8_t *p, size_t n) {
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

static void put_be32(uint8_t *p, uint32_t v) {
    p[0] = (uint8_t)(v >> 24);
    p[1] = (uint8_t)(v >> 16);
    p[2] = (uint8_t)(v >> 8);
    p[3] = (uint8_t)v;
}

uint8_t *png_text_insert(uint8_t *png, size_t *len, const codec_attribute *attrs, int count, char *err,
                         size_t err_len) {
    static const uint8_t sig[PNG_SIGNATURE_BYTES] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    if (count <= 0) return png;
    if (*len < PNG_IHDR_END || memcmp(png, sig, sizeof sig) != 0 || memcmp(png + 12, "IHDR", 4) != 0) {
        snprintf(err, err_len, "tEXt: not a PNG file");
        free(png);
        return NULL;
    }
    size_t extra = 0;
    for (int i = 0; i < count; i++) {
        size_t kl = strlen(attrs[i].name);
        if (kl < 1 || kl > 79) {
            snprintf(err, err_len, "tEXt: keyword \"%.90s\" must be 1 to 79 bytes", attrs[i].name);
            free(png);
            return NULL;
        }
        extra += 12 + kl + 1 + strlen(attrs[i].value);
    }
    uint8_t *out = malloc(*len + extra);
    if (!out) {
        snprintf(err, err_len, "out of memory");
        free(png);
        return NULL;
    }
    memcpy(out, png, PNG_IHDR_END);
    uint8_t *p = out + PNG_IHDR_END;
    for (int i = 0; i < count; i++) {
        size_t kl = strlen(attrs[i].name), vl = strlen(attrs[i].value);
        put_be32(p, (uint32_t)(kl + 1 + vl));
        memcpy(p + 4, "tEXt", 4);
        memcpy(p + 8, attrs[i].name, kl);
        p[8 + kl] = 0;
        memcpy(p + 9 + kl, attrs[i].value, vl);
        put_be32(p + 9 + kl + vl, crc32_update(0, p + 4, 4 + kl + 1 + vl));
        p += 12 + kl + 1 + vl;
    }
    memcpy(p, png + PNG_IHDR_END, *len - PNG_IHDR_END);
    *len += extra;
    free(png);
    return out;
}
