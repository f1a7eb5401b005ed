#include "bsdf.h"

namespace tessera {

namespace {

float schlick_weight(float c) {
  float m = std::clamp(1.0f - c, 0.0f, 1.0f);
  float m2 = m * m;
  return m2 * m2 * m;
}

// Cycles' interpolate_fresnel_color: the dielectric Fresnel at the
// microfacet, renormalised so that it starts at cspec0 and reaches 1.
vec3 interpolate_fresnel(float cos_ih, float ior, const vec3& cspec0) {
  float f0 = fresnel_dielectric(1.0f, ior);
  float fh = (fresnel_dielectric(cos_ih, ior) - f0) / (1.0f - f0);
  return cspec0 * (1.0f - fh) + vec3(fh);
}

// Bends the shading normal n (towards the geometric normal ng, within their
// plane) just enough that the mirror reflection of wo stays above the
// geometric surface, as Cycles does for every closure (ensure_valid_reflection).
// Without it, interpolated normals on coarse smooth meshes reflect and refract
// into the surface and those paths are lost: glass and metal turn dark.
vec3 ensure_valid_reflection(const vec3& ng, const vec3& wo, const vec3& n) {
  const vec3 r = 2.0f * glm::dot(n, wo) * n - wo;
  // The reflection may be as shallow as the incoming direction, but not below.
  const float threshold = std::min(0.9f * glm::dot(ng, wo), 0.01f);
  if (glm::dot(ng, r) >= threshold) return n;
  // Frame with ng as z and n in the x-z plane; solve for the new normal's z^2.
  const float n_dot_ng = glm::dot(n, ng);
  const vec3 x_axis = glm::normalize(n - n_dot_ng * ng);
  const float ix = glm::dot(wo, x_axis), iz = glm::dot(wo, ng);
  const float ix2 = ix * ix, iz2 = iz * iz;
  const float a = ix2 + iz2;
  const float b = safe_sqrt(ix2 * (a - threshold * threshold));
  const float c = iz * threshold + a;
  const float fac = 0.5f / a;
  const float z2_1 = fac * (b + c), z2_2 = fac * (c - b);
  bool valid1 = z2_1 > 1e-5f && z2_1 <= 1.0f + 1e-5f;
  bool valid2 = z2_2 > 1e-5f && z2_2 <= 1.0f + 1e-5f;
  vec2 nn;
  if (valid1 && valid2) {
    // Both solve the equation: keep the one whose reflection is valid and shallowest.
    const vec2 n1(safe_sqrt(1.0f - z2_1), safe_sqrt(z2_1)), n2(safe_sqrt(1.0f - z2_2), safe_sqrt(z2_2));
    const float r1 = 2.0f * (n1.x * ix + n1.y * iz) * n1.y - iz;
    const float r2 = 2.0f * (n2.x * ix + n2.y * iz) * n2.y - iz;
    valid1 = r1 >= 1e-5f;
    valid2 = r2 >= 1e-5f;
    nn = (valid1 && valid2) ? (r1 < r2 ? n1 : n2) : (r1 > r2 ? n1 : n2);
  } else if (valid1 || valid2) {
    const float z2 = valid1 ? z2_1 : z2_2;
    nn = vec2(safe_sqrt(1.0f - z2), safe_sqrt(z2));
  } else {
    return ng;
  }
  const vec3 out = nn.x * x_axis + nn.y * ng;
  return is_finite(out) ? out : ng;
}

}  // namespace

BSDF::BSDF(const vec3& ns, const vec3& ng, const Material& m, bool back_face, const vec3& wo_world)
    : frame_(ensure_valid_reflection(ng, wo_world, ns)), ng_(ng), wo_world_(wo_world) {
  wo_ = frame_.to_local(wo_world);
  const float metallic = std::clamp(m.metallic, 0.0f, 1.0f);
  const float transmission = std::clamp(m.transmission, 0.0f, 1.0f) * (1.0f - metallic);
  const vec3 base = glm::clamp(m.base_color, vec3(0.0f), vec3(1.0f));
  roughness_ = std::clamp(m.roughness, 0.0f, 1.0f);
  const float alpha = roughness_ * roughness_;

  diffuse_weight_ = base * ((1.0f - metallic) * (1.0f - std::clamp(m.transmission, 0.0f, 1.0f)));

  const float specular = std::max(0.0f, m.specular);
  spec_weight_ = (specular > 1e-5f || metallic > 1e-5f) ? 1.0f - transmission : 0.0f;
  spec_ior_ = 2.0f / (1.0f - std::sqrt(std::min(0.08f * specular, 0.999f))) - 1.0f;
  cspec0_ = vec3(specular * 0.08f) * (1.0f - metallic) + base * metallic;
  spec_ggx_ = GGX{alpha};

  glass_weight_ = transmission;
  glass_color_ = base;
  const float ior = std::max(m.ior, 1e-4f);
  eta_ = back_face ? 1.0f / ior : ior;
  glass_ggx_ = GGX{alpha};
  fresnel_o_ = fresnel_dielectric(wo_.z, eta_);

  // Lobe selection by estimated albedo for this wo.
  const float cos_o = std::max(wo_.z, 0.0f);
  const vec3 spec_albedo = cspec0_ + (vec3(1.0f) - cspec0_) * schlick_weight(cos_o);
  float w[kNumLobes];
  w[kDiffuse] = luminance(diffuse_weight_);
  w[kSpecular] = spec_weight_ > 0.0f ? spec_weight_ * std::max(luminance(spec_albedo), 0.02f) : 0.0f;
  w[kGlassReflect] = glass_weight_ * fresnel_o_;
  w[kGlassRefract] = glass_weight_ * (1.0f - fresnel_o_) * std::max(luminance(glass_color_), 0.02f);
  float total = 0.0f;
  for (float x : w) total += x;
  if (total > 0.0f) {
    for (int i = 0; i < kNumLobes; ++i) {
      prob_[i] = w[i] / total;
      if (prob_[i] > 0.0f && !is_delta(i)) has_smooth_ = true;
    }
  }
}

vec3 BSDF::eval_lobe(int lobe, const vec3& wi) const {
  const vec3& wo = wo_;
  switch (lobe) {
    case kDiffuse: {
      // Cycles 3.x principled diffuse (Burley 2012 with its retro-reflection term).
      if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      float fl = schlick_weight(wi.z), fv = schlick_weight(wo.z);
      float f = (1.0f - 0.5f * fv) * (1.0f - 0.5f * fl);
      float rr = roughness_ * (glm::dot(wi, wo) + 1.0f);
      f += rr * (fl + fv + fl * fv * (rr - 1.0f));
      return diffuse_weight_ * (f * kInvPi);
    }
    case kSpecular: {
      if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      vec3 wm = wi + wo;
      if (glm::dot(wm, wm) == 0.0f) return vec3(0.0f);
      wm = glm::normalize(wm);
      vec3 F = interpolate_fresnel(glm::dot(wi, wm), spec_ior_, cspec0_);
      return spec_weight_ * F * (spec_ggx_.D(wm) * spec_ggx_.G(wo, wi) / (4.0f * wi.z * wo.z));
    }
    case kGlassReflect: {
      if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      vec3 wm = glm::normalize(wi + wo);
      return vec3(glass_weight_ * fresnel_o_ * glass_ggx_.D(wm) * glass_ggx_.G(wo, wi) / (4.0f * wi.z * wo.z));
    }
    case kGlassRefract: {
      if (wi.z >= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      // Generalised half vector (Walter et al. 2007), facing wo's side.
      vec3 wm = glm::normalize(wi * eta_ + wo);
      if (wm.z < 0.0f) wm = -wm;
      float dot_i = glm::dot(wi, wm), dot_o = glm::dot(wo, wm);
      if (dot_i >= 0.0f || dot_o <= 0.0f) return vec3(0.0f);
      float denom = sqr(dot_i + dot_o / eta_);
      float ft = glass_ggx_.D(wm) * glass_ggx_.G(wo, wi) * std::abs(dot_i * dot_o / (wi.z * wo.z * denom));
      // No 1/eta^2 radiance scaling, as in Cycles.
      return glass_color_ * (glass_weight_ * (1.0f - fresnel_o_) * ft);
    }
  }
  return vec3(0.0f);
}

float BSDF::pdf_lobe(int lobe, const vec3& wi) const {
  const vec3& wo = wo_;
  switch (lobe) {
    case kDiffuse:
      return wi.z > 0.0f ? wi.z * kInvPi : 0.0f;
    case kSpecular:
    case kGlassReflect: {
      if (wi.z <= 0.0f || wo.z <= 0.0f) return 0.0f;
      const GGX& g = lobe == kSpecular ? spec_ggx_ : glass_ggx_;
      vec3 wm = glm::normalize(wi + wo);
      return g.pdf_visible(wo, wm) / (4.0f * std::abs(glm::dot(wo, wm)));
    }
    case kGlassRefract: {
      if (wi.z >= 0.0f || wo.z <= 0.0f) return 0.0f;
      vec3 wm = glm::normalize(wi * eta_ + wo);
      if (wm.z < 0.0f) wm = -wm;
      float dot_i = glm::dot(wi, wm), dot_o = glm::dot(wo, wm);
      if (dot_i >= 0.0f || dot_o <= 0.0f) return 0.0f;
      float dwm_dwi = std::abs(dot_i) / sqr(dot_i + dot_o / eta_);
      return glass_ggx_.pdf_visible(wo, wm) * dwm_dwi;
    }
  }
  return 0.0f;
}

vec3 BSDF::f(const vec3& wi_world) const {
  const vec3 wi = frame_.to_local(wi_world);
  const bool reflect_side = same_side(wi_world);
  vec3 sum(0.0f);
  for (int l = 0; l < kNumLobes; ++l) {
    // The geometric side decides reflection vs transmission (no light leaks).
    if (prob_[l] == 0.0f || is_delta(l) || (l == kGlassRefract) == reflect_side) continue;
    sum += eval_lobe(l, wi);
  }
  return sum;
}

float BSDF::pdf(const vec3& wi_world) const {
  const vec3 wi = frame_.to_local(wi_world);
  const bool reflect_side = same_side(wi_world);
  float p = 0.0f;
  for (int l = 0; l < kNumLobes; ++l) {
    if (prob_[l] == 0.0f || is_delta(l) || (l == kGlassRefract) == reflect_side) continue;
    p += prob_[l] * pdf_lobe(l, wi);
  }
  return p;
}

bool BSDF::sample_f(float u_lobe, vec2 u, BSDFSample& s) const {
  if (wo_.z <= 0.0f) return false;
  int lobe = -1;
  float acc = 0.0f;
  for (int l = 0; l < kNumLobes; ++l) {
    if (prob_[l] == 0.0f) continue;
    acc += prob_[l];
    lobe = l;
    if (u_lobe < acc) break;
  }
  if (lobe < 0) return false;
  s.kind = lobe == kDiffuse ? BSDFSample::kDiffuse : lobe == kGlassRefract ? BSDFSample::kTransmission : BSDFSample::kGlossy;
  vec3 wi;
  if (is_delta(lobe)) {
    if (lobe == kGlassRefract) {
      if (!refract(wo_, vec3(0, 0, 1), eta_, &wi)) return false;
    } else {
      wi = vec3(-wo_.x, -wo_.y, wo_.z);
    }
    s.wi = frame_.to_world(wi);
    if ((lobe == kGlassRefract) == same_side(s.wi)) return false;
    const float cos_i = std::abs(wi.z);
    vec3 weight = lobe == kSpecular ? spec_weight_ * interpolate_fresnel(wo_.z, spec_ior_, cspec0_)
                : lobe == kGlassReflect ? vec3(glass_weight_ * fresnel_o_)
                : glass_color_ * (glass_weight_ * (1.0f - fresnel_o_));
    s.f = weight / cos_i;
    s.pdf = prob_[lobe];
    s.delta = true;
    return max_component(s.f) > 0.0f;
  }
  switch (lobe) {
    case kDiffuse:
      wi = sample_cosine_hemisphere(u);
      break;
    case kSpecular:
    case kGlassReflect: {
      const GGX& g = lobe == kSpecular ? spec_ggx_ : glass_ggx_;
      wi = reflect(wo_, g.sample_visible(wo_, u));
      if (wi.z <= 0.0f) return false;
      break;
    }
    case kGlassRefract: {
      vec3 wm = glass_ggx_.sample_visible(wo_, u);
      if (!refract(wo_, wm, eta_, &wi) || wi.z >= 0.0f) return false;
      break;
    }
  }
  s.wi = frame_.to_world(wi);
  s.delta = false;
  s.f = f(s.wi);
  s.pdf = pdf(s.wi);
  return s.pdf > 0.0f && max_component(s.f) > 0.0f;
}

}  // namespace tessera
