/* bsdf.h - scattering for each material kind: evaluate, sample, pdf.
 *
 * All directions are unit vectors in the local shading frame, z along the
 * normal. For opaque materials the caller orients the frame so that
 * wo.z > 0 (surfaces reflect on both sides); for glass z is the outward
 * geometric normal and the sign of wo.z says whether the path is outside.
 * Radiance transport (paths start at the camera): refraction scales by
 * (eta_i / eta_t)^2. */
#ifndef TESSERA_BSDF_H
#define TESSERA_BSDF_H

#include "scene.h"
#include "vec.h"

typedef struct {
    vec3 wi;      /* sampled incident direction */
    vec3 weight;  /* f * |cos(wi)| / pdf: what the path throughput is multiplied by */
    float pdf;    /* solid-angle density of wi; 0 for delta (specular) events */
    int is_delta; /* 1 for mirror and glass: no light sampling, no MIS */
    float eta;    /* eta_t / eta_i of a refraction (weight holds 1 / eta^2); 1 otherwise */
} bsdf_sample;

/* 1 if the material has a non-delta component that light sampling can hit. */
static inline int bsdf_is_smooth(const material *m) {
    return m->kind == MATERIAL_DIFFUSE || m->kind == MATERIAL_GLOSSY || m->kind == MATERIAL_PBR;
}

/* f(wo, wi); zero for delta materials and for wi below the surface. */
vec3 bsdf_eval(const material *m, vec3 wo, vec3 wi);

/* The density bsdf_sample draws wi with, per unit solid angle; zero for delta
 * materials. */
float bsdf_pdf(const material *m, vec3 wo, vec3 wi);

/* bsdf_eval, and bsdf_pdf into *pdf, in one call: what light sampling
 * needs, for less than the two calls. */
vec3 bsdf_eval_pdf(const material *m, vec3 wo, vec3 wi, float *pdf);

/* Draw wi given wo from three uniform numbers. Returns 1 and fills *out, or
 * 0 when the sample is lost (absorbed, or a lobe sample below the surface):
 * the path ends. Can't fail otherwise. */
int bsdf_sample_wi(const material *m, vec3 wo, float u1, float u2, float u3, bsdf_sample *out);

/* Fresnel reflectance of a smooth dielectric for a wave arriving with cosine
 * cos_i (> 0 outside, < 0 inside) at an interface with relative IOR eta
 * (inside / outside). Returns 1 for total internal reflection. */
float bsdf_fresnel_dielectric(float cos_i, float eta);

#endif
