#include "lights.h"

#include "background.h"

namespace tessera {

namespace {

// Whether the receiver has a normal for the rectangles' cosine warp.
bool has_normal(const vec3& n) { return glm::dot(n, n) > 0.0f; }

// Cosine of the angle between the direction w (unit, from the light) and the
// spot's axis: in the light object's own space in Cycles 4.x (elliptical
// cones under non-uniform scale), around `direction` otherwise.
float spot_cos_to_axis(const Light& l, const vec3& w) {
  if (!l.spot_scaled) return glm::dot(w, l.direction);
  const vec3 local = l.spot_to_local * w;
  const float len = glm::length(local);
  return len > 0.0f ? -local.z / len : 0.0f;
}

// Cosine of the widest half angle of a spot's cone about `direction`: its
// own under no or uniform scale, else that of the longer of the scaled x and
// y axes (Cycles' cos_half_larger_spread), for the light BVH's bounds.
float spot_bounding_cos(const Light& l) {
  if (!l.spot_scaled || l.spot_cos <= 0.0f) return l.spot_cos;
  const glm::mat3 m = glm::inverse(l.spot_to_local);  // columns: the object's scaled axes
  const float lx2 = glm::dot(m[0], m[0]), ly2 = glm::dot(m[1], m[1]), lz2 = glm::dot(m[2], m[2]);
  const float tan2 = (1.0f - l.spot_cos * l.spot_cos) / (l.spot_cos * l.spot_cos);
  const float c = 1.0f / std::sqrt(1.0f + tan2 * std::max(lx2, ly2) / lz2);
  return std::isfinite(c) ? std::min(c, l.spot_cos) : -1.0f;
}

// 1 - cos of the half angle whose sine squared is s2, without cancellation
// for small angles (Cycles' sin_sqr_to_one_minus_cos).
float sin2_to_one_minus_cos(float s2) { return s2 / (1.0f + safe_sqrt(1.0f - s2)); }

// A sphere light of centre c and radius r seen from p: outside it, the cone
// the sphere subtends; inside, every direction. Returns the solid-angle
// density of sample_sphere_light's directions (1 / the cone's solid angle,
// or uniform over the sphere of directions inside) and whether p is outside.
float sphere_light_pdf(const vec3& c, float r, const vec3& p, bool* outside) {
  const vec3 pc = c - p;
  const float d2 = glm::dot(pc, pc), r2 = r * r;
  *outside = d2 > r2;
  if (!*outside) return kUniformSpherePdf;
  return 1.0f / (2.0f * kPi * sin2_to_one_minus_cos(r2 / d2));
}

// A direction towards the sphere light (uniform in the cone it subtends, or
// over all directions from inside it) and the distance to its surface along
// it (law of cosines, as Cycles' point_light_sample).
bool sample_sphere_light(const vec3& c, float r, const vec3& p, vec2 u, vec3* wi, float* t, float* pdf,
                         bool* outside) {
  const vec3 pc = c - p;
  const float d2 = glm::dot(pc, pc), r2 = r * r;
  const float d = std::sqrt(d2);
  if (!(d > 0.0f)) return false;
  const vec3 axis = pc / d;
  *pdf = sphere_light_pdf(c, r, p, outside);
  if (*outside) {
    const float one_minus_cos_max = sin2_to_one_minus_cos(r2 / d2);
    const float x = u.x * one_minus_cos_max;  // 1 - cos(theta)
    const float cos_t = 1.0f - x, sin2_t = x * (2.0f - x);
    const float sin_t = safe_sqrt(sin2_t), phi = 2.0f * kPi * u.y;
    const Frame f(axis);
    *wi = glm::normalize(f.to_world(vec3(sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t)));
    *t = d * cos_t - safe_sqrt(r2 - d2 * sin2_t);  // nearer intersection
  } else {
    *wi = sample_uniform_sphere(u);
    const float cos_t = glm::dot(*wi, axis);
    *t = d * cos_t + safe_sqrt(r2 - d2 * (1.0f - cos_t * cos_t));  // the way out
  }
  return *t > 0.0f && std::isfinite(*t);
}

// Distance along the unit direction d from o to the sphere (c, r): the
// nearer intersection ahead, the way out from inside; false if none before
// tmax (Ray Tracing Gems, ch. 7: the discriminant from the closest approach).
bool intersect_sphere(const vec3& o, const vec3& d, const vec3& c, float r, float tmax, float* t) {
  const vec3 oc = o - c;
  const float b = glm::dot(oc, d);
  const vec3 closest = oc - b * d;
  const float disc = r * r - glm::dot(closest, closest);
  if (disc < 0.0f) return false;
  const float q = -b - std::copysign(std::sqrt(disc), b);
  const float cc = glm::dot(oc, oc) - r * r;
  float t0 = q != 0.0f ? cc / q : 0.0f, t1 = q;
  if (t0 > t1) std::swap(t0, t1);
  const float th = t0 > 0.0f ? t0 : t1;
  if (!(th > 0.0f && th < tmax)) return false;
  *t = th;
  return true;
}

// Bound on the rounding error, along the ray, of both ends of a shadow ray
// from p to a point q on geometry, both in world space: p's offset origin
// and the ray's transform into an instance's space (gamma(3) of the world
// magnitudes each, with a factor 2 for the translation), and q's error.
float shadow_end_error(const vec3& p, const vec3& q) {
  return gamma(8) * (max_component(abs(p)) + max_component(abs(q))) * 2.0f;
}

// How sample() samples an emissive triangle from the shading point p:
// uniformly in solid angle (Arvo 1995, sample_spherical_triangle) when p is
// close to it, else uniformly by area, at about a quarter of the cost. A
// large triangle close to p (a quad light just below a ceiling) is where
// area sampling's 1/d^2 weights made fireflies, which Russian roulette then
// multiplied (McGuire's Cornell box, the ceiling above its light). Area
// sampling is kept where it is nearly as good:
// - the solid angle bound is below kMinSphericalSampleArea (pbrt-v4
//   Triangle::Sample's bound): seen that small, the area density is nearly
//   constant in solid angle;
// - p is at least kSolidAngleWithin bounding-sphere radii r from the
//   sphere (distance d): the light's points then lie between d and d + 2r
//   away, so the 1/distance^2 in the weights varies by at most
//   (1 + 2r / d)^2 <= 4 over it. Cycles samples by area from as close as
//   its longest edge to its plane (triangle_light_sample); this is farther.
//   Solid-angle sampling (with its atan and sincos) was 11% of McGuire's
//   box's and the Mitsuba box's render time, and is 3% with this rule
//   (perf, 160 px, 64 spp); their noise at 64 spp did not change
//   (scripts/noise_at_equal_samples.py, 3 seeds).
// - a rectangle (two triangles joined, sampled by Urena et al.'s spherical
//   rectangle, whose set-up and sample cost more than Arvo's: 12% of
//   modern_hall.blend's render) is also sampled by area inside that region
//   when p lies outside its bounding sphere and sees it from above rather
//   than at a grazing angle (height over the plane more than
//   sqrt(kRectangleGrazing2) = half its distance from the middle). Above a
//   light the distances to its points vary little; beside it, near its
//   plane, the cosine at the light joins the 1/d^2 and area weights spread
//   (a relative deviation of 1.4 per sample 0.3 beside a 1 x 1 light's edge,
//   test LightSampling.LightSamplingSwitchesToAreaWithBoundedWeights, had
//   the sphere alone been the rule). Against the rule for triangles,
//   per-pixel variance at 64 spp (120 px, 8 seeds, three seed sets):
//   modern_hall +1.5-1.6% for 7-11% less render time (1 / (variance x time)
//   +5-10%); cornell_mcguire and cbox_mitsuba within noise (+0.0%, +1.1%
//   variance; time -2 to +2%, -2 to -3%). The sphere alone: modern_hall
//   +9-14%, cornell_mcguire and cbox_mitsuba +4%; solid angle only within
//   half a radius of the middle, or never: variance +7%.
constexpr float kMinSphericalSampleArea = 3e-4f;
constexpr float kSolidAngleWithin = 2.0f;
constexpr float kRectangleGrazing2 = 0.25f;

// Sets t's centre and the squared distance from it beyond which sample()
// samples t by area: its bounding sphere (centre, radius r) is then d > 0 away with
// area < kMinSphericalSampleArea d^2 or d >= kSolidAngleWithin r, i.e. from
// r + min(sqrt(area / kMinSphericalSampleArea), kSolidAngleWithin r) on. A
// rectangle's sphere is about its middle, through its corners. And the
// size's part of in_emitter_plane's tolerance, so that no light sample takes
// a square root for it.
void set_area_from(EmissiveTriangle& t) {
  float r2;
  if (t.rectangle()) {
    t.centre = t.p0 + 0.5f * (t.e1 + t.e2);
    r2 = 0.25f * glm::dot(t.e1 + t.e2, t.e1 + t.e2);
  } else {
    const vec3 v1 = t.p0 + t.e1, v2 = t.p0 + t.e2;
    t.centre = t.p0 + (t.e1 + t.e2) * (1.0f / 3.0f);
    r2 = std::max(glm::dot(t.p0 - t.centre, t.p0 - t.centre),
                  std::max(glm::dot(v1 - t.centre, v1 - t.centre), glm::dot(v2 - t.centre, v2 - t.centre)));
  }
  const float r = std::sqrt(r2);
  const float d = r + std::min(std::sqrt(t.area / kMinSphericalSampleArea), kSolidAngleWithin * r);
  t.area_from2 = d * d;
  t.plane_tolerance = 1e-5f * std::sqrt(t.rectangle() ? 0.5f * t.area : t.area);
}

// A point in the emitter's plane (on the emitter itself, or on its other
// triangles) receives nothing from it; its corners then lie on one great
// circle and the solid angle is 0 or 2 pi by rounding. Close to the emitter
// (where the sampling functions below look) sample() gives it no sample: a
// point on a quad light, in McGuire's box's 1 cm gap above it or seen from
// the room, traced a shadow ray for a cosine of ~1e-7; pdf_triangle() gives
// it density 0. Returns its distance h from the plane. (The tolerance scales
// with a triangle's area: a rectangle's half.)
bool in_emitter_plane(const EmissiveTriangle& t, const vec3& p, float* h) {
  *h = std::abs(glm::dot(p - t.p0, t.n));
  return *h <= t.plane_tolerance + 1e-6f * (max_component(abs(p)) + max_component(abs(t.p0)));
}

// Solid angle of triangle t from p when sample() samples it by solid angle,
// with its corners as unit vectors from p; 0 when it samples it by area; -1
// when p is in its plane close by (no sample, density 0). sample() and
// pdf_triangle() decide with this one function. near_plane (if
// given): p is within 1% of its distance to the corners from the
// triangle's plane, where sample_spherical_triangle needs double precision.
float spherical_sampling_area(const EmissiveTriangle& t, const vec3& p, vec3 corners[3], bool* near_plane = nullptr) {
  const vec3 to_centre = p - t.centre;
  if (glm::dot(to_centre, to_centre) > t.area_from2) return 0.0f;
  float h;
  if (in_emitter_plane(t, p, &h)) return -1.0f;
  const vec3 a = t.p0 - p, b = a + t.e1, c = a + t.e2;
  const float la = glm::length(a), lb = glm::length(b), lc = glm::length(c);
  if (!(la > 0.0f && lb > 0.0f && lc > 0.0f)) return 0.0f;
  corners[0] = a * (1.0f / la), corners[1] = b * (1.0f / lb), corners[2] = c * (1.0f / lc);
  if (near_plane) *near_plane = h < 0.01f * std::max(la, std::max(lb, lc));
  const float omega = spherical_triangle_area(corners[0], corners[1], corners[2]);
  return omega >= kMinSphericalSampleArea && std::isfinite(omega) ? omega : 0.0f;
}

// The same decision as spherical_sampling_area for a rectangle emitter,
// with its spherical rectangle from p.
// The plane comes first here, before the distance: points of the light's
// plane beyond the solid-angle region (the ceiling around a light set into
// it) get no area sample with a cosine of 1e-7 either.
float rectangle_sampling_area(const EmissiveTriangle& t, const vec3& p, SphericalRectangle* rect) {
  float h;
  if (in_emitter_plane(t, p, &h)) return -1.0f;
  const vec3 to_centre = p - t.centre;
  const float dist2 = glm::dot(to_centre, to_centre);
  if (dist2 > t.area_from2) return 0.0f;
  // Outside the bounding sphere and seen from above rather than at a grazing angle: by area.
  const vec3 diagonal = t.e1 + t.e2;
  const float radius2 = 0.25f * glm::dot(diagonal, diagonal);
  if (dist2 > radius2 && h * h > kRectangleGrazing2 * dist2) return 0.0f;
  if (!rect->init(p, t.p0, t.e1, t.e2, h, std::sqrt(dist2) + std::sqrt(radius2))) return 0.0f;
  const float omega = rect->solid_angle();
  return omega >= kMinSphericalSampleArea && std::isfinite(omega) ? omega : 0.0f;
}

// How sample() samples emitter t from p, and how pdf_triangle() recomputes
// it: the solid angle it samples uniformly (> 0; with the spherical rectangle
// or the triangle's corners set up), 0 for by area, -1 for nothing (p in its
// plane).
struct EmitterSampling {
  SphericalRectangle rect;
  vec3 corners[3];
  bool near_plane = true;
  float omega = 0.0f;
  EmitterSampling(const EmissiveTriangle& t, const vec3& p)
      : omega(t.rectangle() ? rectangle_sampling_area(t, p, &rect) : spherical_sampling_area(t, p, corners, &near_plane)) {}
};

// Whether the point q of area light l's plane lies on the light.
bool on_area_light(const Light& l, const vec3& q) {
  const vec3 d = q - l.position;
  const float a = glm::dot(d, l.axis_u) / glm::dot(l.axis_u, l.axis_u);
  const float b = glm::dot(d, l.axis_v) / glm::dot(l.axis_v, l.axis_v);
  return l.ellipse ? a * a + b * b <= 1.0f : (std::abs(a) <= 1.0f && std::abs(b) <= 1.0f);
}

// Cycles' soft-box Spread (area_light_spread_attenuation): the factor on
// the radiance of area light l towards the direction w (unit, from the
// shading point to the light), from the angle a between -w and the light's
// normal. tan a from the cross product: 1 - cos^2 near the normal would
// cost half the digits, which narrow spreads need.
float spread_attenuation(const Light& l, const vec3& w) {
  if (!std::isfinite(l.spread_tan)) return 1.0f;
  const float cos_a = -glm::dot(w, l.direction);
  if (!(cos_a > 0.0f)) return 0.0f;
  const float tan_a = glm::length(glm::cross(w, l.direction)) / cos_a;
  return std::max((l.spread_tan - tan_a) * l.spread_norm, 0.0f);
}

// The part of area light l that sample() samples from p, and how; pdf_area()
// decides with the same function, so that the densities agree. Without
// spread: the whole rectangle, uniformly in the solid angle it subtends
// (Urena et al. 2013, as Cycles) when that is at least
// kMinSphericalSampleArea, else by area (close to a large rectangle, area
// sampling's 1/d^2 weights were fireflies), or the whole ellipse by area.
// With spread, only the disk of radius h tan(half spread) about p's foot on
// the light's plane (h: p's height above it) emits towards p, as Cycles'
// area_light_spread_clamp_light uses: a rectangle is clipped to the disk's
// bounding square (then sampled as above); an ellipse is replaced by the
// smallest of: itself, the disk (by area) and the disk's bounding square
// clipped to the ellipse's bounding rectangle (as a rectangle above), a
// sampled point off the ellipse being no sample (zero radiance). Cycles 4.x
// picks among the same kinds of regions for ellipses (by area only).
struct AreaRegion {
  enum Kind { Rectangle, Ellipse, SpreadDisk } kind = Rectangle;
  vec3 centre{0.0f};         // of the rectangle, ellipse or disk
  vec3 eu{0.0f}, ev{0.0f};   // its half-extent vectors (the disk: radius x an in-plane frame)
  float area = 0.0f;
  bool by_solid_angle = false;
  bool may_miss = false;     // covers more than the light: points off it are no sample
  SphericalRectangle rect;
};

// False when no part of l emits towards p (p behind it, in its plane, or
// outside its spread).
bool area_region(const Light& l, const vec3& p, AreaRegion* r) {
  const float h = glm::dot(p - l.position, l.direction);
  if (!(h > 0.0f)) return false;
  r->kind = l.ellipse ? AreaRegion::Ellipse : AreaRegion::Rectangle;
  r->centre = l.position;
  r->eu = l.axis_u;
  r->ev = l.axis_v;
  r->area = l.area;
  if (std::isfinite(l.spread_tan)) {
    const float radius = h * l.spread_tan;
    const vec3 foot = p - h * l.direction;
    const float lu = glm::length(l.axis_u), lv = glm::length(l.axis_v);
    if (!(lu > 0.0f && lv > 0.0f && radius > 0.0f)) return false;
    const vec3 du = l.axis_u / lu, dv = l.axis_v / lv;
    const float cu = glm::dot(foot - l.position, du), cv = glm::dot(foot - l.position, dv);
    // The disk's bounding square clipped to the light's (bounding) rectangle.
    const float u0 = std::max(cu - radius, -lu), u1 = std::min(cu + radius, lu);
    const float v0 = std::max(cv - radius, -lv), v1 = std::min(cv + radius, lv);
    if (!(u0 < u1 && v0 < v1)) return false;
    const float clipped_area = (u1 - u0) * (v1 - v0), disk_area = kPi * radius * radius;
    if (!l.ellipse || clipped_area < std::min(disk_area, l.area)) {
      r->kind = AreaRegion::Rectangle;
      r->centre = l.position + (0.5f * (u0 + u1)) * du + (0.5f * (v0 + v1)) * dv;
      r->eu = (0.5f * (u1 - u0)) * du;
      r->ev = (0.5f * (v1 - v0)) * dv;
      r->area = clipped_area;
      r->may_miss = l.ellipse;
    } else if (disk_area < l.area) {
      const Frame f(l.direction);
      r->kind = AreaRegion::SpreadDisk;
      r->centre = foot;
      r->eu = radius * f.t;
      r->ev = radius * f.b;
      r->area = disk_area;
      r->may_miss = true;
    }
  }
  if (!(r->area > 0.0f)) return false;
  r->by_solid_angle = false;
  if (r->kind == AreaRegion::Rectangle) {
    const float to_middle = glm::length(p - r->centre), radius = glm::length(r->eu + r->ev);
    const float d = to_middle - radius;
    if (!(d > 0.0f && r->area < kMinSphericalSampleArea * d * d) &&
        r->rect.init(p, r->centre - r->eu - r->ev, 2.0f * r->eu, 2.0f * r->ev, h, to_middle + radius))
      r->by_solid_angle = r->rect.solid_angle() >= kMinSphericalSampleArea;
  }
  return true;
}

float light_power(const Light& l, float scene_radius) {
  float lum = luminance(l.radiance);
  switch (l.type) {
    case LightType::Point:
    case LightType::Spot:
      return l.radius > 0.0f ? lum * 4.0f * kPi * kPi * l.radius * l.radius : lum * 4.0f * kPi;
    case LightType::Sun: {
      float e = l.radius > 0.0f ? lum * kPi * l.radius * l.radius : lum;
      return e * kPi * scene_radius * scene_radius;
    }
    case LightType::Area:
      return lum * kPi * l.area;
    default:
      return 0.0f;
  }
}

}  // namespace

// Smooth edge of a spot light, as Cycles' spot_light_attenuation: cut at
// the cone and smoothstepped over the blend, times the cosine to the axis
// in Cycles 3.x (spot_cosine), without it in 4.0+. dir_from_light: from the
// point on the light towards the shading point (Cycles' -ls->D).
float spot_attenuation(const Light& l, const vec3& dir_from_light) {
  const float c = spot_cos_to_axis(l, dir_from_light);
  if (c <= l.spot_cos) return 0.0f;
  float a = l.spot_cosine ? c : 1.0f;
  const float t = c - l.spot_cos;
  if (l.spot_smooth > 0.0f && t < l.spot_smooth) {
    const float x = t / l.spot_smooth;
    a *= x * x * (3.0f - 2.0f * x);
  }
  return a;
}

void LightSampler::build(std::vector<Light> lights, std::vector<EmissiveTriangle> triangles, const Background* world,
                         float scene_radius) {
  lights_ = std::move(lights);
  triangles_ = std::move(triangles);
  // The world is sampled only where it varies over directions (an
  // environment image), as Cycles enables its background light only for a
  // spatially varying world shader (LightManager::test_enabled_lights). A
  // constant world is found by the BSDF alone, with MIS weight 1: for
  // cosine sampling under a uniform sky that is the better estimator, and
  // the light samples it took went to it instead of the lights (a 64 px
  // test scene under a constant sky: 1.18-1.32x Cycles' variance per sample,
  // 0.81-0.89x after).
  // A world hidden from every scattered ray lights nothing.
  world_ = (world && world->emits() && world->has_image() && (world->visibility() & kScatteredRays)) ? world : nullptr;
  hittable_lights_.clear();
  camera_sees_lights_ = false;
  // Bounds of every bounded emitter for the BVH, with the same power
  // estimates the first step weighs the BVH, the world and suns with.
  std::vector<LightBounds> bounds(lights_.size() + triangles_.size());
  std::vector<float> top_weights;
  top_entries_.clear();
  double bvh_power = 0.0;
  for (uint32_t i = 0; i < lights_.size(); ++i) {
    const Light& l = lights_[i];
    const float power = light_power(l, scene_radius);
    if (l.type == LightType::Area || ((l.type == LightType::Point || l.type == LightType::Spot) && l.radius > 0.0f)) {
      hittable_lights_.push_back(i);
      camera_sees_lights_ = camera_sees_lights_ || (l.visibility & kRayCamera);
    }
    if (l.type == LightType::Sun) {
      top_entries_.push_back(i);
      top_weights.push_back(power);
      continue;
    }
    LightBounds& b = bounds[i];
    b.phi = power;
    if (l.type == LightType::Area) {
      // One-sided, emitting into the hemisphere around its direction.
      for (float su : {-1.0f, 1.0f})
        for (float sv : {-1.0f, 1.0f}) b.bounds.grow(l.position + su * l.axis_u + sv * l.axis_v);
      b.w = l.direction;
      b.cos_theta_o = 1.0f;
      b.cos_theta_e = 0.0f;
    } else {
      b.bounds.grow(l.position - vec3(l.radius));
      b.bounds.grow(l.position + vec3(l.radius));
      if (l.type == LightType::Spot) {
        // Emits within the cone only.
        b.w = l.direction;
        b.cos_theta_o = spot_bounding_cos(l);
        b.cos_theta_e = std::cos(1e-3f);
      } else {
        b.cos_theta_o = -1.0f;  // every direction
        b.cos_theta_e = 0.0f;
      }
    }
    bvh_power += power;
  }
  const uint32_t nl = uint32_t(lights_.size());
  for (uint32_t k = 0; k < triangles_.size(); ++k) {
    const EmissiveTriangle& t = triangles_[k];
    LightBounds& b = bounds[nl + k];
    const float front = luminance(t.le_front), back = luminance(t.le_back);
    b.phi = kPi * t.area * (front + back);
    b.bounds.grow(t.p0);
    b.bounds.grow(t.p0 + t.e1);
    b.bounds.grow(t.p0 + t.e2);
    if (t.rectangle()) b.bounds.grow(t.p0 + t.e1 + t.e2);
    b.w = front > 0.0f ? t.n : -t.n;
    b.two_sided = front > 0.0f && back > 0.0f;
    b.cos_theta_o = 1.0f;
    b.cos_theta_e = 0.0f;
    bvh_power += b.phi;
  }
  bvh_.build(bounds);
  for (EmissiveTriangle& t : triangles_) set_area_from(t);
  if (!bvh_.empty()) {
    top_entries_.push_back(kTopBVH);
    top_weights.push_back(float(bvh_power));
  }
  if (world_) {
    top_entries_.push_back(kTopWorld);
    top_weights.push_back(kPi * 4.0f * kPi * scene_radius * scene_radius * world_->average_luminance());
  }
  top_ = top_weights.empty() ? AliasTable{} : AliasTable(top_weights);
  top_bvh_pmf_ = top_world_pmf_ = 0.0f;
  sun_disks_.clear();
  for (uint32_t i = 0; i < top_entries_.size(); ++i) {
    if (top_entries_[i] == kTopBVH) top_bvh_pmf_ = top_.pmf(i);
    else if (top_entries_[i] == kTopWorld) top_world_pmf_ = top_.pmf(i);
    else if (lights_[top_entries_[i]].radius > 0.0f) sun_disks_.push_back({top_entries_[i], top_.pmf(i)});
  }
  // Lookup from a hit (instance, prim) to its emitter: a rectangle's two
  // triangles both lead to it.
  std::vector<std::pair<uint64_t, uint32_t>> keyed;
  keyed.reserve(triangles_.size() * 2);
  for (uint32_t i = 0; i < triangles_.size(); ++i) {
    const EmissiveTriangle& t = triangles_[i];
    keyed.push_back({(uint64_t(t.instance) << 32) | t.prim, i});
    if (t.rectangle()) keyed.push_back({(uint64_t(t.instance) << 32) | t.second, i});
  }
  std::sort(keyed.begin(), keyed.end());
  triangle_keys_.resize(keyed.size());
  triangle_order_.resize(keyed.size());
  for (size_t i = 0; i < keyed.size(); ++i) triangle_keys_[i] = keyed[i].first, triangle_order_[i] = keyed[i].second;
}

float LightSampler::selection_pmf(uint32_t entry, const vec3& p, const vec3& n) const {
  return top_bvh_pmf_ > 0.0f ? top_bvh_pmf_ * bvh_.pmf(p, n, entry) : 0.0f;
}

bool LightSampler::sample(const vec3& p, const vec3& n, vec2 u, LightSample& ls, const vec3* above) const {
  if (top_.empty()) return false;
  float pmf = 1.0f, u_rest = u.x;  // one top entry: taken with probability 1
  const uint32_t top = top_entries_.size() > 1 ? top_entries_[top_.sample(u.x, &pmf, &u_rest)] : top_entries_[0];
  if (pmf <= 0.0f) return false;
  uint32_t entry = top;
  if (top == kTopBVH) {
    float bvh_pmf;
    if (!bvh_.sample(p, n, u_rest, &entry, &bvh_pmf, &u_rest)) return false;
    pmf *= bvh_pmf;
  }
  return sample_entry(entry, pmf, p, n, vec2(u_rest, u.y), ls, above);
}

bool LightSampler::sample_entry(uint32_t entry, float pmf, const vec3& p, const vec3& n, vec2 u, LightSample& ls,
                                const vec3* above) const {
  const uint32_t nl = uint32_t(lights_.size());
  if (entry == kTopWorld) {
    float pdf;
    if (!world_->sample(u, &ls.wi, &pdf, &ls.li)) return false;
    ls.dist = kInf;
    ls.pdf = pdf * pmf;
    ls.is_delta = false;
    ls.visibility = world_->visibility() | kRayShadow;
    return ls.pdf > 0.0f;
  }
  if (entry >= nl) {
    const EmissiveTriangle& t = triangles_[entry - nl];
    // Wholly behind a receiver that only reflects: nothing to set up (the
    // light BVH's importance takes the receiver as two-sided; 30% of
    // modern_hall.blend's light samples ended here, f = 0).
    if (above) {
      const vec3 a = t.p0 - p;
      const float da = glm::dot(a, *above), d1 = glm::dot(t.e1, *above), d2 = glm::dot(t.e2, *above);
      if (da <= 0.0f && da + d1 <= 0.0f && da + d2 <= 0.0f && (!t.rectangle() || da + d1 + d2 <= 0.0f)) return false;
    }
    // Uniformly in the solid angle the emitter subtends (omega > 0), or by area.
    EmitterSampling how(t, p);
    const float omega = how.omega;
    if (omega < 0.0f) return false;  // in its plane
    vec3 q;
    float dist2, density = 1.0f;  // the rectangle's cosine warp's
    if (omega > 0.0f && t.rectangle()) {
      if (has_normal(n)) how.rect.warp_by_cosine(n);
      const vec3 w = how.rect.sample_offset(u, &density);  // from p to the point
      dist2 = glm::dot(w, w);
      if (!(dist2 > 0.0f)) return false;
      ls.dist = std::sqrt(dist2);
      ls.wi = w / ls.dist;
      q = p + w;
    } else if (omega > 0.0f) {
      vec3 w;
      const vec3* c = how.corners;
      if (!sample_spherical_triangle(c[0], c[1], c[2], omega, u, &w, how.near_plane)) return false;
      // Where the sampled direction meets the triangle's plane.
      const float denom = glm::dot(w, t.n);
      const float s = denom != 0.0f ? glm::dot(t.p0 - p, t.n) / denom : 0.0f;
      if (!(s > 0.0f && std::isfinite(s))) return false;
      q = p + s * w;
      ls.wi = w;
      ls.dist = s;
      dist2 = s * s;
    } else {
      const vec2 b = t.rectangle() ? u : sample_uniform_triangle(u);
      q = t.p0 + b.x * t.e1 + b.y * t.e2;
      const vec3 d = q - p;
      dist2 = glm::dot(d, d);
      if (dist2 <= 0.0f) return false;
      ls.dist = std::sqrt(dist2);
      ls.wi = d / ls.dist;
    }
    // The emitter is geometry: a shadow ray that reaches it is blocked by it.
    // Stop short of it by a bound on the rounding of both ends: q here, the
    // triangle as the BVH tests it (in its instance's space), and the shading
    // point's offset origin (pbrt-v4 SpawnRayTo offsets both ends). Without it,
    // far from the origin (1e3 and beyond) every shadow ray hit its own light.
    // The bound is on where the emitter's plane lies, across it; along a ray
    // that meets the plane at cosine cos_l it is 1 / |cos_l| as long. Taken
    // along the ray as it is, a grazing ray met its own light first: a tilted
    // ceiling 1 cm above a light panel lost nearly all of the panel's light
    // beside it, and McGuire's box traced in its object space 0.2% of its
    // image (test ShadowRaysToAPanelUnderACeilingDoNotHitThePanel).
    float cos_l = -glm::dot(ls.wi, t.n);  // > 0: we see the front face
    if (cos_l == 0.0f) return false;
    const float stop_short = (shadow_end_error(p, q) + t.local_error) / std::abs(cos_l);
    if (!(stop_short < ls.dist)) return false;  // too grazing to tell the light from its plane
    ls.dist -= stop_short;
    ls.li = cos_l > 0.0f ? t.le_front : t.le_back;
    ls.pdf = omega > 0.0f ? pmf * density / omega : pmf * dist2 / (std::abs(cos_l) * t.area);
    ls.is_delta = false;
    ls.visibility = t.visibility | kRayShadow;  // the object's own Shadow flag is about blocking
    return max_component(ls.li) > 0.0f;
  }
  const Light& l = lights_[entry];
  ls.is_delta = false;
  ls.visibility = l.visibility;
  switch (l.type) {
    case LightType::Point:
    case LightType::Spot: {
      const bool spot = l.type == LightType::Spot;
      vec3 to_center = l.position - p;
      float d2 = glm::dot(to_center, to_center);
      if (d2 <= 0.0f) return false;
      float d = std::sqrt(d2);
      vec3 dir = to_center / d;
      if (l.radius <= 0.0f) {
        const float atten = spot ? spot_attenuation(l, -dir) : 1.0f;
        if (atten <= 0.0f) return false;
        ls.wi = dir;
        ls.dist = d;
        ls.li = l.radiance * atten / d2;
        ls.pdf = pmf;
        ls.is_delta = true;
        return true;
      }
      if (l.sphere) {
        // Cycles 4.x's sphere light; a spot's cone applies outside it only.
        float t, pdf;
        bool outside;
        if (!sample_sphere_light(l.position, l.radius, p, u, &ls.wi, &t, &pdf, &outside)) return false;
        const float atten = spot && outside ? spot_attenuation(l, -ls.wi) : 1.0f;
        if (atten <= 0.0f) return false;
        ls.dist = t;
        ls.li = l.radiance * atten;
        ls.pdf = pmf * pdf;
        return true;
      }
      // The disk of the radius facing p (Cycles 3.x; 4.x with Soft Falloff).
      Frame f(-dir);
      vec2 disk = l.radius * sample_uniform_disk_concentric(u);
      vec3 q = l.position + f.t * disk.x + f.b * disk.y;
      vec3 w = q - p;
      float dist2 = glm::dot(w, w);
      ls.dist = std::sqrt(dist2);
      ls.wi = w / ls.dist;
      float cos_l = std::abs(glm::dot(ls.wi, f.n));
      if (cos_l <= 0.0f) return false;
      // The cone is measured from the sampled point, as Cycles does.
      const float atten = spot ? spot_attenuation(l, -ls.wi) : 1.0f;
      if (atten <= 0.0f) return false;
      ls.li = l.radiance * atten;
      ls.pdf = pmf * dist2 / (cos_l * kPi * l.radius * l.radius);
      return true;
    }
    case LightType::Sun: {
      if (l.radius <= 0.0f) {
        ls.wi = -l.direction;
        ls.dist = kInf;
        ls.li = l.radiance;
        ls.pdf = pmf;
        ls.is_delta = true;
        return true;
      }
      // Point on a disk of radius tan(half angle) one unit away (Cycles).
      Frame f(-l.direction);
      vec2 disk = l.radius * sample_uniform_disk_concentric(u);
      vec3 w = f.n + f.t * disk.x + f.b * disk.y;
      float len2 = glm::dot(w, w);
      float len = std::sqrt(len2);
      ls.wi = w / len;
      ls.dist = kInf;
      ls.li = l.radiance;
      ls.pdf = pmf * len2 * len / (kPi * l.radius * l.radius);
      // Escaping rays see the disk too (sun_disks_seen): MIS-weighted.
      ls.is_delta = false;
      return true;
    }
    case LightType::Area: {
      // Wholly behind a receiver that only reflects (its bounding rectangle,
      // position +- axis_u +- axis_v): as for emissive triangles above.
      if (above) {
        const float dc = glm::dot(l.position - p, *above);
        if (dc + std::abs(glm::dot(l.axis_u, *above)) + std::abs(glm::dot(l.axis_v, *above)) <= 0.0f) return false;
      }
      AreaRegion r;
      if (!area_region(l, p, &r)) return false;
      vec3 q;
      float density = 1.0f;  // the rectangle's cosine warp's
      if (r.by_solid_angle) {
        if (has_normal(n)) r.rect.warp_by_cosine(n);
        q = p + r.rect.sample_offset(u, &density);
      } else {
        const vec2 s = r.kind == AreaRegion::Rectangle ? 2.0f * u - vec2(1.0f) : sample_uniform_disk_concentric(u);
        q = r.centre + s.x * r.eu + s.y * r.ev;
      }
      if (r.may_miss && !on_area_light(l, q)) return false;
      vec3 w = q - p;
      float dist2 = glm::dot(w, w);
      if (dist2 <= 0.0f) return false;
      ls.dist = std::sqrt(dist2);
      ls.wi = w / ls.dist;
      float cos_l = -glm::dot(ls.wi, l.direction);
      if (cos_l <= 0.0f) return false;  // area lights emit from their front only
      const float atten = spread_attenuation(l, ls.wi);
      if (!(atten > 0.0f)) return false;
      ls.li = l.radiance * atten;
      ls.pdf = r.by_solid_angle ? pmf * density / r.rect.solid_angle() : pmf * dist2 / (cos_l * r.area);
      return true;
    }
    default:
      return false;
  }
}

float LightSampler::pdf_triangle(const vec3& p, const vec3& n, const vec3& wi, uint32_t instance, uint32_t prim,
                                 float dist, float cos_l) const {
  const uint64_t key = (uint64_t(instance) << 32) | prim;
  auto it = std::lower_bound(triangle_keys_.begin(), triangle_keys_.end(), key);
  if (it == triangle_keys_.end() || *it != key || cos_l <= 0.0f) return 0.0f;
  const uint32_t t = triangle_order_[it - triangle_keys_.begin()];
  const float pmf = selection_pmf(uint32_t(lights_.size()) + t, p, n);
  if (pmf <= 0.0f) return 0.0f;
  const EmissiveTriangle& e = triangles_[t];
  EmitterSampling how(e, p);
  const float omega = how.omega;
  if (omega < 0.0f) return 0.0f;  // in its plane: sample() gives no sample
  if (omega == 0.0f) return pmf * dist * dist / (cos_l * e.area);
  if (e.rectangle() && has_normal(n) && how.rect.warp_by_cosine(n)) return pmf * how.rect.density(wi * dist) / omega;
  return pmf / omega;
}

float LightSampler::pdf_area(uint32_t light, const vec3& p, const vec3& n, const vec3& wi, float dist,
                             float cos_l) const {
  if (cos_l <= 0.0f) return 0.0f;
  // The region sample() samples from p. A point of the light outside it
  // (possible with spread) has no emission towards p, so its density does
  // not matter.
  AreaRegion r;
  if (!area_region(lights_[light], p, &r)) return 0.0f;
  if (r.by_solid_angle) {
    const float density = has_normal(n) && r.rect.warp_by_cosine(n) ? r.rect.density(wi * dist) : 1.0f;
    return selection_pmf(light, p, n) * density / r.rect.solid_angle();
  }
  return selection_pmf(light, p, n) * dist * dist / (cos_l * r.area);
}

vec3 LightSampler::sun_disks_seen(const vec3& d, float bsdf_pdf, RayKind kind) const {
  vec3 sum(0.0f);
  for (const auto& [index, pmf] : sun_disks_) {
    const Light& l = lights_[index];
    if (!(l.visibility & kind)) continue;
    // d meets the plane one unit towards the sun at d / c; inside the disk
    // of radius r = tan(half angle) when tan^2 theta = (1 - c^2) / c^2 <= r^2.
    const float c = -glm::dot(d, l.direction);
    if (!(c > 0.0f) || 1.0f - c * c > l.radius * l.radius * c * c) continue;
    // sample()'s density for d: pmf |q|^3 / (pi r^2), |q| = 1 / c.
    const float light_pdf = pmf / (kPi * l.radius * l.radius * c * c * c);
    sum += l.radiance * (bsdf_pdf > 0.0f ? power_heuristic(bsdf_pdf, light_pdf) : 1.0f);
  }
  return sum;
}

float LightSampler::pdf_background(const vec3& wi) const {
  if (!world_) return 0.0f;
  return top_world_pmf_ * world_->pdf(wi);
}

float LightSampler::pdf_sphere(uint32_t light, const vec3& p, const vec3& n, float dist, float cos_l) const {
  const Light& l = lights_[light];
  if (l.radius <= 0.0f) return 0.0f;
  if (l.sphere) {
    bool outside;
    return selection_pmf(light, p, n) * sphere_light_pdf(l.position, l.radius, p, &outside);
  }
  if (cos_l <= 0.0f) return 0.0f;
  return selection_pmf(light, p, n) * dist * dist / (cos_l * kPi * l.radius * l.radius);
}

int LightSampler::intersect_lights(const vec3& o, const vec3& d, float tmax, float* t_hit, vec3* le, float* pdf,
                                   const vec3& p, const vec3& n, RayKind kind) const {
  int best = -1;
  for (uint32_t i : hittable_lights_) {
    const Light& l = lights_[i];
    if (!(l.visibility & kind)) continue;
    if (l.type == LightType::Area) {
      float denom = glm::dot(d, l.direction);
      if (denom >= 0.0f) continue;  // back side or parallel: area lights are one-sided
      float t = glm::dot(l.position - o, l.direction) / denom;
      if (!(t > 0.0f && t < tmax)) continue;
      if (!on_area_light(l, o + t * d)) continue;
      const float atten = spread_attenuation(l, d);  // outside its spread: not seen
      if (!(atten > 0.0f)) continue;
      tmax = t;
      best = int(i);
      *t_hit = t;
      *le = l.radiance * atten;
      *pdf = pdf_area(i, p, n, d, t, -denom);
    } else if (l.sphere) {
      // Cycles 4.x's sphere light (point_light_intersect); a spot is only
      // hit by rays heading towards its centre (spot_light_intersect).
      const bool spot = l.type == LightType::Spot;
      if (spot && glm::dot(d, o - l.position) >= 0.0f) continue;
      float t;
      if (!intersect_sphere(o, d, l.position, l.radius, tmax, &t)) continue;
      const vec3 oc = o - l.position;
      const bool outside = glm::dot(oc, oc) > l.radius * l.radius;
      const float atten = spot && outside ? spot_attenuation(l, -d) : 1.0f;
      if (atten <= 0.0f) continue;
      tmax = t;
      best = int(i);
      *t_hit = t;
      *le = l.radiance * atten;
      *pdf = pdf_sphere(i, p, n, t, 1.0f);
    } else {
      // The disk of the light's radius facing the ray origin.
      const vec3 to_center = l.position - o;
      const float dist_c = glm::length(to_center);
      if (!(dist_c > l.radius)) continue;
      const vec3 disk_n = -to_center / dist_c;  // towards the origin
      const float denom = glm::dot(d, disk_n);
      if (denom >= 0.0f) continue;
      const float t = glm::dot(l.position - o, disk_n) / denom;
      if (!(t > 0.0f && t < tmax)) continue;
      const vec3 q = o + t * d - l.position;
      if (glm::dot(q, q) > l.radius * l.radius) continue;
      const float atten = l.type == LightType::Spot ? spot_attenuation(l, -d) : 1.0f;
      if (atten <= 0.0f) continue;
      tmax = t;
      best = int(i);
      *t_hit = t;
      *le = l.radiance * atten;
      // The MIS density as sample() from (p, n), the shading point's normal
      // (not the disk's: it picks the light by it).
      *pdf = pdf_sphere(i, p, n, t, -denom);
    }
  }
  return best;
}

}  // namespace tessera
