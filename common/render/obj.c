/* obj.c - a reader for the geometry part of Wavefront OBJ files.
 *
 * One pass over the text, line by line, parsed where it lies (a line ends
 * at its '\n'; only a last line without one is copied, to end it with a
 * NUL). Indices are resolved as they are read (OBJ allows negative indices
 * relative to the vertices so far), so a face that names a vertex not yet
 * defined is an error on its own line.
 *
 * A big text is cut at line ends into one span per core (par.h). Each span
 * first counts its lines and its v, vn and vt records; with the counts of
 * the spans before it, a span is then parsed on its own, resolving indices
 * as the one pass would, and the spans' arrays are joined in file order:
 * the same mesh. A text with any error (or too many triangles in all) is
 * parsed again in one pass, which finds the same first error as always. */
#include "obj.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"
#include "memhint.h"
#include "par.h"

#define OBJ_MAX_FILE (1u << 30) /* 1 GiB of text */
#define OBJ_MAX_POLY 64         /* vertices per face */
#define OBJ_MAX_TRIANGLES (1u << 25) /* 33.5M: a scene's memory stays within a machine's */

/* Make room for `need` elements of `size` bytes in *arr (capacity *cap).
 * Returns 0, or -1 when out of memory (then *arr is unchanged). */
static int grow(void **arr, size_t *cap, size_t need, size_t size) {
    if (need <= *cap) return 0;
    size_t n = *cap ? *cap : 256;
    while (n < need) n *= 2;
    void *p = realloc(*arr, n * size);
    if (!p) return -1;
    *arr = p;
    *cap = n;
    return 0;
}

#define OBJ_MAX_LINE 4096 /* bytes, with the '\n' or NUL */

/* strtod or strtol (10) of s, which must not look past its line: the rest of
 * the line (to '\n' or NUL, shorter than OBJ_MAX_LINE) is copied and
 * NUL-terminated first, as the C functions skip any blank, newlines too.
 * Sets *end like they do and returns the result in *d or *l. */
static void parse_in_line(const char *s, char **end, double *d, long *l) {
    char copy[OBJ_MAX_LINE], *e;
    size_t n = 0;
    while (n < sizeof copy - 1 && s[n] != '\n' && s[n] != '\0') n++;
    memcpy(copy, s, n);
    copy[n] = '\0';
    if (d) *d = strtod(copy, &e);
    else *l = strtol(copy, &e, 10);
    *end = (char *)s + (e - copy);
}

static double strtod_line(const char *s, char **end) {
    double d;
    parse_in_line(s, end, &d, NULL);
    return d;
}

static long strtol_line(const char *s, char **end) {
    long l;
    parse_in_line(s, end, NULL, &l);
    return l;
}

/* strtod(s, end), faster for the plain decimals OBJ writers print
 * ("-0.5257311", "1e-3"), with exactly strtod's result: when the digits
 * form an integer m < 2^53 and the power of ten p has |p| <= 22, both m and
 * 10^|p| are exact doubles and one IEEE multiplication or division rounds
 * m * 10^p correctly, as strtod does (Clinger's fast path). Anything else
 * (more digits, big exponents, inf, nan, hex, a number not followed by
 * a blank) goes to strtod itself. */
static double parse_double(const char *s, char **end) {
    static const double pow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                     1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
    const char *p = s;
    while (*p == ' ' || *p == '\t') p++;
    int neg = *p == '-';
    if (*p == '-' || *p == '+') p++;
    uint64_t m = 0;
    int digits = 0, frac = 0, exp = 0;
    for (; *p >= '0' && *p <= '9'; p++, digits++) m = m * 10 + (uint64_t)(*p - '0');
    if (*p == '.')
        for (p++; *p >= '0' && *p <= '9'; p++, digits++, frac++) m = m * 10 + (uint64_t)(*p - '0');
    if (digits == 0 || digits > 19) return strtod_line(s, end);
    if (*p == 'e' || *p == 'E') {
        const char *q = p + 1;
        int eneg = *q == '-';
        if (*q == '-' || *q == '+') q++;
        if (!(*q >= '0' && *q <= '9')) return strtod_line(s, end);
        for (; *q >= '0' && *q <= '9' && exp < 1000; q++) exp = exp * 10 + (*q - '0');
        if (eneg) exp = -exp;
        p = q;
    }
    if (!(*p == ' ' || *p == '\t' || *p == '\0' || *p == '\r' || *p == '\n' || *p == '#')) return strtod_line(s, end);
    int p10 = exp - frac;
    if (m > (1ull << 53) || p10 > 22 || p10 < -22) return strtod_line(s, end);
    double v = p10 >= 0 ? (double)m * pow10[p10] : (double)m / pow10[-p10];
    *end = (char *)p;
    return neg ? -v : v;
}

