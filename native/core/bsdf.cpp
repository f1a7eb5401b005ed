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

BSDF::Lobe& BSDF::add_lobe(Lobe::Type type, float sample_weight) {
  Lobe& l = lobes_[num_lobes_];
  sample_weight_[num_lobes_++] = sample_weight;
  l.type = type;
  return l;
}

// The Principled BSDF as Cycles 3.x builds it from its inputs (svm_closure.h,
// CLOSURE_BSDF_PRINCIPLED_ID), each lobe scaled by the closure weight w.
// The lobes' sample weights estimate their albedo for this wo.
void BSDF::add_principled(const Closure& c, bool back_face) {
  const float w = c.weight;
  const float metallic = std::clamp(c.metallic, 0.0f, 1.0f);
  const float transmission = std::clamp(c.transmission, 0.0f, 1.0f) * (1.0f - metallic);
  const vec3 base = glm::clamp(c.color, vec3(0.0f), vec3(1.0f));
  const float roughness = std::clamp(c.roughness, 0.0f, 1.0f);
  const float alpha = roughness * roughness;

  const vec3 diffuse_weight = base * ((1.0f - metallic) * (1.0f - std::clamp(c.transmission, 0.0f, 1.0f)) * w);

  const float specular = std::max(0.0f, c.specular);
  const float spec_weight = (specular > 1e-5f || metallic > 1e-5f) ? (1.0f - transmission) * w : 0.0f;
  const float spec_ior = 2.0f / (1.0f - std::sqrt(std::min(0.08f * specular, 0.999f))) - 1.0f;
  const vec3 cspec0 = vec3(specular * 0.08f) * (1.0f - metallic) + base * metallic;

  const float glass_weight = transmission * w;
  const float ior = std::max(c.ior, 1e-4f);
  const float eta = back_face ? 1.0f / ior : ior;
  const float fresnel_o = fresnel_dielectric(wo_.z, eta);

  const float cos_o = std::max(wo_.z, 0.0f);
  const vec3 spec_albedo = cspec0 + (vec3(1.0f) - cspec0) * schlick_weight(cos_o);
  const float w_diffuse = luminance(diffuse_weight);
  const float w_spec = spec_weight > 0.0f ? spec_weight * std::max(luminance(spec_albedo), 0.02f) : 0.0f;
  const float k_reflect = glass_weight * fresnel_o;
  const float k_refract = glass_weight * (1.0f - fresnel_o);
  const float w_refract = k_refract * std::max(luminance(base), 0.02f);

  if (w_diffuse > 0.0f) {
    Lobe& l = add_lobe(Lobe::kBurley, w_diffuse);
    l.tint = diffuse_weight;
    l.a = roughness;
  }
  if (w_spec > 0.0f) {
    Lobe& l = add_lobe(Lobe::kSpecular, w_spec);
    l.k = spec_weight;
    l.ggx = GGX{alpha};
    l.cspec0 = cspec0;
    l.spec_ior = spec_ior;
  }
  if (k_reflect > 0.0f) {  // untinted, as Cycles 3.x's principled glass reflection
    Lobe& l = add_lobe(Lobe::kReflection, k_reflect);
    l.k = k_reflect;
    l.tint = vec3(1.0f);
    l.ggx = GGX{alpha};
  }
  if (w_refract > 0.0f) {
    Lobe& l = add_lobe(Lobe::kRefraction, w_refract);
    l.k = k_refract;
    l.tint = base;
    l.ggx = GGX{alpha};
    l.eta = eta;
  }
}

