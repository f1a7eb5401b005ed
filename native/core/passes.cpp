#include "passes.h"

namespace tessera {

namespace {
// Cycles' denoising_passes.h: closures with squared roughness (alpha_x
// alpha_y = roughness^4) above 0.075^2 count as diffuse-like.
bool diffuse_like(float roughness) { return roughness * roughness > 0.075f; }
}  // namespace

ClosureAlbedo closure_albedo(const Material& m) {
  const float metallic = glm::clamp(m.metallic, 0.0f, 1.0f);
  const float transmission = glm::clamp(m.transmission, 0.0f, 1.0f);
  const vec3 base = glm::max(m.base_color, vec3(0.0f));
  // The Principled closure weights of bsdf.h, Fresnel taken at normal
  // incidence for the specular lobe (Cycles scales by its average Fresnel).
  const float w_diffuse = (1.0f - metallic) * (1.0f - transmission);
  const float w_specular = 1.0f - (1.0f - metallic) * transmission;
  const float w_glass = (1.0f - metallic) * transmission;
  const vec3 f0 = glm::mix(vec3(0.08f * glm::max(m.specular, 0.0f)), base, metallic);
  ClosureAlbedo a;
  a.diffuse_color = w_diffuse * base;
  const vec3 specular = w_specular * f0, glass = w_glass * base;
  const float s_diffuse = average(a.diffuse_color), s_specular = average(specular), s_glass = average(glass);
  a.diffuse_like = a.diffuse_color;
  a.specular_like = vec3(0.0f);
  a.sample_weight = s_diffuse + s_specular + s_glass;
  a.nonspecular_sample_weight = s_diffuse;
  if (diffuse_like(m.roughness)) {
    a.diffuse_like += specular + glass;
    a.nonspecular_sample_weight += s_specular + s_glass;
  } else {
    a.specular_like = specular + glass;
  }
  return a;
}

void FirstHit::surface(const Ray& ray, float t, const SurfaceInteraction& si, const Material& m, const vec3& le) {
  // Cycles flips the shading normal to the side the ray arrived from.
  const vec3 n = si.back_face ? -si.ns : si.ns;
  const ClosureAlbedo a = closure_albedo(m);
  if (!emission_done) {
    emission_done = true;
    emission = le;
  }
  if (!hit && camera_ray && (alpha_threshold <= 0.0f || !m.may_be_transparent() || 1.0f - average(m.transparency()) >= alpha_threshold)) {
    hit = true;
    position = ray.o + t * ray.d;
    normal = n;
    diffuse_color = a.diffuse_color;
  }
  if (denoising_done) return;
  denoising_albedo += denoising_throughput * le;
  // Wait for the next surface while 75% or more of the sample weight is
  // specular-like, carrying its albedo (film_write_denoising_features_surface).
  if (a.sample_weight == 0.0f || a.nonspecular_sample_weight * 4.0f > a.sample_weight) {
    denoising_done = true;
    denoising_normal = n;
    denoising_albedo += denoising_throughput * a.diffuse_like;
    denoising_depth = average(denoising_throughput) * t;
  } else {
    denoising_throughput *= a.specular_like;
  }
}

void FirstHit::miss(const vec3& le) {
  if (denoising_done) return;
  denoising_albedo += denoising_throughput * le;
  denoising_done = true;
}

}  // namespace tessera