/* strtol(s, end, 10), with a fast path for plain digits; same results. */
static long parse_long(const char *s, char **end) {
    const char *p = s;
    int neg = *p == '-';
    if (neg) p++;
    long v = 0;
    int digits = 0;
    for (; *p >= '0' && *p <= '9' && digits < 18; p++, digits++) v = v * 10 + (*p - '0');
    if (digits == 0 || (*p >= '0' && *p <= '9')) return strtol_line(s, end);
    *end = (char *)p;
    return neg ? -v : v;
}

typedef struct {
    const char *name;
    size_t line;
    char *err;
    size_t err_len;
    obj_mesh *m;
    size_t pos_cap, idx_cap, n_cap, uv_cap, nidx_cap, uvidx_cap;
    size_t v_base, vn_base, vt_base; /* records in the spans before this one */
    int window; /* positions, normals, uvs and indices are windows of a whole text's arrays: they cannot grow */
} obj_reader;

/* grow() for the arrays that may be windows. */
static int reserve(obj_reader *r, void **arr, size_t *cap, size_t need, size_t size) {
    if (r->window && need > *cap) return -1;
    return grow(arr, cap, need, size);
}

static int obj_fail(obj_reader *r, const char *what) {
    snprintf(r->err, r->err_len, "%s:%zu: %s", r->name, r->line, what);
    return -1;
}

/* Parse "v x y z [w]". */
static int read_vertex(obj_reader *r, const char *s) {
    double p[3];
    for (int i = 0; i < 3; i++) {
        char *end;
        p[i] = parse_double(s, &end);
        if (end == s) return obj_fail(r, "vertex needs three numbers");
        if (!isfinite(p[i])) return obj_fail(r, "vertex coordinate is not finite");
        s = end;
    }
    obj_mesh *m = r->m;
    if (reserve(r, (void **)&m->positions, &r->pos_cap, 3 * (m->vertex_count + 1), sizeof(double)))
        return obj_fail(r, "out of memory");
    memcpy(m->positions + 3 * m->vertex_count, p, sizeof p);
    m->vertex_count++;
    return 0;
}

/* Parse "vn x y z" (dims 3) or "vt u [v [w]]" (dims 2: u and v, v = 0 when
 * absent) into *arr (count entries so far, capacity *cap). */
static int read_attribute(obj_reader *r, const char *s, int dims, float **arr, size_t *count, size_t *cap) {
    float p[3] = {0, 0, 0};
    for (int i = 0; i < dims; i++) {
        char *end;
        double x = parse_double(s, &end);
        if (end == s) {
            if (dims == 2 && i == 1) break;
            return obj_fail(r, dims == 3 ? "normal needs three numbers" : "texture coordinate needs a number");
        }
        if (!isfinite(x) || !isfinite((float)x))
            return obj_fail(r, dims == 3 ? "normal is not finite" : "texture coordinate is not finite");
        p[i] = (float)x;
        s = end;
    }
    if (reserve(r, (void **)arr, cap, (size_t)dims * (*count + 1), sizeof(float))) return obj_fail(r, "out of memory");
    memcpy(*arr + (size_t)dims * *count, p, (size_t)dims * sizeof(float));
    (*count)++;
    return 0;
}

/* Resolve a 1-based or negative OBJ index against n entries. Returns the
 * 0-based index, or -1 when it names nothing. */
static long resolve_index(long v, size_t n) {
    long idx = v > 0 ? v - 1 : (long)n + v;
    return v == 0 || idx < 0 || idx >= (long)n ? -1 : idx;
}