void BSDF::add_closure(const Closure& c, bool back_face) {
  if (!(c.weight > 0.0f)) return;
  const vec3 color = glm::clamp(c.color, vec3(0.0f), vec3(1.0f));
  // Cycles drops closures of negligible weight (CLOSURE_WEIGHT_CUTOFF).
  if (c.kind != ClosureKind::Principled && !(max_component(color) * c.weight > 1e-5f)) return;
  const float roughness = std::clamp(c.roughness, 0.0f, 1.0f);
  switch (c.kind) {
    case ClosureKind::Principled:
      add_principled(c, back_face);
      break;
    case ClosureKind::Diffuse: {
      // Cycles' bsdf_oren_nayar_setup; roughness 0 is Lambert (bsdf_diffuse).
      Lobe& l = add_lobe(Lobe::kOrenNayar, c.weight * luminance(color));
      l.tint = color * c.weight;
      if (roughness > 0.0f) {
        const float div = 1.0f / (kPi + ((3.0f * kPi - 4.0f) / 6.0f) * roughness);
        l.a = div;
        l.b = roughness * div;
      } else {
        l.a = kInvPi;
        l.b = 0.0f;
      }
      break;
    }
    case ClosureKind::Glossy: {
      Lobe& l = add_lobe(Lobe::kReflection, c.weight * std::max(luminance(color), 0.02f));
      l.k = c.weight;
      l.tint = color;
      l.ggx = GGX{roughness * roughness};
      break;
    }
    case ClosureKind::Glass: {
      // Cycles 3.x splits the Glass BSDF by the Fresnel factor at wo, and its
      // colour tints both parts.
      const float ior = std::max(c.ior, 1e-5f);
      const float eta = back_face ? 1.0f / ior : ior;
      const float fresnel_o = fresnel_dielectric(wo_.z, eta);
      const float lum = std::max(luminance(color), 0.02f);
      if (fresnel_o > 0.0f) {
        Lobe& l = add_lobe(Lobe::kReflection, c.weight * fresnel_o * lum);
        l.k = c.weight * fresnel_o;
        l.tint = color;
        l.ggx = GGX{roughness * roughness};
      }
      if (fresnel_o < 1.0f) {
        Lobe& l = add_lobe(Lobe::kRefraction, c.weight * (1.0f - fresnel_o) * lum);
        l.k = c.weight * (1.0f - fresnel_o);
        l.tint = color;
        l.ggx = GGX{roughness * roughness};
        l.eta = eta;
      }
      break;
    }
    case ClosureKind::Transparent: {
      Lobe& l = add_lobe(Lobe::kTransparent, c.weight * luminance(color));
      l.k = c.weight;
      l.tint = color;
      break;
    }
  }
}

BSDF::BSDF(const vec3& ns, const vec3& ng, const Material& m, bool back_face, const vec3& wo_world)
    : frame_(ensure_valid_reflection(ng, wo_world, ns)), ng_(ng), ns_(ns), wo_world_(wo_world) {
  wo_ = frame_.to_local(wo_world);
  Closure c0 = m.closure(0);
  // Principled Alpha (Cycles: mix of a white Transparent BSDF by 1 - alpha).
  if (m.alpha < 1.0f && c0.weight > 0.0f) {
    const float a = std::max(m.alpha, 0.0f);
    Lobe& l = add_lobe(Lobe::kTransparent, c0.weight * (1.0f - a));
    l.k = c0.weight * (1.0f - a);
    l.tint = vec3(1.0f);
    c0.weight *= a;
  }
  add_closure(c0, back_face);
  for (uint32_t i = 0; i < m.num_more && i + 1 < uint32_t(kMaxClosures); ++i) add_closure(m.more[i], back_face);

  float total = 0.0f;
  for (int i = 0; i < num_lobes_; ++i) total += sample_weight_[i];
  if (total > 0.0f) {
    for (int i = 0; i < num_lobes_; ++i) {
      Lobe& l = lobes_[i];
      l.prob = sample_weight_[i] / total;
      l.is_delta = l.delta();
      l.is_transmit = l.transmits();
      if (l.prob > 0.0f && !l.is_delta) has_smooth_ = true;
    }
  } else {
    num_lobes_ = 0;  // nothing scatters
  }
}

