#include "integrator.h"

#include "bsdf.h"

namespace tessera {

namespace {
// Cycles' sample clamping (kernel_accum_clamp): scales a contribution down so
// that its largest component is at most the limit; 0 is off.
inline vec3 clamped(vec3 c, float limit) {
  if (limit > 0.0f) {
    const float m = max_component(c);
    if (m > limit) c *= limit / m;
  }
  return c;
}
}  // namespace

SceneFeatures scene_features(const Scene& scene) {
  const LightSampler& lights = scene.light_sampler();
  bool area = false;  // lights that scattered rays can hit (LightSampler::intersect_lights)
  for (const Light& l : lights.lights())
    area = area || l.type == LightType::Area || ((l.type == LightType::Point || l.type == LightType::Spot) && l.radius > 0.0f);
  SceneFeatures f;
  f.hittable_emitters = area || !lights.triangles().empty() || scene.background.emits();
  f.emits = f.hittable_emitters || !lights.lights().empty();
  return f;
}

vec3 Li(const Scene& scene, Ray ray, Sampler& sampler, const RenderOptions& options, PathCounters& counters,
        const SceneFeatures& features) {
  const LightSampler& lights = scene.light_sampler();
  vec3 L(0.0f), beta(1.0f);
  float prev_bsdf_pdf = 0.0f;
  bool count_emission_fully = true;  // camera rays and delta bounces: no MIS
  // Bounces of each kind so far (BSDFSample::Kind), for the per-kind limits.
  int kind_bounces[3] = {0, 0, 0};
  const int kind_limit[3] = {options.max_diffuse_bounces, options.max_glossy_bounces, options.max_transmission_bounces};
  // Clamping as in Cycles: contributions of bounce 0 (what the camera sees
  // emit, light sampled at the first hit) are direct, the rest indirect.
  auto add = [&](int bounce, vec3 c) { L += clamped(c, bounce == 0 ? options.clamp_direct : options.clamp_indirect); };

  for (int bounce = 0;; ++bounce) {
    Hit hit;
    ++counters.rays;
    const bool found = scene.intersect(ray, hit);
    const float t_end = found ? hit.t : ray.tmax;

    // Area lights and point/spot lights with a radius are seen by scattered
    // rays, not by the camera (as in Cycles), and do not block the ray.
    if (bounce > 0) {
      float t_light, light_pdf;
      vec3 le;
      int light = lights.intersect_lights(ray.o, ray.d, t_end, &t_light, &le, &light_pdf);
      if (light >= 0) {
        float w = count_emission_fully ? 1.0f : power_heuristic(prev_bsdf_pdf, light_pdf);
        add(bounce, beta * le * w);
      }
    }

    if (!found) {
      if (scene.background.emits()) {
        float w = count_emission_fully ? 1.0f : power_heuristic(prev_bsdf_pdf, lights.pdf_background(ray.d));
        add(bounce, beta * scene.background.Le(ray.d) * w);
      }
      break;
    }

    const SurfaceInteraction si = scene.interaction(ray, hit);
    const Material material = scene.material_at(si);
    const vec3 le = material.emission(si.back_face);
    if (max_component(le) > 0.0f) {
      float w = 1.0f;
      if (!count_emission_fully) {
        float cos_l = std::abs(glm::dot(ray.d, si.ng));
        w = power_heuristic(prev_bsdf_pdf, lights.pdf_triangle(hit.instance, hit.prim, hit.t, cos_l));
      }
      add(bounce, beta * le * w);
    }
    if (bounce > options.max_bounces) break;
    if (kind_bounces[0] > kind_limit[0] || kind_bounces[1] > kind_limit[1] || kind_bounces[2] > kind_limit[2]) break;

    // Shade on the side the ray arrived from (Blender surfaces are two-sided).
    const vec3 ng = si.back_face ? -si.ng : si.ng;
    const vec3 ns = si.back_face ? -si.ns : si.ns;
    const BSDF bsdf(ns, ng, material, si.back_face, -ray.d);

    // Next-event estimation.
    const float u_light = sampler.get_1d();
    const vec2 u_light_pos = sampler.get_2d();
    LightSample ls;
    if (bsdf.has_smooth_lobes() && !lights.empty() && lights.sample(si.p, u_light, u_light_pos, ls)) {
      vec3 f = bsdf.f(ls.wi) * std::abs(glm::dot(ls.wi, ns));
      if (max_component(f) > 0.0f) {
        vec3 origin = offset_ray_origin(si.p, si.p_error, ng, ls.wi);
        // Stop just short of the sampled light point, relative to its distance,
        // measured from the offset origin (far from the world origin the offset
        // is not negligible next to the distance).
        float tmax = std::isinf(ls.dist) ? kInf : (ls.dist - glm::dot(origin - si.p, ls.wi)) * (1.0f - 1e-4f);
        ++counters.rays;
        if (!scene.occluded(origin, ls.wi, tmax)) {
          float w = ls.is_delta ? 1.0f : power_heuristic(ls.pdf, bsdf.pdf(ls.wi));
          add(bounce, beta * f * ls.li * (w / ls.pdf));
        }
      }
    }

    // Continue the path by sampling the BSDF.
    BSDFSample bs;
    const float u_lobe = sampler.get_1d();
    if (!bsdf.sample_f(u_lobe, sampler.get_2d(), bs)) break;
    beta *= bs.f * (std::abs(glm::dot(bs.wi, ns)) / bs.pdf);
    prev_bsdf_pdf = bs.pdf;
    count_emission_fully = bs.delta;
    ++kind_bounces[bs.kind];
    // The next vertex would only add emission and stop: with nothing a ray
    // can hit that emits, skip it (same image, one ray fewer per path).
    if (!features.hittable_emitters &&
        (bounce + 1 > options.max_bounces || kind_bounces[bs.kind] > kind_limit[bs.kind])) {
      ++counters.skipped_rays;
      break;
    }
    ray.o = offset_ray_origin(si.p, si.p_error, ng, bs.wi);
    ray.d = bs.wi;
    ray.tmax = kInf;

    // Russian roulette (pbrt-v4, 14.1.5): survive with the throughput's
    // largest component.
    const float u_rr = sampler.get_1d();
    if (bounce + 1 >= options.rr_depth) {
      float q = std::max(0.0f, 1.0f - max_component(beta));
      if (u_rr < q) break;
      beta /= 1.0f - q;
    }
  }
  if (!is_finite(L)) {
    ++counters.invalid_samples;
    return vec3(0.0f);
  }
  return L;
}

}  // namespace tessera