/* One face corner: 0-based indices, OBJ_NONE where the corner names none. */
typedef struct {
    uint32_t v, t, n;
} obj_corner;

/* Parse one face corner "i", "i/t", "i//n" or "i/t/n"; *s is advanced past
 * it. Returns 1 for a corner, 0 at the end of the line, -1 on error. */
static int read_corner(obj_reader *r, const char **s, obj_corner *out) {
    const char *p = *s;
    while (*p == ' ' || *p == '\t') p++;
    if (*p == '\0' || *p == '\r' || *p == '\n' || *p == '#') return 0;
    char *end;
    long v = parse_long(p, &end);
    if (end == p) return obj_fail(r, "face corner is not an index");
    long idx = resolve_index(v, r->v_base + r->m->vertex_count);
    if (idx < 0) return obj_fail(r, "face refers to a vertex that does not exist");
    out->v = (uint32_t)idx;
    out->t = out->n = OBJ_NONE;
    for (int part = 0; part < 2 && *end == '/'; part++) {
        p = end + 1;
        if (part == 0 && *p == '/') { /* i//n */
            end = (char *)p;
            continue;
        }
        v = 0;
        end = (char *)p;
        if (isdigit((unsigned char)*p) || *p == '-') v = parse_long(p, &end);
        if (end == p) return obj_fail(r, part ? "face corner's normal index is missing" : "face corner's texture index is missing");
        idx = resolve_index(v, part ? r->vn_base + r->m->normal_count : r->vt_base + r->m->uv_count);
        if (idx < 0)
            return obj_fail(r, part ? "face refers to a normal that does not exist"
                                    : "face refers to a texture coordinate that does not exist");
        *(part ? &out->n : &out->t) = (uint32_t)idx;
    }
    if (*end && !isspace((unsigned char)*end)) return obj_fail(r, "face corner is not of the form v, v/t, v//n or v/t/n");
    *s = end;
    return 1;
}

/* Append 3 indices per new triangle to *arr (allocated on first use, earlier
 * triangles then get OBJ_NONE). */
static int push_attribute_indices(obj_reader *r, uint32_t **arr, size_t *cap, const uint32_t *tri, size_t first) {
    if (!*arr) {
        if (grow((void **)arr, cap, 3 * (first + 1), sizeof(uint32_t))) return -1;
        for (size_t i = 0; i < 3 * first; i++) (*arr)[i] = OBJ_NONE;
    } else if (grow((void **)arr, cap, 3 * (first + 1), sizeof(uint32_t))) {
        return -1;
    }
    memcpy(*arr + 3 * first, tri, 3 * sizeof(uint32_t));
    (void)r;
    return 0;
}

/* Parse "f a b c ..." and fan-triangulate it. */
static int read_face(obj_reader *r, const char *s) {
    obj_corner corner[OBJ_MAX_POLY], c;
    int count = 0, rc;
    while ((rc = read_corner(r, &s, &c)) == 1) {
        if (count == OBJ_MAX_POLY) return obj_fail(r, "face has more than 64 vertices");
        if (count && ((c.n == OBJ_NONE) != (corner[0].n == OBJ_NONE) || (c.t == OBJ_NONE) != (corner[0].t == OBJ_NONE)))
            return obj_fail(r, "face mixes corners with and without normals or texture coordinates");
        corner[count++] = c;
    }
    if (rc < 0) return -1;
    if (count < 3) return obj_fail(r, "face needs at least three vertices");
    obj_mesh *m = r->m;
    size_t tris = (size_t)count - 2;
    if (m->triangle_count + tris > OBJ_MAX_TRIANGLES) return obj_fail(r, "more than 33554432 triangles");
    if (reserve(r, (void **)&m->indices, &r->idx_cap, 3 * (m->triangle_count + tris), sizeof(uint32_t)))
        return obj_fail(r, "out of memory");
    for (int i = 1; i + 1 < count; i++) {
        const obj_corner *k[3] = {&corner[0], &corner[i], &corner[i + 1]};
        uint32_t v[3] = {k[0]->v, k[1]->v, k[2]->v}, n[3] = {k[0]->n, k[1]->n, k[2]->n},
                 t[3] = {k[0]->t, k[1]->t, k[2]->t};
        if ((n[0] != OBJ_NONE || m->normal_indices) &&
            push_attribute_indices(r, &m->normal_indices, &r->nidx_cap, n, m->triangle_count))
            return obj_fail(r, "out of memory");
        if ((t[0] != OBJ_NONE || m->uv_indices) &&
            push_attribute_indices(r, &m->uv_indices, &r->uvidx_cap, t, m->triangle_count))
            return obj_fail(r, "out of memory");
        memcpy(m->indices + 3 * m->triangle_count++, v, sizeof v);
    }
    return 0;
}

