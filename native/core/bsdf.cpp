#include "bsdf.h"

#include "ggx_energy.h"

namespace tessera {

namespace {

float schlick_weight(float c) {
  float m = std::clamp(1.0f - c, 0.0f, 1.0f);
  float m2 = m * m;
  return m2 * m2 * m;
}

// Cycles' interpolate_fresnel_color: the dielectric Fresnel at the
// microfacet, renormalised so that it starts at cspec0 and reaches 1;
// f0 = fresnel_dielectric(1, ior).
vec3 interpolate_fresnel(float cos_ih, float ior, float f0, const vec3& cspec0) {
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

// Cycles' CLOSURE_WEIGHT_CUTOFF: closures lighter than this are left out.
constexpr float kClosureCutoff = 1e-5f;

vec3 saturate(const vec3& v) { return glm::clamp(v, vec3(0.0f), vec3(1.0f)); }

// Average single-scattering Fresnel 2 int_0^1 F(mu, eta) mu dmu, Kulla and
// Conty's fit (Cycles' fresnel_dielectric_Fss).
float fresnel_dielectric_Fss(float eta) {
  if (eta < 1.0f) return 0.997118f + eta * (0.1014f - eta * (0.965241f + eta * 0.130607f));
  return (eta - 1.0f) / (4.08567f + 1.00071f * eta);
}

// F82-tint's b: the Schlick value at cos = 1/7 (about 82 degrees) scaled by
// the tint (Cycles' fresnel_f82tint_B); and the model's average Fss.
vec3 fresnel_f82tint_B(const vec3& F0, const vec3& tint) {
  const float f = 6.0f / 7.0f, f5 = f * f * f * f * f;
  const vec3 F_schlick = glm::mix(F0, vec3(1.0f), f5);
  return F_schlick * (7.0f / (f5 * f)) * (vec3(1.0f) - tint);
}
vec3 fresnel_f82_Fss(const vec3& F0, const vec3& B) { return glm::mix(F0, vec3(1.0f), 1.0f / 21.0f) - B * (1.0f / 126.0f); }

// The angular part G(theta) of the directional albedo of Fujii's
// Oren-Nayar, E(mu) = pi A + B G(mu) (Cycles' bsdf_oren_nayar_G).
float oren_nayar_G(float cos_theta) {
  if (cos_theta < 1e-6f) return (0.5f * kPi - 2.0f / 3.0f) - cos_theta;
  const float sin_theta = safe_sqrt(1.0f - cos_theta * cos_theta);
  const float theta = std::acos(std::clamp(cos_theta, -1.0f, 1.0f));
  return sin_theta * (theta - 2.0f / 3.0f - sin_theta * cos_theta) +
         2.0f / 3.0f * (sin_theta / cos_theta) * (1.0f - sin_theta * sin_theta * sin_theta);
}

// Cycles' closure_layering_weight: what a layer with albedo estimate
// `albedo` (its weight included) leaves of `weight` for the layers below.
vec3 layering_weight(const vec3& albedo, const vec3& weight) {
  float m = 0.0f;
  for (int i = 0; i < 3; ++i)
    if (weight[i] != 0.0f) m = std::max(m, albedo[i] / weight[i]);
  return weight * std::clamp(1.0f - m, 0.0f, 1.0f);
}

}  // namespace

// A lobe's probability of being sampled, and what eval() and sample_f()
// read of it without recomputing: its flags, the ray kinds it scatters into
// and, for a smooth GGX lobe, Smith's Lambda(wo).
void BSDF::finish_lobe(Lobe& l, float prob) {
  l.prob = prob;
  l.is_delta = l.delta();
  l.is_reflect = l.reflects();
  l.is_transmit = l.transmits();
  l.kinds = l.type == Lobe::kBurley || l.type == Lobe::kOrenNayar ? kRayDiffuse
            : l.type == Lobe::kGlass                             ? kRayGlossy | kRayTransmission
            : l.transmits()                                      ? kRayTransmission
                                                                 : kRayGlossy;
  if (l.type != Lobe::kBurley && l.type != Lobe::kOrenNayar && !l.is_delta) l.lambda_o = l.ggx.lambda(wo_);
  if (l.prob > 0.0f && !l.is_delta) has_smooth_ = true, has_smooth_transmission_ |= l.is_transmit;
}

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
  const vec3 cspec0 = vec3(specular * 0.08f) * (1.0f - metallic) + base * metallic;

