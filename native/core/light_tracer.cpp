#include "light_tracer.h"

#include "bsdf.h"
#include "microfacet.h"
#include "sampler.h"

namespace tessera {

namespace {
// A light path's random numbers: a hash chain from (seed, path index), so that
// a path is the same whichever thread traces it.
struct PathRng {
  uint32_t state;
  float next() {
    state = hash_u32(state + 0x9e3779b9U);
    return u32_to_unit_float(state);
  }
  vec2 next_2d() {
    const float a = next();
    return vec2(a, next());
  }
};

// Whether a material can scatter by a delta lobe (microfacet.h's kSmoothAlpha),
// and whether one that can reads a texture's blurred level after a diffuse
// bounce (which the light paths, not knowing the camera path's lobe, could
// not reproduce).
bool may_be_delta(const Closure& c, bool roughness_textured) {
  if (c.kind == ClosureKind::Diffuse || c.kind == ClosureKind::Transparent || !(c.weight > 0.0f)) return false;
  return roughness_textured || c.roughness * c.roughness <= kSmoothAlpha ||
         (c.coat > 0.0f && c.coat_roughness * c.coat_roughness <= kSmoothAlpha);
}

bool blurred(const Scene& scene, const TextureRef& t) {
  return t.valid() && !scene.textures[t.texture].coarse.empty();
}
}  // namespace

LightTracer::LightTracer(const Scene& scene, const RenderOptions& options, const PixelFilter& filter, int x0, int y0,
                         int x1, int y1)
    : scene_(scene), options_(options), filter_(filter), x0_(x0), y0_(y0), x1_(x1), y1_(y1),
      full_w_(scene.camera.width), full_h_(scene.camera.height) {
  const Camera& cam = scene.camera;
  const bool full_frame = x0 == 0 && y0 == 0 && x1 == cam.width && y1 == cam.height;
  const bool kind_limits = options.max_diffuse_bounces >= options.max_bounces &&
                           options.max_glossy_bounces >= options.max_bounces &&
                           options.max_transmission_bounces >= options.max_bounces;
  if (!(options.caustic_light_paths > 0.0f) || cam.type != Camera::Type::Perspective || cam.has_lens() ||
      !full_frame || !kind_limits || options.clamp_direct > 0.0f || options.clamp_indirect > 0.0f ||
      options.max_bounces < 1 || scene_features(scene).transparent || filter.radius() < 0.5f)
    return;
  for (const Instance& inst : scene.instances)
    if (inst.visibility != kVisibleToAll) return;
  bool smooth = false;
  for (const Material& m : scene.materials)
    for (int i = 0; i < m.num_closures(); ++i) {
      if (!may_be_delta(m.closure(i), i == 0 && m.roughness_tex.valid())) continue;
      if (blurred(scene, m.base_color_tex) || blurred(scene, m.metallic_tex) || blurred(scene, m.roughness_tex)) return;
      smooth = true;
    }
  if (!smooth) return;
  const auto& lights = scene.light_sampler().lights();
  std::vector<float> power;
  for (uint32_t i = 0; i < lights.size(); ++i) {
    const Light& l = lights[i];
    if (!(l.type == LightType::Point || l.type == LightType::Spot) || !(l.radius > 0.0f) || l.sphere) continue;
    if (l.visibility != kLightDefaultVisibility) continue;
    float cos_cone = -1.0f;
    if (l.type == LightType::Spot && !l.spot_scaled) cos_cone = std::clamp(l.spot_cos, -1.0f, 1.0f);
    const float p = luminance(l.radiance) * l.radius * l.radius * (1.0f - cos_cone);
    if (!(p > 0.0f) || !std::isfinite(p)) continue;
    lights_.push_back(i);
    cos_cone_.push_back(cos_cone);
    power.push_back(p);
  }
  if (lights_.empty()) return;
  traced_.assign(lights.size(), 0);
  for (uint32_t i : lights_) traced_[i] = 1;
  choice_ = AliasTable(power);
  to_camera_ = glm::inverse(cam.to_world);
  camera_pos_ = vec3(cam.to_world[3]);
  film_area_ = (cam.right - cam.left) * (cam.top - cam.bottom);
}

void LightTracer::trace(uint64_t first, uint64_t count, uint32_t seed, std::vector<Splat>& out,
                        PathCounters& counters) const {
  for (uint64_t j = first; j < first + count; ++j) trace_path(j, seed, out, counters);
}

void LightTracer::trace_path(uint64_t index, uint32_t seed, std::vector<Splat>& out, PathCounters& counters) const {
  PathRng rng{hash_combine(hash_combine(hash_u32(seed ^ 0x5bd1e995U), uint32_t(index)), uint32_t(index >> 32))};
  // A traced light by power.
  float pmf;
  const uint32_t k = choice_.sample(rng.next(), &pmf);
  const Light& l = scene_.light_sampler().lights()[lights_[k]];
  // A ray of the light: a direction u uniform in its cone and a point
  // uniform on the disk of its radius across u, so that rays are uniform in
  // projected area and direction (dA_perp du): the flux along one is L
  // dA_perp du, and the path's weight L pi r^2 / p(u). Traced to its first
  // surface z, it is one of the rays the path tracer's ray from z to the
  // light is (the disk facing z, lights.cpp) when it crosses that disk:
  // others are dropped, so both count the same rays.
  const vec3 axis = l.type == LightType::Spot ? l.direction : vec3(0, 0, 1);
  vec3 t, b;
  make_basis(axis, t, b);
  const vec3 local = sample_uniform_cone(rng.next_2d(), cos_cone_[k]);
  const vec3 u = glm::normalize(local.x * t + local.y * b + local.z * axis);
  const float pdf_u = uniform_cone_pdf(cos_cone_[k]);
  const float atten = l.type == LightType::Spot ? spot_attenuation(l, u) : 1.0f;
  if (!(atten > 0.0f)) return;
  make_basis(u, t, b);
  const vec2 q = sample_uniform_disk_concentric(rng.next_2d()) * l.radius;
  Ray ray{l.position + q.x * t + q.y * b, u, kInf};
  Hit hit;
  ++counters.rays;
  if (!scene_.intersect(ray, hit)) return;
  SurfaceInteraction si = scene_.interaction(ray, hit);
  {
    // The path tracer's test from z (LightSampler::intersect_lights).
    const vec3 to_center = l.position - si.p;
    const float dist_c = glm::length(to_center);
    if (!(dist_c > l.radius)) return;
    const vec3 disk_n = -to_center / dist_c;
    const float denom = glm::dot(-u, disk_n);
    if (!(denom < 0.0f)) return;
    const vec3 on_disk = si.p + (glm::dot(to_center, disk_n) / denom) * -u - l.position;
    if (glm::dot(on_disk, on_disk) > l.radius * l.radius) return;
  }
  vec3 w_light = -u;  // towards the light
  vec3 beta = l.radiance * (atten * kPi * l.radius * l.radius / (pmf * pdf_u));

  // Through delta surfaces: at least one before a connection.
  int deltas = 0;
  for (;;) {
    MaterialScratch textured;
    const bool back_face = glm::dot(-w_light, si.ng) > 0.0f;
    si.back_face = back_face;
    const Material& material = scene_.material_at(si, textured, false);
    if (deltas > 0) connect(beta, si, material, w_light, out, counters);
    if (deltas >= options_.max_bounces) return;
    const vec3 ng = back_face ? -si.ng : si.ng;
    const vec3 ns = back_face ? -si.ns : si.ns;
    const BSDF bsdf(ns, ng, material, back_face, w_light);
    BSDFSample bs;
    const float u_lobe = rng.next();
    if (!bsdf.sample_f(u_lobe, rng.next_2d(), bs) || !bs.delta || bs.kind == BSDFSample::kTransparent) return;
    // Importance transport with shading normals (Veach 1997, 5.3; pbrt-v4 CorrectShadingNormal).
    const float num = std::abs(glm::dot(w_light, ns)) * std::abs(glm::dot(bs.wi, ng));
    const float den = std::abs(glm::dot(w_light, ng)) * std::abs(glm::dot(bs.wi, ns));
    if (!(den > 0.0f)) return;
    beta *= bs.f * (bsdf.abs_cos(bs.wi) / bs.pdf) * (num / den);
    ++deltas;
    ray.o = offset_ray_origin(si.p, si.p_error, ng, bs.wi);
    ray.d = bs.wi;
    ray.tmax = kInf;
    ++counters.rays;
    if (!scene_.intersect(ray, hit)) return;
    si = scene_.interaction(ray, hit);
    w_light = -bs.wi;
  }
}

// The camera sees x directly: the path's light leaving x towards it, weighted
// by the camera's importance (pinhole: We = 1 / (A cos^4), pbrt-v4 5.4) and
// the pixel filter around its raster position.
void LightTracer::connect(const vec3& beta, const SurfaceInteraction& si, const Material& material,
                          const vec3& w_light, std::vector<Splat>& out, PathCounters& counters) const {
  const Camera& cam = scene_.camera;
  const vec3 pc = vec3(to_camera_ * vec4(si.p, 1.0f));
  const float depth = -pc.z;
  if (!(depth > cam.clip_start && depth < cam.clip_end)) return;
  const float xp = pc.x / depth, yp = pc.y / depth;
  const float sx = (xp - cam.left) / (cam.right - cam.left) * float(cam.width);
  const float sy = (yp - cam.bottom) / (cam.top - cam.bottom) * float(cam.height);
  const float r = filter_.radius();
  if (sx < -r || sy < -r || sx > cam.width + r || sy > cam.height + r) return;
  vec3 w_cam = camera_pos_ - si.p;
  const float dist = glm::length(w_cam);
  w_cam /= dist;
  const bool back_face = glm::dot(-w_cam, si.ng) > 0.0f;
  const vec3 ng = back_face ? -si.ng : si.ng;
  const vec3 ns = back_face ? -si.ns : si.ns;
  const BSDF bsdf(ns, ng, material, back_face, w_cam);
  if (!bsdf.has_smooth_lobes()) return;
  float pdf;
  const vec3 f = bsdf.eval(w_light, &pdf);
  if (!(max_component(f) > 0.0f)) return;
  const float cos_l_g = std::abs(glm::dot(w_light, ng));
  if (!(cos_l_g > 0.0f)) return;
  // The camera ray covers the segment beyond the clipping start.
  const float len = dist / depth;
  const vec3 origin = offset_ray_origin(si.p, si.p_error, ng, w_cam);
  const float tmax = (dist - cam.clip_start * len - glm::dot(origin - si.p, w_cam)) * (1.0f - 1e-4f);
  ++counters.rays;
  if (tmax > 0.0f && scene_.occluded(origin, w_cam, tmax)) return;
  const float cos_cam = depth / dist;
  const float we = 1.0f / (film_area_ * cos_cam * cos_cam * cos_cam * cos_cam);
  const vec3 c = beta * f * (bsdf.abs_cos(w_light) / cos_l_g) * std::abs(glm::dot(ng, w_cam)) * (we * cos_cam / (dist * dist));
  if (!is_finite(c)) return;
  out.push_back({vec2(sx, sy), c});
}

// The pixel filter as camera rays sample it (PixelFilter::density): pixel
// (px, py), centre (px + 0.5, py + 0.5), takes the splat with the filter's
// density at the offset.
void LightTracer::splat(const Splat& s, std::vector<vec3>& image, int y_begin, int y_end) const {
  const float r = filter_.radius();
  const int w = x1_ - x0_;
  const int py_end = std::min(std::min(y1_, y_end), int(std::ceil(s.raster.y - 0.5f + r)) + 1);
  for (int py = std::max(std::max(y0_, y_begin), int(std::floor(s.raster.y - 0.5f - r))); py < py_end; ++py) {
    const float fy = filter_.density(s.raster.y - (py + 0.5f));
    if (!(fy > 0.0f)) continue;
    for (int px = std::max(x0_, int(std::floor(s.raster.x - 0.5f - r))); px <= int(std::ceil(s.raster.x - 0.5f + r)) && px < x1_; ++px) {
      const float fx = filter_.density(s.raster.x - (px + 0.5f));
      if (fx > 0.0f) image[size_t(py - y0_) * w + (px - x0_)] += s.value * (fx * fy);
    }
  }
}

}  // namespace tessera