/* Parse the lines of buf[pos, end) (end: a line's start, or len) into
 * r->m, which the caller has cleared. Returns 0, or -1 with r->err set. */
static int parse_lines(obj_reader *r, const char *buf, size_t pos, size_t end) {
    char last[OBJ_MAX_LINE]; /* the last line when no '\n' ends it */
    obj_mesh *out = r->m;
    while (pos < end) {
        const char *nl = memchr(buf + pos, '\n', end - pos), *line = buf + pos;
        size_t n = nl ? (size_t)(nl - line) : end - pos;
        r->line++;
        if (n >= OBJ_MAX_LINE) return obj_fail(r, "line longer than 4095 characters");
        if (memchr(line, '\0', n)) return obj_fail(r, "NUL byte in text");
        if (!nl) {
            memcpy(last, line, n);
            last[n] = '\0';
            line = last;
        }
        pos += n + 1;
        const char *s = line;
        while (*s == ' ' || *s == '\t') s++;
        int rc = 0;
        if (s[0] == 'v' && (s[1] == ' ' || s[1] == '\t'))
            rc = read_vertex(r, s + 2);
        else if (s[0] == 'f' && (s[1] == ' ' || s[1] == '\t'))
            rc = read_face(r, s + 2);
        else if (s[0] == 'v' && s[1] == 'n' && (s[2] == ' ' || s[2] == '\t'))
            rc = read_attribute(r, s + 3, 3, &out->normals, &out->normal_count, &r->n_cap);
        else if (s[0] == 'v' && s[1] == 't' && (s[2] == ' ' || s[2] == '\t'))
            rc = read_attribute(r, s + 3, 2, &out->uvs, &out->uv_count, &r->uv_cap);
        if (rc) return -1;
    }
    return 0;
}

/* The text in one pass. */
static int parse_serial(const char *buf, size_t len, const char *name, obj_mesh *out, char *err, size_t err_len) {
    obj_reader r = {.name = name, .err = err, .err_len = err_len, .m = out};
    memset(out, 0, sizeof *out);
    if (parse_lines(&r, buf, 0, len)) goto fail;
    if (out->triangle_count == 0) {
        snprintf(err, err_len, "%s: no faces", name);
        goto fail;
    }
    return 0;
fail:
    obj_mesh_free(out);
    return -1;
}

#define OBJ_SPAN_MIN (4u << 20) /* bytes: smaller texts are parsed in one pass */

/* One span of a text parsed in parts: its bytes, what it counts, where its
 * records go. */
typedef struct {
    size_t begin, end;             /* bytes; end is a line's start, or the text's end */
    size_t lines, v, vn, vt, tris; /* counted before parsing; tris from the corners of `f` lines */
    obj_mesh m;                    /* windows of the text's arrays, and its own attribute indices */
    int failed;
    char err[8];                   /* a span's message is not kept: a failed text is parsed again */
} obj_span;

typedef struct {
    const char *buf, *name;
    obj_mesh *out; /* the text's arrays */
    obj_span span[PAR_MAX_PARTS];
} obj_spans;

/* Triangles an `f` line's corners make, s past the "f": corners are
 * separated by blanks and end at '\r', '#' or the line's end, as
 * read_corner reads them in a well-formed face (an odd one, which parses to
 * more, only makes its span fail; see parse_span). */
static size_t count_face(const char *s, const char *stop) {
    size_t corners = 0;
    for (int in_token = 0; s < stop && *s != '\r' && *s != '#'; s++) {
        int blank = *s == ' ' || *s == '\t';
        corners += !blank && !in_token;
        in_token = !blank;
    }
    return corners > 2 ? corners - 2 : 0;
}

