// Surface scattering at a shading point, in the local frame of the shading
// normal (z up). For now the diffuse lobe of the Principled BSDF: Lambertian
// reflection of the base colour (pbrt-v4, 9.2).
#pragma once
#include "material.h"
#include "sampling.h"

namespace tessera {

struct BSDFSample {
  vec3 wi;    // world space
  vec3 f;     // BSDF value
  float pdf;  // solid-angle density
};

struct BSDF {
  Frame frame;
  vec3 ng;  // geometric normal, on the side of the incoming ray
  vec3 albedo;

  BSDF(const vec3& shading_normal, const vec3& geometric_normal, const Material& m)
      : frame(shading_normal), ng(geometric_normal), albedo(m.base_color) {}

  // Light is reflected only when wo and wi are on the same side of the
  // geometric surface; this avoids light leaking through interpolated normals.
  vec3 f(const vec3& wo, const vec3& wi) const {
    if (glm::dot(wi, ng) * glm::dot(wo, ng) <= 0.0f) return vec3(0.0f);
    float cos_i = glm::dot(wi, frame.n);
    return cos_i > 0.0f ? albedo * kInvPi : vec3(0.0f);
  }
  float pdf(const vec3& wo, const vec3& wi) const {
    if (glm::dot(wi, ng) * glm::dot(wo, ng) <= 0.0f) return 0.0f;
    return std::max(0.0f, glm::dot(wi, frame.n)) * kInvPi;
  }
  bool sample_f(const vec3& wo, vec2 u, BSDFSample& s) const {
    vec3 local = sample_cosine_hemisphere(u);
    if (local.z <= 0.0f) return false;
    s.wi = frame.to_world(local);
    s.pdf = local.z * kInvPi;
    s.f = f(wo, s.wi);
    return s.pdf > 0.0f && max_component(s.f) > 0.0f;
  }
};

}  // namespace tessera
