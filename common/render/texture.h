/* texture.h - decoded image textures (PNG, JPEG) and their filtered lookup.
 *
 * A texture keeps 8-bit RGBA texels as the file stored them and decodes on
 * lookup: sRGB-encoded colour (glTF baseColorTexture, OBJ map_Kd) through the
 * sRGB transfer curve to linear, data textures (metallic-roughness, normal
 * maps) as plain value / 255. Lookup is bilinear, with glTF's wrap modes, and
 * UV orientation per the glTF spec: (0, 0) is the top-left corner of the
 * image's first row, v grows down the image. */
#ifndef TESSERA_TEXTURE_H
#define TESSERA_TEXTURE_H

#include <stddef.h>
#include <stdint.h>

#include "vec.h"

/* Refused before decoding: a texture may hold at most this many texels and
 * be at most TEXTURE_MAX_SIDE on a side (a 16384^2 RGBA texture is 1 GiB). */
#define TEXTURE_MAX_SIDE 16384
#define TEXTURE_MAX_TEXELS (64u << 20)

typedef enum { WRAP_REPEAT, WRAP_CLAMP, WRAP_MIRROR } texture_wrap;

typedef struct texture {
    int width, height;
    uint8_t *rgba;     /* width * height * 4, top row first */
    int srgb;          /* colour: decode RGB through the sRGB curve */
    texture_wrap wrap_s, wrap_t;
} texture;

typedef struct {
    vec3 rgb; /* linear */
    float a;
} texel;

/* Decode a PNG or JPEG file held in memory (told apart by their signature)
 * into *out (wrap REPEAT, srgb 0; set them after). The declared size is
 * checked against the limits above before anything is decoded. Returns 0,
 * or -1 with "NAME: reason" in err. Free with texture_free. */
int texture_decode(const uint8_t *data, size_t len, const char *name, texture *out, char *err, size_t err_len);

/* Bilinear lookup at (u, v), wrapped per the texture's modes. NaN or infinite
 * coordinates read texel (0, 0). Can't fail. */
texel texture_lookup(const texture *t, float u, float v);

/* sRGB-encoded 8-bit value to linear (exact table of the IEC 61966-2-1 curve). */
float texture_srgb_to_linear(uint8_t c);

/* Free the texels; the struct itself is the caller's. NULL is allowed. */
void texture_free(texture *t);

#endif
