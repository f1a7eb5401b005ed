// Blender's Principled BSDF as Cycles 3.x evaluates it (principled v1): a
// sum of lobes, each with its Cycles weight:
//   diffuse   (1 - metallic)(1 - transmission) base  Burley diffuse with retro-reflection
//   specular  1 - (1 - metallic) transmission         GGX, Fresnel interpolated from cspec0
//   glass     (1 - metallic) transmission             GGX reflection F(wo) + refraction base (1 - F(wo))
// One lobe is sampled per bounce, chosen by its estimated albedo, and the
// lobes are combined by one-sample MIS (pbrt-v4, 9.x; Cycles principled.h).
// Local directions are in the shading frame, whose z points to wo's side.
#pragma once
#include "material.h"
#include "microfacet.h"
#include "sampling.h"

namespace tessera {

struct BSDFSample {
  vec3 wi;     // world space
  vec3 f;      // BSDF value (for a delta lobe: its weight / |cos wi|)
  float pdf;   // solid-angle density (for a delta lobe: the lobe's probability)
  bool delta;  // specular: no MIS with light sampling
  enum Kind : uint8_t { kDiffuse, kGlossy, kTransmission } kind = kDiffuse;  // of the sampled lobe (bounce limits)
};

class BSDF {
 public:
  // ns, ng: shading and geometric normals, both on wo's side; back_face: wo
  // is on the back of the surface (glass is then left, not entered).
  BSDF(const vec3& ns, const vec3& ng, const Material& m, bool back_face, const vec3& wo_world);

  vec3 f(const vec3& wi_world) const;
  float pdf(const vec3& wi_world) const;
  bool sample_f(float u_lobe, vec2 u, BSDFSample& s) const;
  // False when every lobe is a delta: light sampling cannot contribute.
  bool has_smooth_lobes() const { return has_smooth_; }

 private:
  enum Lobe { kDiffuse, kSpecular, kGlassReflect, kGlassRefract, kNumLobes };
  vec3 eval_lobe(int lobe, const vec3& wi) const;
  float pdf_lobe(int lobe, const vec3& wi) const;
  bool is_delta(int lobe) const { return lobe == kSpecular ? spec_ggx_.alpha <= kSmoothAlpha : lobe >= kGlassReflect && glass_ggx_.alpha <= kSmoothAlpha; }
  bool same_side(const vec3& wi_world) const { return glm::dot(wi_world, ng_) > 0.0f; }

  Frame frame_;
  vec3 ng_;
  vec3 wo_;             // local
  vec3 wo_world_;
  vec3 diffuse_weight_;
  float roughness_;
  vec3 cspec0_;
  float spec_weight_;
  float spec_ior_;
  GGX spec_ggx_;
  float glass_weight_;
  vec3 glass_color_;
  float eta_;
  float fresnel_o_;
  GGX glass_ggx_;
  float prob_[kNumLobes] = {};
  bool has_smooth_ = false;
};

}  // namespace tessera