/* Count span k's lines, its v, vn and vt records (classified as
 * parse_lines does: each adds one record or makes the text fail) and the
 * triangles of its faces. */
static void count_span(void *ctx, size_t b, size_t e, int k) {
    obj_span *sp = &((obj_spans *)ctx)->span[k];
    const char *buf = ((obj_spans *)ctx)->buf;
    (void)b;
    (void)e;
    for (size_t pos = sp->begin; pos < sp->end;) {
        const char *nl = memchr(buf + pos, '\n', sp->end - pos), *s = buf + pos, *stop = nl ? nl : buf + sp->end;
        sp->lines++;
        while (s < stop && (*s == ' ' || *s == '\t')) s++;
        if (stop - s >= 2 && (s[1] == ' ' || s[1] == '\t')) {
            sp->v += s[0] == 'v';
            if (s[0] == 'f') sp->tris += count_face(s + 1, stop);
        } else if (stop - s >= 3 && s[0] == 'v' && (s[2] == ' ' || s[2] == '\t')) {
            sp->vn += s[1] == 'n';
            sp->vt += s[1] == 't';
        }
        pos = (size_t)(stop - buf) + 1;
    }
}

/* Parse span k into its windows of the text's arrays, its indices resolved
 * against the records of the spans before it. A span that would need more
 * room than counted fails (and the text is parsed again in one pass). */
static void parse_span(void *ctx, size_t b, size_t e, int k) {
    obj_spans *S = ctx;
    obj_span *sp = &S->span[k];
    obj_reader r = {.name = S->name, .err = sp->err, .err_len = sizeof sp->err, .m = &sp->m, .window = 1};
    size_t tri_base = 0;
    (void)b;
    (void)e;
    for (int j = 0; j < k; j++) {
        r.line += S->span[j].lines;
        r.v_base += S->span[j].v;
        r.vn_base += S->span[j].vn;
        r.vt_base += S->span[j].vt;
        tri_base += S->span[j].tris;
    }
    sp->m.positions = S->out->positions + 3 * r.v_base;
    sp->m.normals = S->out->normals ? S->out->normals + 3 * r.vn_base : NULL;
    sp->m.uvs = S->out->uvs ? S->out->uvs + 2 * r.vt_base : NULL;
    sp->m.indices = S->out->indices + 3 * tri_base;
    r.pos_cap = 3 * sp->v;
    r.n_cap = 3 * sp->vn;
    r.uv_cap = 2 * sp->vt;
    r.idx_cap = 3 * sp->tris;
    sp->failed = parse_lines(&r, S->buf, sp->begin, sp->end) != 0 || sp->m.vertex_count != sp->v ||
                 sp->m.normal_count != sp->vn || sp->m.uv_count != sp->vt;
}

/* Append a span's per-triangle attribute indices (3 per triangle; OBJ_NONE
 * for a span without them) to *dst, which holds `have` triangles' (OBJ_NONE
 * there if it is NULL). Nothing happens while no span has any. */
static int join_corners(uint32_t **dst, size_t have, const uint32_t *src, size_t n) {
    if (!*dst && !src) return 0;
    uint32_t *p = realloc(*dst, 3 * (have + n) * sizeof *p);
    if (!p) return -1;
    if (!*dst)
        for (size_t i = 0; i < 3 * have; i++) p[i] = OBJ_NONE;
    for (size_t i = 0; i < 3 * n; i++) p[3 * have + i] = src ? src[i] : OBJ_NONE;
    *dst = p;
    return 0;
}

/* Join the parsed spans in out: counts, triangles moved down over what a
 * span counted but did not make, attribute indices. Returns 0, or -1 when
 * out of memory. */
static int join_spans(obj_spans *S, int parts, obj_mesh *out) {
    int rc = 0;
    for (int k = 0; k < parts; k++) {
        obj_mesh *m = &S->span[k].m;
        size_t t = out->triangle_count;
        if (m->indices != out->indices + 3 * t)
            memmove(out->indices + 3 * t, m->indices, 3 * m->triangle_count * sizeof(uint32_t));
        rc = rc || join_corners(&out->normal_indices, t, m->normal_indices, m->triangle_count) ||
             join_corners(&out->uv_indices, t, m->uv_indices, m->triangle_count);
        out->vertex_count += m->vertex_count;
        out->normal_count += m->normal_count;
        out->uv_count += m->uv_count;
        out->triangle_count += m->triangle_count;
        free(m->normal_indices);
        free(m->uv_indices);
        m->normal_indices = m->uv_indices = NULL;
    }
    return rc ? -1 : 0;
}

