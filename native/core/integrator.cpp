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

// Transparent shadows (Cycles' shadow_all): the shadow ray passes surfaces
// whose material lets rays through, keeping their transparent weight, and
// is blocked by anything else or after max_hits such surfaces (the
// transparent bounces the path has left).
vec3 shadow_transmittance(const Scene& scene, vec3 o, const vec3& d, float tmax, int max_hits,
                          PathCounters& counters) {
  vec3 tr(1.0f);
  for (int hits = 0;; ++hits) {
    Ray r{o, d, tmax};
    Hit hit;
    ++counters.rays;
    if (!scene.intersect(r, hit, kRayShadow)) return tr;
    if (hits >= max_hits) return vec3(0.0f);
    const SurfaceInteraction si = scene.interaction(r, hit);
    const Material& base = scene.materials[si.material];
    if (!base.may_be_transparent()) return vec3(0.0f);
    MaterialScratch textured;
    tr *= scene.material_at(si, textured).transparency();
    if (!(max_component(tr) > 0.0f)) return vec3(0.0f);
    const vec3 next = offset_ray_origin(si.p, si.p_error, si.back_face ? -si.ng : si.ng, d);
    if (!std::isinf(tmax)) {
      tmax -= glm::dot(next - o, d);
      if (!(tmax > 0.0f)) return tr;
    }
    o = next;
  }
}

// Cycles' Light Threshold (light_sample_terminate): a light sample whose
// contribution before the path's throughput, f Li weight, has its largest
// component below the threshold is traced with probability max / threshold,
// and `weight` divided by that (Russian roulette on shadow rays: the same
// expectation, fewer rays to lights that add little). 0: every sample.
inline bool light_threshold_survives(const vec3& f_li, float& weight, float threshold, float u) {
  if (!(threshold > 0.0f)) return true;
  const float p = max_component(f_li) * weight / threshold;
  if (p >= 1.0f) return true;
  if (!(u < p)) return false;
  weight /= p;
  return true;
}

// The solid-angle density of hittable light `light` for MIS, as seen from the
// last scattering vertex, mis_t behind the ray's origin on the same line (the
// ray has since passed transparent surfaces; Cycles moves the origin back by
// mis_ray_t the same way). If another such light lies nearer on that line,
// this segment's density is kept.
float light_pdf_from_vertex(const LightSampler& lights, const Ray& ray, float mis_t, int light, float t_light,
                            float pdf, const vec3& vertex_p, const vec3& vertex_n, RayKind kind) {
  float t, p;
  vec3 le;
  if (lights.intersect_lights(ray.o - ray.d * mis_t, ray.d, (mis_t + t_light) * (1.0f + 1e-4f), &t, &le, &p, vertex_p,
                              vertex_n, kind) == light)
    return p;
  return pdf;
}
}  // namespace

SceneFeatures scene_features(const Scene& scene) {
  const LightSampler& lights = scene.light_sampler();
  SceneFeatures f;
  f.hittable_emitters = lights.has_hittable_lights() || lights.has_sun_disks() || !lights.triangles().empty() || scene.background.emits();
  f.emits = f.hittable_emitters || !lights.lights().empty();
  f.camera_emission = (scene.background.emits() && scene.background.seen_by(kRayCamera)) || lights.camera_sees_lights();
  for (const Material& m : scene.materials) {
    f.transparent = f.transparent || m.may_be_transparent();
    f.camera_emission = f.camera_emission || m.is_emissive();
  }
  return f;
}

vec3 camera_emission(const Scene& scene, const Ray& ray, const RenderOptions& options, PathCounters& counters) {
  Hit hit;
  ++counters.rays;
  const bool found = scene.intersect(ray, hit, kRayCamera);
  vec3 le(0.0f);
  // Area and sphere lights made visible to the camera, in front of the hit.
  if (scene.light_sampler().camera_sees_lights()) {
    float t, pdf;
    scene.light_sampler().intersect_lights(ray.o, ray.d, found ? hit.t : ray.tmax, &t, &le, &pdf, ray.o, vec3(0.0f),
                                           kRayCamera);
  }
  if (!found) {
    if (scene.background.emits() && scene.background.seen_by(kRayCamera) && !options.film_transparent)
      le += scene.background.Le(ray.d, nullptr);
    return clamped(le, options.clamp_direct);
  }
  const SurfaceInteraction si = scene.interaction(ray, hit);
  const Material& base = scene.materials[si.material];
  if (base.is_emissive()) {
    MaterialScratch textured;
    le += scene.material_at(si, textured).emission(si.back_face);
  }
  return clamped(le, options.clamp_direct);
}

