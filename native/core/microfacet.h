// Trowbridge-Reitz (GGX) microfacet distribution in the local shading frame
// (z up): NDF, Smith masking and sampling of visible normals (Heitz 2018,
// "Sampling the GGX Distribution of Visible Normals", JCGT 7(4)).
#pragma once
#include "math.h"

namespace tessera {

// Surfaces this smooth are treated as perfect mirrors / refractors (as Cycles
// treats alpha <= 1e-4 as a singular closure).
constexpr float kSmoothAlpha = 1e-4f;

struct GGX {
  float alpha;

  float D(const vec3& wm) const {
    float c2 = wm.z * wm.z;
    float a2 = alpha * alpha;
    float d = c2 * (a2 - 1.0f) + 1.0f;
    return a2 / (kPi * d * d);
  }
  float lambda(const vec3& w) const {
    float c2 = w.z * w.z;
    if (c2 <= 0.0f) return kInf;
    float tan2 = std::max(0.0f, 1.0f - c2) / c2;
    return 0.5f * (std::sqrt(1.0f + alpha * alpha * tan2) - 1.0f);
  }
  float G1(const vec3& w) const { return 1.0f / (1.0f + lambda(w)); }
  // Cycles 3.x uses the separable (uncorrelated) Smith form G1(wo) G1(wi).
  float G(const vec3& wo, const vec3& wi) const { return G1(wo) * G1(wi); }
  // Cycles 4.x the height-correlated form (Heitz 2014, "Understanding the
  // Masking-Shadowing Function", eq. 99): 1 / (1 + Lambda(wo) + Lambda(wi)).
  float G_correlated(const vec3& wo, const vec3& wi) const { return 1.0f / (1.0f + lambda(wo) + lambda(wi)); }

  // Density of visible normal wm seen from w (w.z > 0).
  float pdf_visible(const vec3& w, const vec3& wm) const {
    return G1(w) / std::abs(w.z) * D(wm) * std::abs(glm::dot(w, wm));
  }

  vec3 sample_visible(const vec3& w, vec2 u) const {
    vec3 wh = glm::normalize(vec3(alpha * w.x, alpha * w.y, w.z));
    if (wh.z < 0.0f) wh = -wh;
    vec3 t1 = wh.z < 0.99999f ? glm::normalize(glm::cross(vec3(0, 0, 1), wh)) : vec3(1, 0, 0);
    vec3 t2 = glm::cross(wh, t1);
    vec2 p = std::sqrt(u.x) * cos_sin_2pi(u.y);
    float h = std::sqrt(std::max(0.0f, 1.0f - p.x * p.x));
    p.y = h + (p.y - h) * (1.0f + wh.z) * 0.5f;
    float pz = safe_sqrt(1.0f - p.x * p.x - p.y * p.y);
    vec3 nh = p.x * t1 + p.y * t2 + pz * wh;
    return glm::normalize(vec3(alpha * nh.x, alpha * nh.y, std::max(1e-6f, nh.z)));
  }
};

// Unpolarised Fresnel reflectance of a dielectric interface, eta = n_t / n_i
// (Cycles' fresnel_dielectric_cos); 1 under total internal reflection.
inline float fresnel_dielectric(float cos_i, float eta) {
  float c = std::abs(cos_i);
  float g = eta * eta - 1.0f + c * c;
  if (g <= 0.0f) return 1.0f;
  g = std::sqrt(g);
  float a = (g - c) / (g + c);
  float b = (c * (g + c) - 1.0f) / (c * (g - c) + 1.0f);
  return 0.5f * a * a * (1.0f + b * b);
}

// Refracts w (pointing away from the surface, on the side of n) through an
// interface of relative IOR eta = n_t / n_i; false on total internal reflection.
inline bool refract(const vec3& w, const vec3& n, float eta, vec3* wt) {
  float cos_i = glm::dot(n, w);
  float sin2_t = std::max(0.0f, 1.0f - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1.0f) return false;
  float cos_t = std::sqrt(1.0f - sin2_t);
  *wt = -w / eta + (cos_i / eta - cos_t) * n;
  return true;
}

inline vec3 reflect(const vec3& w, const vec3& n) { return -w + 2.0f * glm::dot(w, n) * n; }

}  // namespace tessera