vec3 BSDF::eval_lobe(const Lobe& l, const vec3& wi) const {
  const vec3& wo = wo_;
  switch (l.type) {
    case Lobe::kBurley: {
      // Cycles 3.x principled diffuse (Burley 2012 with its retro-reflection term).
      if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      float fl = schlick_weight(wi.z), fv = schlick_weight(wo.z);
      float f = (1.0f - 0.5f * fv) * (1.0f - 0.5f * fl);
      float rr = l.a * (glm::dot(wi, wo) + 1.0f);
      f += rr * (fl + fv + fl * fv * (rr - 1.0f));
      return l.tint * (f * kInvPi);
    }
    case Lobe::kOrenNayar: {
      // Cycles' bsdf_oren_nayar (the "qualitative" model, Oren and Nayar 1994):
      // f = A + B max(0, cos(phi_i - phi_o)) sin(a) tan(b), written with dot products.
      if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      float t = glm::dot(wi, wo) - wi.z * wo.z;
      if (t > 0.0f) t /= std::max(wi.z, wo.z) + std::numeric_limits<float>::min();
      return l.tint * (l.a + l.b * t);
    }
    case Lobe::kSpecular: {
      if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      vec3 wm = wi + wo;
      if (glm::dot(wm, wm) == 0.0f) return vec3(0.0f);
      wm = glm::normalize(wm);
      vec3 F = interpolate_fresnel(glm::dot(wi, wm), l.spec_ior, l.cspec0);
      return l.k * F * (l.ggx.D(wm) * l.ggx.G(wo, wi) / (4.0f * wi.z * wo.z));
    }
    case Lobe::kReflection: {
      if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      vec3 wm = glm::normalize(wi + wo);
      return l.tint * (l.k * l.ggx.D(wm) * l.ggx.G(wo, wi) / (4.0f * wi.z * wo.z));
    }
    case Lobe::kRefraction: {
      if (wi.z >= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      // Generalised half vector (Walter et al. 2007), facing wo's side.
      vec3 wm = glm::normalize(wi * l.eta + wo);
      if (wm.z < 0.0f) wm = -wm;
      float dot_i = glm::dot(wi, wm), dot_o = glm::dot(wo, wm);
      if (dot_i >= 0.0f || dot_o <= 0.0f) return vec3(0.0f);
      float denom = sqr(dot_i + dot_o / l.eta);
      float ft = l.ggx.D(wm) * l.ggx.G(wo, wi) * std::abs(dot_i * dot_o / (wi.z * wo.z * denom));
      // No 1/eta^2 radiance scaling, as in Cycles.
      return l.tint * (l.k * ft);
    }
    case Lobe::kTransparent:
      break;
  }
  return vec3(0.0f);
}

float BSDF::pdf_lobe(const Lobe& l, const vec3& wi) const {
  const vec3& wo = wo_;
  switch (l.type) {
    case Lobe::kBurley:
    case Lobe::kOrenNayar:
      return wi.z > 0.0f ? wi.z * kInvPi : 0.0f;
    case Lobe::kSpecular:
    case Lobe::kReflection: {
      if (wi.z <= 0.0f || wo.z <= 0.0f) return 0.0f;
      vec3 wm = glm::normalize(wi + wo);
      return l.ggx.pdf_visible(wo, wm) / (4.0f * std::abs(glm::dot(wo, wm)));
    }
    case Lobe::kRefraction: {
      if (wi.z >= 0.0f || wo.z <= 0.0f) return 0.0f;
      vec3 wm = glm::normalize(wi * l.eta + wo);
      if (wm.z < 0.0f) wm = -wm;
      float dot_i = glm::dot(wi, wm), dot_o = glm::dot(wo, wm);
      if (dot_i >= 0.0f || dot_o <= 0.0f) return 0.0f;
      float dwm_dwi = std::abs(dot_i) / sqr(dot_i + dot_o / l.eta);
      return l.ggx.pdf_visible(wo, wm) * dwm_dwi;
    }
    case Lobe::kTransparent:
      break;
  }
  return 0.0f;
}

vec3 BSDF::f(const vec3& wi_world) const {
  const vec3 wi = frame_.to_local(wi_world);
  const bool reflect_side = same_side(wi_world);
  vec3 sum(0.0f);
  for (int i = 0; i < num_lobes_; ++i) {
    const Lobe& l = lobes_[i];
    // The geometric side decides reflection vs transmission (no light leaks).
    if (l.prob == 0.0f || l.is_delta || l.is_transmit == reflect_side) continue;
    sum += eval_lobe(l, wi);
  }
  return sum;
}

float BSDF::pdf(const vec3& wi_world) const {
  const vec3 wi = frame_.to_local(wi_world);
  const bool reflect_side = same_side(wi_world);
  float p = 0.0f;
  for (int i = 0; i < num_lobes_; ++i) {
    const Lobe& l = lobes_[i];
    if (l.prob == 0.0f || l.is_delta || l.is_transmit == reflect_side) continue;
    p += l.prob * pdf_lobe(l, wi);
  }
  return p;
}

bool BSDF::sample_f(float u_lobe, vec2 u, BSDFSample& s) const {
  if (wo_.z <= 0.0f) return false;
  int chosen = -1;
  float acc = 0.0f;
  for (int i = 0; i < num_lobes_; ++i) {
    if (lobes_[i].prob == 0.0f) continue;
    acc += lobes_[i].prob;
    chosen = i;
    if (u_lobe < acc) break;
  }
  if (chosen < 0) return false;
  const Lobe& l = lobes_[chosen];
  switch (l.type) {
    case Lobe::kBurley:
    case Lobe::kOrenNayar: s.kind = BSDFSample::kDiffuse; break;
    case Lobe::kSpecular:
    case Lobe::kReflection: s.kind = BSDFSample::kGlossy; break;
    case Lobe::kRefraction: s.kind = BSDFSample::kTransmission; break;
    case Lobe::kTransparent: s.kind = BSDFSample::kTransparent; break;
  }
  vec3 wi;
  if (l.type == Lobe::kTransparent) {
    // Straight on, exactly; weighted against the shading normal the caller
    // multiplies by, so that f |cos| / pdf is the closure weight / prob.
    s.wi = -wo_world_;
    const float cos_i = std::abs(glm::dot(s.wi, ns_));
    if (same_side(s.wi) || !(cos_i > 0.0f)) return false;
    s.f = l.tint * l.k / cos_i;
    s.pdf = l.prob;
    s.delta = true;
    return max_component(s.f) > 0.0f;
  }
  if (l.delta()) {
    if (l.type == Lobe::kRefraction) {
      if (!refract(wo_, vec3(0, 0, 1), l.eta, &wi)) return false;
    } else {
      wi = vec3(-wo_.x, -wo_.y, wo_.z);
    }
    s.wi = frame_.to_world(wi);
    if (l.transmits() == same_side(s.wi)) return false;
    const float cos_i = std::abs(wi.z);
    vec3 weight = l.type == Lobe::kSpecular ? l.k * interpolate_fresnel(wo_.z, l.spec_ior, l.cspec0) : l.tint * l.k;
    s.f = weight / cos_i;
    s.pdf = l.prob;
    s.delta = true;
    return max_component(s.f) > 0.0f;
  }
  switch (l.type) {
    case Lobe::kBurley:
    case Lobe::kOrenNayar:
      wi = sample_cosine_hemisphere(u);
      break;
    case Lobe::kSpecular:
    case Lobe::kReflection:
      wi = reflect(wo_, l.ggx.sample_visible(wo_, u));
      if (wi.z <= 0.0f) return false;
      break;
    case Lobe::kRefraction: {
      vec3 wm = l.ggx.sample_visible(wo_, u);
      if (!refract(wo_, wm, l.eta, &wi) || wi.z >= 0.0f) return false;
      break;
    }
    case Lobe::kTransparent:
      return false;
  }
  s.wi = frame_.to_world(wi);
  s.delta = false;
  s.f = f(s.wi);
  s.pdf = pdf(s.wi);
  return s.pdf > 0.0f && max_component(s.f) > 0.0f;
}

}  // namespace tessera