  const float glass_weight = transmission * w;
  const float ior = std::max(c.ior, 1e-4f);
  const float eta = back_face ? 1.0f / ior : ior;
  // Only glass needs the Fresnel term (a square root and two divisions).
  const float fresnel_o = glass_weight > 0.0f ? fresnel_dielectric(wo_.z, eta) : 0.0f;

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
    // The IOR whose reflectance at normal incidence, ((ior - 1) / (ior + 1))^2, is 0.08 specular.
    l.spec_f0 = std::min(0.08f * specular, 0.999f);
    l.spec_ior = 2.0f / (1.0f - std::sqrt(l.spec_f0)) - 1.0f;
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
  if (c.kind != ClosureKind::Principled && !(max_component(color) * c.weight > kClosureCutoff)) return;
  if (c.model != ShadingModel::Cycles3) {
    add_closure_v4(c, back_face);
    return;
  }
  const float roughness = std::clamp(c.roughness, 0.0f, 1.0f);
  switch (c.kind) {
    case ClosureKind::Principled:
      add_principled(c, back_face);
      break;
    case ClosureKind::Diffuse: {
      // Cycles' bsdf_oren_nayar_setup; roughness 0 is Lambert (bsdf_diffuse).
      Lobe& l = add_lobe(Lobe::kOrenNayar, c.weight * luminance(color));
      l.tint = color * c.weight;
      l.ms = vec3(0.0f);
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

// ---------------------------------------------------------------- Cycles 4.x

BSDF::Lobe& BSDF::add_microfacet(Lobe::Fresnel fresnel, const vec3& weight, float alpha, float fresnel_ior,
                                 const vec3& f0) {
  Lobe& l = add_lobe(Lobe::kMicrofacet, 0.0f);
  l.tint = weight;
  l.ggx = GGX{alpha};
  l.fresnel = fresnel;
  l.fresnel_ior = fresnel_ior;
  l.f0 = f0;
  l.f82_b = vec3(0.0f);
  l.energy_scale = 1.0f;
  return l;
}

BSDF::Lobe& BSDF::add_glass(const vec3& weight, float alpha, float eta, const vec3& f0, const vec3& tint_r,
                            const vec3& tint_t) {
  Lobe& l = add_lobe(Lobe::kGlass, 0.0f);
  l.tint = weight;
  l.ggx = GGX{alpha};
  l.fresnel = Lobe::kRealRemapped;
  l.fresnel_ior = eta;
  l.eta = eta;
  l.f0 = saturate(f0);
  l.tint_r = tint_r;
  l.tint_t = tint_t;
  l.energy_scale = 1.0f;
  return l;
}

// Cycles' microfacet_fresnel for a reflection lobe at cos_i = wo.wm.
vec3 BSDF::fresnel(const Lobe& l, float cos_i) const {
  switch (l.fresnel) {
    case Lobe::kFresnelOne:
      return vec3(1.0f);
    case Lobe::kDielectric:
      return vec3(fresnel_dielectric(cos_i, l.fresnel_ior));
    case Lobe::kRealRemapped: {
      const float F0_real = ggx_energy::F0_from_ior(l.fresnel_ior);
      const float s = std::clamp((fresnel_dielectric(cos_i, l.fresnel_ior) - F0_real) / (1.0f - F0_real), 0.0f, 1.0f);
      return glm::mix(l.f0, vec3(1.0f), s);
    }
    case Lobe::kF82Tint: {
      const float m = std::clamp(1.0f - cos_i, 0.0f, 1.0f), m5 = m * m * m * m * m;
      return saturate(glm::mix(l.f0, vec3(1.0f), m5) - l.f82_b * (cos_i * m5 * m));
    }
  }
  return vec3(1.0f);
}

// Glass: reflectance R = F tint_r and transmittance T = (1 - F) tint_t at the
// microfacet (F is 1 under total internal reflection).
void BSDF::glass_fresnel(const Lobe& l, float cos_i, vec3& R, vec3& T) const {
  const vec3 F = fresnel(l, cos_i);
  R = F * l.tint_r;
  T = (vec3(1.0f) - F) * l.tint_t;
}

// Cycles' bsdf_microfacet_estimate_albedo: the lobe's albedo for this wo
// without its weight: the Fresnel factor averaged over the lobe from the
// tables for the generalised Schlick and F82 models, the factor at wo.N for
// the rest (transmission included).
vec3 BSDF::albedo_estimate(const Lobe& l) const {
  const float mu = wo_.z;
  const float rough = std::sqrt(l.ggx.alpha);
  if (l.type == Lobe::kGlass) {
    vec3 R, T;
    glass_fresnel(l, mu, R, T);
    if (max_component(R) > 0.0f)
      R = glm::mix(l.f0, vec3(1.0f), ggx_energy::gen_schlick_ior_s(rough, mu, l.fresnel_ior)) * l.tint_r;
    return R + T;
  }
  switch (l.fresnel) {
    case Lobe::kFresnelOne:
      return vec3(1.0f);
    case Lobe::kDielectric:
      if (l.fresnel_ior > 1.0f)
        return vec3(glm::mix(ggx_energy::F0_from_ior(l.fresnel_ior), 1.0f,
                             ggx_energy::gen_schlick_ior_s(rough, mu, l.fresnel_ior)));
      return fresnel(l, mu);
    case Lobe::kRealRemapped:
      return glm::mix(l.f0, vec3(1.0f), ggx_energy::gen_schlick_ior_s(rough, mu, l.fresnel_ior));
    case Lobe::kF82Tint:
      return glm::mix(l.f0, vec3(1.0f), ggx_energy::schlick_s(rough, mu));
  }
  return vec3(1.0f);
}

// Cycles' microfacet_ggx_preserve_energy (Kulla and Conty 2017): the
// single-scattering lobe loses 1 - E(mu) of the light; scaling it by 1 / E
// gives that back for Fresnel 1, and a coloured Fresnel with average Fss
// keeps (1 + Fms (1 - E) / E) E of it, Fms = Fss E_avg / (1 - Fss (1 - E_avg))
// (the multiple bounces between microfacets saturate the colour).
void BSDF::preserve_energy(Lobe& l, const vec3& Fss) {
  const float mu = wo_.z;
  const float rough = std::sqrt(l.ggx.alpha);
  float E, E_avg;
  if (l.type == Lobe::kGlass) {
    E = ggx_energy::glass_E(rough, mu, l.eta);
    E_avg = ggx_energy::glass_E_avg(rough, l.eta);
  } else {
    E = ggx_energy::E(rough, mu);
    E_avg = ggx_energy::E_avg(rough);
  }
  E = std::max(E, 1e-6f);
  const float missing = (1.0f - E) / E;
  l.energy_scale = 1.0f + missing;
  if (Fss != vec3(1.0f)) {
    const vec3 Fms = Fss * E_avg / (vec3(1.0f) - Fss * (1.0f - E_avg));
    l.tint *= (vec3(1.0f) + Fms * missing) / l.energy_scale;
  }
}

// The Principled BSDF as Cycles 4.x builds it (svm_node_closure_bsdf,
// CLOSURE_BSDF_PRINCIPLED_ID): layers from the top, each taking its albedo
// estimate off the weight of those below. Sheen, subsurface, anisotropy and
// thin film are not modelled (the add-on names them in a warning).
void BSDF::add_principled_v2(const Closure& c, bool back_face) {
  vec3 weight(c.weight);
  const vec3 base = saturate(c.color);
  const float metallic = std::clamp(c.metallic, 0.0f, 1.0f);
  const float transmission = std::clamp(c.transmission, 0.0f, 1.0f);
  const float roughness = std::clamp(c.roughness, 0.0f, 1.0f);
  const float alpha = roughness * roughness;
  const float ior = std::max(c.ior, 1e-5f);
  const vec3 specular_tint = glm::max(c.specular_tint, vec3(0.0f));
  const float mu = wo_.z;
  // The sample weight of the lobe just added: its weight times its albedo estimate.
  auto weigh_last = [this]() {
    const Lobe& l = lobes_[num_lobes_ - 1];
    sample_weight_[num_lobes_ - 1] = luminance(l.tint) * std::max(average(albedo_estimate(l)) * l.energy_scale, 0.02f);
  };

  // Coat: GGX with the dielectric Fresnel of its IOR, always energy-compensated.
  const float coat = std::max(c.coat, 0.0f);
  if (coat > kClosureCutoff) {
    const float coat_roughness = std::clamp(c.coat_roughness, 0.0f, 1.0f);
    const float coat_ior = std::max(c.coat_ior, 1.0f);
    Lobe& l = add_microfacet(Lobe::kDielectric, coat * weight, sqr(coat_roughness), coat_ior, vec3(0.0f));
    preserve_energy(l, vec3(fresnel_dielectric_Fss(coat_ior)));
    weigh_last();
    weight = layering_weight(l.tint * albedo_estimate(l), weight);
    const vec3 coat_tint = glm::max(c.coat_tint, vec3(0.0f));
    if (coat_tint != vec3(1.0f)) {
      // Beer's law along the refracted view ray through a coat of unit thickness.
      const float cos_t = std::sqrt(1.0f - sqr(1.0f / coat_ior) * (1.0f - mu * mu));
      const vec3 absorbed(std::pow(coat_tint.x, 1.0f / cos_t), std::pow(coat_tint.y, 1.0f / cos_t),
                          std::pow(coat_tint.z, 1.0f / cos_t));
      weight *= glm::mix(vec3(1.0f), absorbed, coat);
    }
  }

  // Metal: F82-tint Fresnel from the base colour, tinted at grazing angles by the specular tint.
  if (metallic > kClosureCutoff) {
    Lobe& l = add_microfacet(Lobe::kF82Tint, metallic * weight, alpha, 1.0f, base);
    const vec3 f82 = glm::min(specular_tint, vec3(1.0f));
    l.f82_b = f82 == vec3(1.0f) ? vec3(0.0f) : fresnel_f82tint_B(base, f82);
    if (c.multiscatter) preserve_energy(l, fresnel_f82_Fss(l.f0, l.f82_b));
    weigh_last();
    weight *= 1.0f - metallic;
  }

  // Glass: reflection F, refraction (1 - F) sqrt(base) (the colour is met twice, entering and leaving).
  if (transmission > kClosureCutoff) {
    const float eta = back_face ? 1.0f / ior : ior;
    const vec3 tint_t = glm::sqrt(base);
    Lobe& l = add_glass(transmission * weight, alpha, eta, vec3(ggx_energy::F0_from_ior(ior)) * specular_tint,
                        vec3(1.0f), tint_t);
    if (c.multiscatter) preserve_energy(l, tint_t);
    weigh_last();
    weight *= 1.0f - transmission;
  }

  // Dielectric specular: F0 of the IOR scaled by 2 x Specular IOR Level, i.e. the IOR that has that F0.
  float eta = ior;
  float f0 = ggx_energy::F0_from_ior(ior);
  const float level = std::max(c.specular, 0.0f);
  if (level != 0.5f) {
    f0 *= 2.0f * level;
    eta = ggx_energy::ior_from_F0(f0);
    if (ior < 1.0f) eta = 1.0f / eta;
  }
  if (eta != 1.0f) {
    Lobe& l = add_microfacet(Lobe::kRealRemapped, weight, alpha, eta, saturate(f0 * specular_tint));
    if (c.multiscatter) {
      const float F0_real = ggx_energy::F0_from_ior(eta);
      const float s = std::clamp((fresnel_dielectric_Fss(eta) - F0_real) / (1.0f - F0_real), 0.0f, 1.0f);
      preserve_energy(l, glm::mix(l.f0, vec3(1.0f), s));
    }
    weigh_last();
    weight = layering_weight(l.tint * albedo_estimate(l), weight);
  }

  // Diffuse: Lambert, or Oren-Nayar with the Diffuse Roughness (Blender 4.3 on).
  const vec3 diffuse = base * weight;
  if (max_component(diffuse) > 0.0f) {
    Lobe& l = add_lobe(Lobe::kOrenNayar, luminance(diffuse));
    l.tint = diffuse;
    set_oren_nayar(l, std::clamp(c.diffuse_roughness, 0.0f, 1.0f), base, c.model == ShadingModel::Cycles4_3);
  }
}

// Fujii's Oren-Nayar ("qualitative" model, Cycles' bsdf_oren_nayar_setup) with
// roughness sigma (Lambert below the cutoff); with multiple_scattering, the
// OpenPBR energy-preserving term Cycles 4.3 adds:
// Ems (1 - E(wo)) (1 - E(wi)), Ems = albedo^2 E_avg / (1 - E_avg) / (pi (1 - albedo (1 - E_avg))).
void BSDF::set_oren_nayar(Lobe& l, float sigma, const vec3& color, bool multiple_scattering) const {
  l.ms = vec3(0.0f);
  if (sigma < kClosureCutoff) {
    l.a = kInvPi;
    l.b = 0.0f;
    return;
  }
  l.a = 1.0f / (kPi + sigma * (0.5f * kPi - 2.0f / 3.0f));
  l.b = sigma * l.a;
  if (multiple_scattering) {
    const vec3 albedo = saturate(color);
    const float E_avg = l.a * kPi + ((2.0f * kPi - 5.6f) / 3.0f) * l.b;
    const vec3 Ems = kInvPi * albedo * albedo * (E_avg / (1.0f - E_avg)) / (vec3(1.0f) - albedo * (1.0f - E_avg));
    const float E_o = l.a * kPi + l.b * oren_nayar_G(std::max(wo_.z, 0.0f));
    l.ms = Ems * (1.0f - E_o);
  }
}

// The other closures as Cycles 4.x sets them up.
void BSDF::add_closure_v4(const Closure& c, bool back_face) {
  const vec3 color = saturate(c.color);
  const float roughness = std::clamp(c.roughness, 0.0f, 1.0f);
  switch (c.kind) {
    case ClosureKind::Principled:
      add_principled_v2(c, back_face);
      break;
    case ClosureKind::Diffuse: {
      Lobe& l = add_lobe(Lobe::kOrenNayar, c.weight * luminance(color));
      l.tint = color * c.weight;
      set_oren_nayar(l, roughness, color, c.model == ShadingModel::Cycles4_3);
      break;
    }
    case ClosureKind::Glossy: {
      Lobe& l = add_microfacet(Lobe::kFresnelOne, color * c.weight, roughness * roughness, 1.0f, vec3(1.0f));
      if (c.multiscatter) preserve_energy(l, color);
      sample_weight_[num_lobes_ - 1] = luminance(l.tint) * l.energy_scale + 1e-6f;
      break;
    }
    case ClosureKind::Glass: {
      // One closure: reflection or refraction chosen at the microfacet by its Fresnel factor.
      const float ior = std::max(c.ior, 1e-5f);
      Lobe& l = add_glass(vec3(c.weight), roughness * roughness, back_face ? 1.0f / ior : ior,
                          vec3(ggx_energy::F0_from_ior(ior)), color, color);
      if (c.multiscatter) preserve_energy(l, color);
      sample_weight_[num_lobes_ - 1] = luminance(l.tint) * std::max(luminance(color), 0.02f) * l.energy_scale;
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
    // Cycles 3.x bends the shading normal of every closure so that mirror
    // reflections stay above the surface; Cycles 4.x only where a bump or
    // normal map made the normal (maybe_ensure_valid_specular_reflection,
    // SD_USE_BUMP_MAP_CORRECTION): interpolated normals are used as they are.
    : frame_(m.model == ShadingModel::Cycles3 || m.normal_tex.valid() ? ensure_valid_reflection(ng, wo_world, ns) : ns),
      ng_(ng),
      wo_world_(wo_world) {
  wo_ = frame_.to_local(wo_world);
  if (m.model == ShadingModel::Cycles3 && m.kind == ClosureKind::Principled && m.num_more == 0 && m.alpha >= 1.0f &&
      m.weight > 0.0f && !(m.metallic > 0.0f) && !(m.specular > 0.0f) && !(m.transmission > 0.0f)) {
    // A Cycles 3.x Principled BSDF with no metallic, specular or
    // transmission, alone: its diffuse lobe (add_principled's first) is the
    // whole BSDF, whatever wo is. Built directly, without copying closure 0
    // and running the closure list: the same lobe, bit for bit, for about a
    // third of the constructor's time (McGuire's Cornell box: 6.8% -> 2.4%).
    const vec3 tint = glm::clamp(m.base_color, vec3(0.0f), vec3(1.0f)) * m.weight;
    if (!(luminance(tint) > 0.0f)) return;  // black: nothing scatters
    Lobe& l = add_lobe(Lobe::kBurley, 1.0f);
    l.tint = tint;
    l.a = std::clamp(m.roughness, 0.0f, 1.0f);
    finish_lobe(l, 1.0f);
    return;
  }
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
    for (int i = 0; i < num_lobes_; ++i) finish_lobe(lobes_[i], sample_weight_[i] / total);
  } else {
    num_lobes_ = 0;  // nothing scatters
  }
}

// The lobe's value for wi and, in *pdf, the density with which the lobe
// samples wi (before its probability): the half vector, D and Lambda(wi) of
// a GGX lobe serve both, Lambda(wo) comes from the constructor, and the
// visible-normal density of a reflection, G1(wo) D(wm) |wo.wm| / (wo.z 4 |wo.wm|),
// is G1(wo) D(wm) / (4 wo.z).
vec3 BSDF::eval_lobe(const Lobe& l, const vec3& wi, float* pdf) const {
  const vec3& wo = wo_;
  *pdf = 0.0f;
  switch (l.type) {
    case Lobe::kBurley: {
      // Cycles 3.x principled diffuse (Burley 2012 with its retro-reflection term).
      if (wi.z <= 0.0f) return vec3(0.0f);
      *pdf = wi.z * kInvPi;
      if (wo.z <= 0.0f) return vec3(0.0f);
      float fl = schlick_weight(wi.z), fv = schlick_weight(wo.z);
      float f = (1.0f - 0.5f * fv) * (1.0f - 0.5f * fl);
      float rr = l.a * (glm::dot(wi, wo) + 1.0f);
      f += rr * (fl + fv + fl * fv * (rr - 1.0f));
      return l.tint * (f * kInvPi);
    }
    case Lobe::kOrenNayar: {
      // Cycles' bsdf_oren_nayar (the "qualitative" model, Oren and Nayar 1994):
      // f = A + B max(0, cos(phi_i - phi_o)) sin(a) tan(b), written with dot products.
      if (wi.z <= 0.0f) return vec3(0.0f);
      *pdf = wi.z * kInvPi;
      if (wo.z <= 0.0f) return vec3(0.0f);
      if (l.b <= 0.0f) return l.tint * l.a;
      float t = glm::dot(wi, wo) - wi.z * wo.z;
      if (t > 0.0f) t /= std::max(wi.z, wo.z) + std::numeric_limits<float>::min();
      const float E_i = l.a * kPi + l.b * oren_nayar_G(wi.z);
      return l.tint * (vec3(l.a + l.b * t) + l.ms * (1.0f - E_i));
    }
    case Lobe::kSpecular:
    case Lobe::kReflection:
    case Lobe::kMicrofacet: {
      if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3(0.0f);
      const vec3 wm = glm::normalize(wi + wo);
      const float D = l.ggx.D(wm), lambda_i = l.ggx.lambda(wi);
      const float G1_o = 1.0f / (1.0f + l.lambda_o);
      *pdf = G1_o * D / (4.0f * wo.z);
      if (l.type == Lobe::kMicrofacet) {
        const float G = 1.0f / (1.0f + l.lambda_o + lambda_i);  // height-correlated (Cycles 4.x)
        return l.tint * fresnel(l, glm::dot(wo, wm)) * (l.energy_scale * D * G / (4.0f * wi.z * wo.z));
      }
      const float G = G1_o * (1.0f / (1.0f + lambda_i));  // separable (Cycles 3.x)
      if (l.type == Lobe::kSpecular)
        return l.k * interpolate_fresnel(glm::dot(wi, wm), l.spec_ior, l.spec_f0, l.cspec0) *
               (D * G / (4.0f * wi.z * wo.z));
      return l.tint * (l.k * D * G / (4.0f * wi.z * wo.z));
    }
    case Lobe::kRefraction:
    case Lobe::kGlass: {
      if (wo.z <= 0.0f || wi.z == 0.0f || (l.type == Lobe::kRefraction && wi.z > 0.0f)) return vec3(0.0f);
      const float G1_o = 1.0f / (1.0f + l.lambda_o);
      if (wi.z > 0.0f) {  // glass reflection
        const vec3 wm = glm::normalize(wi + wo);
        vec3 R, T;
        glass_fresnel(l, glm::dot(wo, wm), R, T);
        const float sum = average(R + T);
        const float D = l.ggx.D(wm), G = 1.0f / (1.0f + l.lambda_o + l.ggx.lambda(wi));
        // The visible-normal density times the probability of reflecting at that microfacet.
        if (sum > 0.0f) *pdf = G1_o * D / (4.0f * wo.z) * (average(R) / sum);
        return l.tint * R * (l.energy_scale * D * G / (4.0f * wi.z * wo.z));
      }
      // Generalised half vector (Walter et al. 2007), facing wo's side.
      vec3 wm = glm::normalize(wi * l.eta + wo);
      if (wm.z < 0.0f) wm = -wm;
      const float dot_i = glm::dot(wi, wm), dot_o = glm::dot(wo, wm);
      if (dot_i >= 0.0f || dot_o <= 0.0f) return vec3(0.0f);
      const float denom = sqr(dot_i + dot_o / l.eta);
      const float D = l.ggx.D(wm), lambda_i = l.ggx.lambda(wi);
      const float pdf_wm = G1_o / wo.z * D * dot_o * (std::abs(dot_i) / denom);
      const float ft_D = D * std::abs(dot_i * dot_o / (wi.z * wo.z * denom));
      if (l.type == Lobe::kRefraction) {
        *pdf = pdf_wm;
        // No 1/eta^2 radiance scaling, as in Cycles.
        return l.tint * (l.k * ft_D * (G1_o * (1.0f / (1.0f + lambda_i))));
      }
      vec3 R, T;
      glass_fresnel(l, dot_o, R, T);
      const float sum = average(R + T);
      if (sum > 0.0f) *pdf = pdf_wm * (average(T) / sum);
      return l.tint * T * (l.energy_scale * ft_D * (1.0f / (1.0f + l.lambda_o + lambda_i)));
    }
    case Lobe::kTransparent:
      break;
  }
  return vec3(0.0f);
}

// kExcluding: lobes all of whose kinds are in `excluded` are left out. Not
// inlined into the wrappers below (the render loop calls them).
template <bool kExcluding>
__attribute__((noinline)) vec3 BSDF::eval_lobes(const vec3& wi_world, float* pdf, uint8_t excluded) const {
  const vec3 wi = frame_.to_local(wi_world);
  const bool reflect_side = same_side(wi_world);
  vec3 sum(0.0f);
  float p = 0.0f;
  for (int i = 0; i < num_lobes_; ++i) {
    const Lobe& l = lobes_[i];
    // The geometric side decides reflection vs transmission (no light leaks).
    if (l.prob == 0.0f || l.is_delta || !(reflect_side ? l.is_reflect : l.is_transmit)) continue;
    if (kExcluding && (l.kinds & excluded) == l.kinds) continue;
    float lobe_pdf;
    sum += eval_lobe(l, wi, &lobe_pdf);
    p += l.prob * lobe_pdf;
  }
  *pdf = p;
  return sum;
}

vec3 BSDF::eval(const vec3& wi_world, float* pdf) const { return eval_lobes<false>(wi_world, pdf, 0); }

vec3 BSDF::eval(const vec3& wi_world, float* pdf, uint8_t excluded) const {
  return eval_lobes<true>(wi_world, pdf, excluded);
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
  // Where u_lobe fell within the chosen lobe's share: a fresh uniform number
  // (glass chooses between reflection and refraction with it).
  const float u_within = std::clamp((u_lobe - (acc - l.prob)) / l.prob, 0.0f, 0.99999994f);
  switch (l.type) {
    case Lobe::kBurley:
    case Lobe::kOrenNayar: s.kind = BSDFSample::kDiffuse; break;
    case Lobe::kSpecular:
    case Lobe::kReflection:
    case Lobe::kMicrofacet:
    case Lobe::kGlass: s.kind = BSDFSample::kGlossy; break;
    case Lobe::kRefraction: s.kind = BSDFSample::kTransmission; break;
    case Lobe::kTransparent: s.kind = BSDFSample::kTransparent; break;
  }
  vec3 wi;
  if (l.type == Lobe::kTransparent) {
    // Straight on, exactly; divided by the cosine the caller multiplies by
    // (abs_cos), so that f |cos| / pdf is the closure weight / prob.
    s.wi = -wo_world_;
    const float cos_i = abs_cos(s.wi);
    if (same_side(s.wi) || !(cos_i > 0.0f)) return false;
    s.f = l.tint * l.k / cos_i;
    s.pdf = l.prob;
    s.delta = true;
    return max_component(s.f) > 0.0f;
  }
  if (l.type == Lobe::kGlass) {
    // Cycles 4.x: a visible normal, then reflection or refraction at it with
    // probability avg(R) / avg(R + T).
    const vec3 wm = l.delta() ? vec3(0, 0, 1) : l.ggx.sample_visible(wo_, u);
    vec3 R, T;
    glass_fresnel(l, glm::dot(wo_, wm), R, T);
    const float sum = average(R + T);
    if (!(sum > 0.0f)) return false;
    const float p_reflect = average(R) / sum;
    const bool refracted = u_within >= p_reflect;
    if (refracted) {
      if (!refract(wo_, wm, l.eta, &wi) || wi.z >= 0.0f) return false;
      s.kind = BSDFSample::kTransmission;
    } else {
      wi = reflect(wo_, wm);
      if (wi.z <= 0.0f) return false;
    }
    s.wi = frame_.to_world(wi);
    if (refracted == same_side(s.wi)) return false;
    if (l.delta()) {
      s.f = l.tint * (refracted ? T : R) * (l.energy_scale / std::abs(wi.z));
      s.pdf = l.prob * (refracted ? 1.0f - p_reflect : p_reflect);
      s.delta = true;
      return s.pdf > 0.0f && max_component(s.f) > 0.0f;
    }
    s.delta = false;
    s.f = eval(s.wi, &s.pdf);
    return s.pdf > 0.0f && max_component(s.f) > 0.0f;
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
    vec3 weight = l.type == Lobe::kSpecular     ? l.k * interpolate_fresnel(wo_.z, l.spec_ior, l.spec_f0, l.cspec0)
                  : l.type == Lobe::kMicrofacet ? l.tint * fresnel(l, wo_.z) * l.energy_scale
                                                : l.tint * l.k;
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
    case Lobe::kMicrofacet:
      wi = reflect(wo_, l.ggx.sample_visible(wo_, u));
      if (wi.z <= 0.0f) return false;
      break;
    case Lobe::kRefraction: {
      vec3 wm = l.ggx.sample_visible(wo_, u);
      if (!refract(wo_, wm, l.eta, &wi) || wi.z >= 0.0f) return false;
      break;
    }
    case Lobe::kGlass:
    case Lobe::kTransparent:
      return false;
  }
  s.wi = frame_.to_world(wi);
  s.delta = false;
  s.f = eval(s.wi, &s.pdf);
  return s.pdf > 0.0f && max_component(s.f) > 0.0f;
}

}  // namespace tessera