vec3 Li(const Scene& scene, Ray ray, Sampler& sampler, const RenderOptions& options, PathCounters& counters,
        const SceneFeatures& features, FirstHit* first, vec3* camera_le, float* transparency) {
  if (camera_le) *camera_le = vec3(0.0f);
  if (transparency) *transparency = 0.0f;
  const LightSampler& lights = scene.light_sampler();
  vec3 L(0.0f), beta(1.0f);
  float prev_bsdf_pdf = 0.0f;
  // The last scattering vertex and its shading normal: light pdfs for MIS
  // are those of light sampling from there.
  vec3 prev_p(0.0f), prev_n(0.0f);
  float rr_u = 0.0f;  // Russian roulette at the next hit: its number, and whether it applies
  bool rr_pending = false;
  bool count_emission_fully = true;  // camera rays and delta bounces: no MIS
  // Bounces of each kind so far (BSDFSample::Kind), for the per-kind limits.
  int kind_bounces[3] = {0, 0, 0};
  const int kind_limit[3] = {options.max_diffuse_bounces, options.max_glossy_bounces, options.max_transmission_bounces};
  // Transparent surfaces passed straight through (Cycles' transparent_bounce,
  // its own limit), and the distance travelled through them since the last
  // scattering vertex (Cycles' mis_ray_t): emitters found after them are
  // MIS-weighted as seen from that vertex.
  int transparent_bounces = 0;
  float mis_t = 0.0f;
  // Clamping as in Cycles: contributions of bounce 0 (what the camera sees
  // emit, light sampled at the first hit) are direct, the rest indirect.
  auto add = [&](int bounce, vec3 c) { L += clamped(c, bounce == 0 ? options.clamp_direct : options.clamp_indirect); };
  // The kind of the ray being traced (visibility.h): the camera's until the
  // path scatters (on through transparent surfaces), then that of the lobe
  // it scattered by.
  RayKind kind = kRayCamera;
  // Light tracing's partition: 1 after the first scattering vertex when it
  // scattered by a rough lobe, 2 once delta vertices followed it (and only
  // they), -1 otherwise.
  int caustic_chain = 0;
  // Russian roulette as Cycles does it (path_state_continuation_probability):
  // survive with sqrt of the throughput's largest component, weighted up by
  // its inverse.
  auto survives_roulette = [&]() {
    const float survive = std::min(1.0f, std::sqrt(max_component(beta)));
    if (!(rr_u < survive)) return false;
    beta /= survive;
    return true;
  };

  for (int bounce = 0, vertex = 0;; ++vertex) {
    Hit hit;
    ++counters.rays;
    // Instances hidden from rays of this kind are passed.
    const bool found = scene.intersect(ray, hit, kind);
    const float t_end = found ? hit.t : ray.tmax;

    // Area lights and point/spot lights with a radius are seen by scattered
    // rays and, when made visible to it, by the camera (as in Cycles), and do
    // not block the ray.
    if (bounce > 0 || lights.camera_sees_lights()) {
      float t_light, light_pdf;
      vec3 le;
      int light = lights.intersect_lights(ray.o, ray.d, t_end, &t_light, &le, &light_pdf, prev_p, prev_n, kind);
      if (light >= 0) {
        if (mis_t > 0.0f && !count_emission_fully)
          light_pdf = light_pdf_from_vertex(lights, ray, mis_t, light, t_light, light_pdf, prev_p, prev_n, kind);
        float w = count_emission_fully ? 1.0f : power_heuristic(prev_bsdf_pdf, light_pdf);
        if (camera_le && vertex == 0) *camera_le += clamped(le, options.clamp_direct);
        if (!(caustic_chain == 2 && features.traced_lights && features.traced_lights[light])) add(bounce, beta * le * w);
      }
    }

    if (!found) {
      const bool emits = scene.background.emits() && scene.background.seen_by(kind);
      float world_pdf = 0.0f;
      const vec3 le = emits ? scene.background.Le(ray.d, count_emission_fully ? nullptr : &world_pdf) : vec3(0.0f);
      if (first && !first->complete()) first->miss(le);
      if (options.film_transparent && bounce == 0) {
        // Film > Transparent: the camera sees no world here, the pixel's
        // alpha takes the path's weight (Cycles' film_write_transparent).
        if (transparency) *transparency = average(beta);
        break;
      }
      if (emits) {
        float w = count_emission_fully ? 1.0f : power_heuristic(prev_bsdf_pdf, lights.world_pmf() * world_pdf);
        if (camera_le && vertex == 0) *camera_le += clamped(le, options.clamp_direct);
        add(bounce, beta * le * w);
      }
      // Sun disks, seen by scattered rays only (as area lights are).
      if (bounce > 0 && lights.has_sun_disks())
        add(bounce, beta * lights.sun_disks_seen(ray.d, count_emission_fully ? 0.0f : prev_bsdf_pdf, kind));
      break;
    }

    // Russian roulette (below) first where the hit cannot emit: a path it
    // ends needs nothing more of this hit (the same image, without the
    // interaction and material of hits that end paths).
    if (rr_pending && !scene.materials[scene.material_index(hit)].is_emissive()) {
      rr_pending = false;
      if (!survives_roulette()) break;
    }
    const SurfaceInteraction si = scene.interaction(ray, hit);
    MaterialScratch textured;
    const Material& material = scene.material_at(si, textured, kind_bounces[BSDFSample::kDiffuse] > 0);
    const vec3 le = material.emission(si.back_face);
    if (first && !first->complete()) first->surface(ray, hit.t, si, material, le);
    if (camera_le && vertex == 0) *camera_le += clamped(le, options.clamp_direct);
    if (max_component(le) > 0.0f) {
      float w = 1.0f;
      if (!count_emission_fully) {
        float cos_l = std::abs(glm::dot(ray.d, si.ng));
        w = power_heuristic(prev_bsdf_pdf, lights.pdf_triangle(prev_p, prev_n, ray.d, hit.instance, hit.prim, mis_t + hit.t, cos_l));
      }
      add(bounce, beta * le * w);
    }
    if (rr_pending) {
      rr_pending = false;
      if (!survives_roulette()) break;
    }
    // As Cycles' PATH_RAY_TERMINATE_ON_NEXT_SURFACE after the last transparent bounce.
    if (transparent_bounces > 0 && transparent_bounces >= options.max_transparent_bounces) break;
    if (bounce > options.max_bounces || kind_bounces[0] > kind_limit[0] || kind_bounces[1] > kind_limit[1] ||
        kind_bounces[2] > kind_limit[2]) {
      // Out of bounces: as Cycles' PATH_RAY_TERMINATE_AFTER_TRANSPARENT, the
      // ray still goes on through transparent surfaces (only their
      // transparent closures) to the emitters behind them, as shadow rays
      // do, so that MIS with light sampling stays whole.
      if (!features.transparent || !features.hittable_emitters || !material.may_be_transparent()) break;
      beta *= material.transparency();
      if (!(max_component(beta) > 0.0f)) break;
      ++transparent_bounces;
      mis_t += hit.t;
      const vec3 ng_in = si.back_face ? -si.ng : si.ng;
      ray.o = offset_ray_origin(si.p, si.p_error, ng_in, ray.d);
      if (!std::isinf(ray.tmax)) ray.tmax = std::max(ray.tmax - hit.t, 0.0f);
      continue;
    }

    // Shade on the side the ray arrived from (Blender surfaces are two-sided).
    const vec3 ng = si.back_face ? -si.ng : si.ng;
    const vec3 ns = si.back_face ? -si.ns : si.ns;
    const BSDF bsdf(ns, ng, material, si.back_face, -ray.d);

    // Next-event estimation.
    const vec2 u_light = sampler.get_2d();
    // The lobe choice's number (below), and beside it the light threshold's:
    // one Sobol dimension's two coordinates, drawn in the same order as
    // before (get_1d's number is get_2d's first coordinate).
    const vec2 u_lobe_threshold = sampler.get_2d();
    LightSample ls;
    if (bsdf.has_smooth_lobes() && !lights.empty() && lights.sample(si.p, ns, u_light, ls, bsdf.reflects_only_above())) {
      float bsdf_pdf;
      // Lobes of ray kinds the light is hidden from do not see it.
      const uint8_t excluded = ~ls.visibility & kScatteredRays;
      vec3 f = (excluded ? bsdf.eval(ls.wi, &bsdf_pdf, excluded) : bsdf.eval(ls.wi, &bsdf_pdf)) * bsdf.abs_cos(ls.wi);
      if (max_component(f) > 0.0f) {
        vec3 origin = offset_ray_origin(si.p, si.p_error, ng, ls.wi);
        // Stop just short of the sampled light point, relative to its distance,
        // measured from the offset origin (far from the world origin the offset
        // is not negligible next to the distance).
        float tmax = std::isinf(ls.dist) ? kInf : (ls.dist - glm::dot(origin - si.p, ls.wi)) * (1.0f - 1e-4f);
        // A light with Cast Shadow off is not shadowed.
        const bool shadowed = ls.visibility & kRayShadow;
        const float w = ls.is_delta ? 1.0f : power_heuristic(ls.pdf, bsdf_pdf);
        float weight = w / ls.pdf;
        if (shadowed && light_threshold_survives(f * ls.li, weight, options.light_threshold, u_lobe_threshold.y)) {
          if (!features.transparent) {
            ++counters.rays;
            if (!scene.occluded(origin, ls.wi, tmax)) add(bounce, beta * f * ls.li * weight);
          } else {
            const vec3 tr = shadow_transmittance(scene, origin, ls.wi, tmax,
                                                 options.max_transparent_bounces - transparent_bounces, counters);
            if (max_component(tr) > 0.0f) add(bounce, beta * f * tr * ls.li * weight);
          }
        } else if (!shadowed) {
          add(bounce, beta * f * ls.li * weight);
        }
      }
    }

    // Continue the path by sampling the BSDF.
    BSDFSample bs;
    // The first bounces' directions continue the pixel position's Sobol
    // point (Sampler::get_2d_joint): stratified together with it.
    if (!bsdf.sample_f(u_lobe_threshold.x, sampler.get_2d_joint(), bs)) break;
    if (bs.kind == BSDFSample::kTransparent) {
      // Straight on through the surface: not a bounce, and the MIS state of
      // the last scattering vertex is kept (Cycles' path_state_next for
      // LABEL_TRANSPARENT).
      beta *= bs.f * (bsdf.abs_cos(bs.wi) / bs.pdf);
      ++transparent_bounces;
      mis_t += hit.t;
      if (!features.hittable_emitters && transparent_bounces >= options.max_transparent_bounces) {
        ++counters.skipped_rays;
        break;
      }
      ray.o = offset_ray_origin(si.p, si.p_error, ng, bs.wi);
      if (!std::isinf(ray.tmax)) ray.tmax = std::max(ray.tmax - hit.t, 0.0f);
      continue;
    }
    beta *= bs.f * (bsdf.abs_cos(bs.wi) / bs.pdf);
    if (bounce == 0) caustic_chain = bs.delta ? -1 : 1;
    else if (caustic_chain >= 1) caustic_chain = bs.delta ? 2 : -1;
    if (first) first->scattered();
    prev_bsdf_pdf = bs.pdf;
    prev_p = si.p;
    prev_n = ns;
    count_emission_fully = bs.delta;
    mis_t = 0.0f;
    ++kind_bounces[bs.kind];
    kind = bs.kind == BSDFSample::kDiffuse ? kRayDiffuse : bs.kind == BSDFSample::kGlossy ? kRayGlossy : kRayTransmission;
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

    // Russian roulette as Cycles does it (path_state_continuation_probability,
    // integrator_intersect_terminate): decided at the next surface hit, after
    // its emission is counted, surviving with sqrt of the throughput's
    // largest component. Ending the path before the ray was traced lost the
    // emission found at its end, MIS-weighted direct light: McGuire's Cornell
    // box 64 spp RMSE 0.0785 -> 0.0649 for 18% more rays.
    rr_u = sampler.get_1d();
    rr_pending = bounce + 1 >= options.rr_depth;
    ++bounce;
  }
  if (!is_finite(L)) {
    ++counters.invalid_samples;
    if (camera_le) *camera_le = vec3(0.0f);
    return vec3(0.0f);
  }
  return L;
}

}  // namespace tessera
