/* bsdf_pbr.h - the glTF 2.0 metallic-roughness BRDF (glTF spec, appendix B).
 *
 * With base colour b, metallic m, roughness r, alpha = r^2 (at least
 * PBR_ALPHA_MIN), h the half vector and F0 = mix(0.04, b, m):
 *   F    = F0 + (1 - F0) (1 - |wo.h|)^5                    (Schlick)
 *   D    = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)    (GGX / Trowbridge-Reitz)
 *   G2   = 1 / (1 + L(wo) + L(wi)),  L(w) = (sqrt(1 + alpha^2 tan^2 w) - 1) / 2
 *                                                          (height-correlated Smith)
 *   f    = F D G2 / (4 wo.z wi.z)  +  (1 - F) (1 - m) b / pi
 * The specular term is the glTF spec's; the diffuse term is its Lambert
 * layer weighted by (1 - F) per channel, as in the spec's sample
 * implementation (symmetric in wo and wi, since |wo.h| = |wi.h|).
 *
 * Sampling is a mixture chosen by u3: with probability p_spec (a function of
 * the material and wo only) the GGX distribution of visible normals (Heitz
 * 2018, "Sampling the GGX Distribution of Visible Normals") and a mirror
 * reflection about the sampled normal, whose density is
 *   pdf_spec(wi) = G1(wo) D(h) / (4 wo.z),
 * otherwise the cosine hemisphere, pdf_diff(wi) = wi.z / pi; the stated pdf
 * is the mixture p_spec pdf_spec + (1 - p_spec) pdf_diff.
 *
 * Conventions as bsdf.h: local frame, z the (shading) normal, wo.z > 0. */
#ifndef TESSERA_BSDF_PBR_H
#define TESSERA_BSDF_PBR_H

#include "bsdf.h"

#define PBR_ALPHA_MIN 1e-3f

vec3 bsdf_pbr_eval(const material *m, vec3 wo, vec3 wi);
float bsdf_pbr_pdf(const material *m, vec3 wo, vec3 wi);
/* Same contract as bsdf_sample_wi: (u1, u2) the direction, u3 the lobe. */
int bsdf_pbr_sample(const material *m, vec3 wo, float u1, float u2, float u3, bsdf_sample *out);

/* The GGX pieces, exposed for the tests. */
float pbr_ggx_d(float alpha, float cos_h);
float pbr_smith_lambda(float alpha, float cos_w);

#endif