/* Allocate out's arrays for the counted records. Returns 0 or -1. */
static int alloc_counted(obj_mesh *out, size_t v, size_t vn, size_t vt, size_t tris) {
    out->positions = malloc((3 * v + 1) * sizeof(double));
    out->indices = malloc((3 * tris + 1) * sizeof(uint32_t));
    out->normals = vn ? malloc(3 * vn * sizeof(float)) : NULL;
    out->uvs = vt ? malloc(2 * vt * sizeof(float)) : NULL;
    memhint_fresh(out->positions, (3 * v + 1) * sizeof(double));
    memhint_fresh(out->indices, (3 * tris + 1) * sizeof(uint32_t));
    if (out->normals) memhint_fresh(out->normals, 3 * vn * sizeof(float));
    if (out->uvs) memhint_fresh(out->uvs, 2 * vt * sizeof(float));
    if (!out->positions || !out->indices || (vn && !out->normals) || (vt && !out->uvs)) return -1;
    return 0;
}

int obj_parse_spans(const char *buf, size_t len, const char *name, int parts, obj_mesh *out) {
    obj_spans S;
    memset(out, 0, sizeof *out);
    if (parts < 1 || parts > PAR_MAX_PARTS) return -1;
    memset(&S, 0, sizeof S);
    S.buf = buf;
    S.name = name;
    S.out = out;
    size_t at = 0, v = 0, vn = 0, vt = 0, tris = 0;
    for (int k = 0; k < parts; k++) { /* cut after the '\n' that ends the line holding the even share's end */
        size_t b, e;
        par_range(len, parts, k, &b, &e);
        S.span[k].begin = at;
        const char *nl = e < len && e > at ? memchr(buf + e - 1, '\n', len - (e - 1)) : NULL;
        at = k == parts - 1 ? len : nl ? (size_t)(nl - buf) + 1 : e > at ? len : at;
        S.span[k].end = at;
    }
    par_run((size_t)parts, parts, count_span, &S);
    for (int k = 0; k < parts; k++) {
        v += S.span[k].v, vn += S.span[k].vn, vt += S.span[k].vt, tris += S.span[k].tris;
    }
    if (tris == 0 || tris > OBJ_MAX_TRIANGLES || alloc_counted(out, v, vn, vt, tris)) return obj_mesh_free(out), -1;
    par_run((size_t)parts, parts, parse_span, &S);
    int failed = 0;
    for (int k = 0; k < parts; k++) failed |= S.span[k].failed;
    if (failed || join_spans(&S, parts, out)) {
        for (int k = 0; k < parts; k++) {
            free(S.span[k].m.normal_indices);
            free(S.span[k].m.uv_indices);
        }
        obj_mesh_free(out);
        return -1;
    }
    if (out->triangle_count == 0) return obj_mesh_free(out), -1;
    return 0;
}

int obj_parse(const char *buf, size_t len, const char *name, obj_mesh *out, char *err, size_t err_len) {
    int parts = par_parts_touch(len, OBJ_SPAN_MIN);
    if (parts > 1 && obj_parse_spans(buf, len, name, parts, out) == 0) return 0;
    return parse_serial(buf, len, name, out, err, err_len);
}

int obj_load(const char *path, obj_mesh *out, char *err, size_t err_len) {
    size_t len;
    char *buf = file_read_all(path, OBJ_MAX_FILE, &len, err, err_len);
    if (!buf) return -1;
    int rc = obj_parse(buf, len, path, out, err, err_len);
    free(buf);
    return rc;
}

void obj_mesh_free(obj_mesh *m) {
    free(m->positions);
    free(m->indices);
    free(m->normals);
    free(m->uvs);
    free(m->normal_indices);
    free(m->uv_indices);
    memset(m, 0, sizeof *m);
}
