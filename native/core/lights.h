// Light sources and light sampling for next-event estimation. A light is
// picked in two steps: a power-weighted alias table over the light BVH (all
// bounded emitters: point, spot and area lights, emissive triangles and
// rectangles), the
// world when its image emits (a constant world is left to BSDF sampling, as
// in Cycles), and each sun; then, in the BVH, by the estimated
// contribution at the shading point (light_bvh.h). Conversions from
// Blender's Watts follow Cycles, so that a file is as bright in both engines.
#pragma once
#include <utility>
#include <vector>
#include "light_bvh.h"
#include "material.h"
#include "sampling.h"
#include "visibility.h"

namespace tessera {

enum class LightType : uint32_t { Point, Spot, Sun, Area, Triangle, Background };

// One Blender light, already converted to radiometric quantities.
struct Light {
  LightType type = LightType::Point;
  // Object Properties > Visibility > Ray Visibility of the light (visibility.h):
  // the kinds of rays that see it and that it lights (Camera: area and
  // sphere lights are seen by camera rays; Shadow: it casts shadows). Next
  // to the type: intersect_lights reads both for every light.
  uint8_t visibility = kLightDefaultVisibility;
  vec3 position{0.0f};
  vec3 direction{0.0f, 0.0f, -1.0f};  // emission axis (spot, sun, area): the light's -Z
  vec3 axis_u{1, 0, 0}, axis_v{0, 1, 0};  // area: half-extent vectors
  float radius = 0.0f;      // point/spot: sphere radius; sun: tan(half angle)
  // point/spot with a radius: Cycles 4.x's sphere light ("Soft Falloff" off):
  // constant radiance from the sphere's surface, sampled in the cone the
  // sphere subtends (kernel/light/point.h). Otherwise the disk of the radius
  // facing the shading point (Cycles 3.x, and 4.x with Soft Falloff).
  bool sphere = false;
  float spot_cos = -1.0f;   // spot: cos(half cone angle)
  float spot_smooth = 0.0f; // spot: width of the smooth edge in cosine
  // spot: Cycles 3.x multiplies the smooth edge by the cosine to the axis;
  // Cycles 4.0+ (kernel/light/spot.h) uses the smoothstep alone.
  bool spot_cosine = true;
  // spot: Cycles 4.x measures the angle to the axis in the light object's own
  // space (spot_light_to_local: the inverse of its transform), so that a
  // non-uniform scale makes the cone elliptical. When spot_scaled, a
  // direction w from the light is taken to spot_to_local * w (the inverse of
  // the object's 3x3, emission along local -Z); otherwise the cone is round
  // around `direction` (Cycles 3.x ignores the scale).
  bool spot_scaled = false;
  glm::mat3 spot_to_local{1.0f};
  bool ellipse = false;     // area: disk/ellipse instead of square/rectangle
  // area: Blender's Spread, as Cycles' soft box (kernel/light/area.h,
  // area_light_spread_attenuation): radiance leaving at angle a to the
  // normal is scaled by max((spread_tan - tan a) * spread_norm, 0), with
  // spread_tan = tan(half spread) and spread_norm = 1 / (spread_tan - half
  // spread), which keeps the light's power. spread_tan = inf: no spread
  // (the full hemisphere, factor 1). Only the disk of radius h * spread_tan
  // around the foot of a point at height h emits towards it, and sample()
  // samples that part of the light only.
  float spread_tan = kInf;
  float spread_norm = 0.0f;
  vec3 radiance{0.0f};      // emitted radiance (area, sphere, sun disk) or intensity (radius 0)
  float area = 0.0f;        // area lights: surface area
};

// A spot light's smooth edge for a direction from the light (lights.cpp;
// light tracing weighs its rays by it too).
float spot_attenuation(const Light& l, const vec3& dir_from_light);

// An emissive triangle p0 + s e1 + t e2 (s, t >= 0, s + t <= 1) or, when
// `second` names the other triangle of the pair, the rectangle p0 + s e1 +
// t e2 (s, t in [0, 1], e1 perpendicular to e2) that two emissive triangles
// sharing their hypotenuse make (a quad light, as Blender's planes are):
// sample() then draws directions uniformly in the solid angle of the whole
// rectangle (Urena et al. 2013, as for area lights), one entry instead of
// two (Scene::collect_emissive_triangles pairs them).
struct EmissiveTriangle {
  static constexpr uint32_t kAlone = ~0u;
  vec3 p0, e1, e2;  // world space
  vec3 n;           // unit geometric normal (front side)
  float area;
  vec3 le_front, le_back;
  uint32_t instance, prim;  // prim in leaf order
  // Bound on the rounding, in world units, of points on the triangle as the
  // BVH tests them in its instance's space (large when the mesh's own
  // coordinates are large, whatever the world position).
  float local_error = 0.0f;
  // Set by LightSampler::build: the centre, and the squared distance from it
  // beyond which sample() samples the triangle by area (lights.cpp,
  // spherical_sampling_area), next to the corners that sampling reads.
  vec3 centre{0.0f};
  float area_from2 = 0.0f;
  // Set by LightSampler::build: the part of in_emitter_plane's tolerance that
  // scales with the size, 1e-5 sqrt(area of one triangle) (lights.cpp).
  float plane_tolerance = 0.0f;
  uint8_t visibility = kVisibleToAll;  // its instance's (visibility.h)
  uint32_t second = kAlone;  // a rectangle: its other triangle (leaf order)
  bool rectangle() const { return second != kAlone; }
};

struct LightSample {
  vec3 wi;        // direction from the shading point
  float dist;     // distance to the light point (kInf for sun and world)
  vec3 li;        // incident radiance (or intensity / dist^2 for delta lights)
  float pdf;      // solid-angle pdf including selection; for delta lights, selection pmf only
  bool is_delta;  // no MIS: BSDF sampling cannot hit it (delta lights: points, spots, suns without a radius)
  // The ray kinds that see the light (visibility.h): light sampling leaves
  // out the BSDF lobes of the others, and traces no shadow ray without the
  // shadow kind.
  uint8_t visibility = kVisibleToAll;
};

class Background;

class LightSampler {
 public:
  void build(std::vector<Light> lights, std::vector<EmissiveTriangle> triangles, const Background* world,
             float scene_radius);
  bool empty() const { return top_.empty(); }
  const std::vector<Light>& lights() const { return lights_; }
  const std::vector<EmissiveTriangle>& triangles() const { return triangles_; }

  // A light sample for the shading point p with shading normal n (either
  // side; 0 when there is none): the light is chosen by its estimated
  // contribution there, so the same (p, n) must be given to the pdf_*
  // functions below for MIS. u.x picks the light and, rescaled to [0,1) by
  // that choice, becomes the first coordinate of the point on it (as Cycles'
  // light_distribution_sample reuses its random number), so that the points
  // on each light are stratified with the choice, from one 2D sample.
  // above: when not null, the receiver's BSDF is 0 for every direction
  // behind the plane through p it is normal to (BSDF::reflects_only_above),
  // and an emissive triangle or area light wholly behind it gets no sample
  // (false, as a sample of zero contribution: the densities do not change).
  // n (unit, or 0 for none) is the receiver's shading normal: the lights'
  // importance looks at it, and rectangles near p follow its |cos|
  // (SphericalRectangle::warp_by_cosine).
  bool sample(const vec3& p, const vec3& n, vec2 u, LightSample& ls, const vec3* above = nullptr) const;

  // Densities with which sample() from (p, n) would have produced the
  // direction wi (unit) hitting: the emissive triangle (instance, prim) at distance
  // dist with cosine cos_l; area light `light`; point/spot light `light`
  // with a radius (a sphere light: by the cone it subtends from p; otherwise
  // seen as the disk facing p, at dist with cosine cos_l); the world.
  float pdf_triangle(const vec3& p, const vec3& n, const vec3& wi, uint32_t instance, uint32_t prim, float dist,
                     float cos_l) const;
  float pdf_area(uint32_t light, const vec3& p, const vec3& n, const vec3& wi, float dist, float cos_l) const;
  float pdf_sphere(uint32_t light, const vec3& p, const vec3& n, float dist, float cos_l) const;
  float pdf_background(const vec3& wi) const;
  // The probability of picking the world among the lights (pdf_background =
  // this x the world's own density), for a caller that has that density.
  float world_pmf() const { return world_ ? top_world_pmf_ : 0.0f; }

  // Nearest area light, or point/spot light with a radius, seen by rays of
  // kind `kind` and hit by the ray before tmax (BSDF-sampled rays see them,
  // so they take part in MIS); returns the light index or -1, with the hit
  // distance, radiance and the light's solid-angle pdf for MIS as sample()
  // from (p, n) would have produced it (p: the scattering vertex the ray left).
  int intersect_lights(const vec3& o, const vec3& d, float tmax, float* t, vec3* le, float* pdf, const vec3& p,
                       const vec3& n, RayKind kind) const;
  // Some light is of the kind intersect_lights finds (area lights, point
  // and spot lights with a radius); some of those is visible to the camera.
  bool has_hittable_lights() const { return !hittable_lights_.empty(); }
  bool camera_sees_lights() const { return camera_sees_lights_; }
  // Suns with an angle are disks at infinity that escaping rays see, as
  // Cycles' integrate_distant_lights: the radiance of those seen by rays of
  // kind `kind` whose disk the direction d lies in, each weighted by the
  // power heuristic against its light-sampling density, d having been drawn
  // with density bsdf_pdf (0: weight 1, after a delta bounce).
  bool has_sun_disks() const { return !sun_disks_.empty(); }
  vec3 sun_disks_seen(const vec3& d, float bsdf_pdf, RayKind kind) const;

 private:
  // Probability that sample() from (p, n) picks light entry `entry` (lights,
  // then triangles: the BVH's ids).
  float selection_pmf(uint32_t entry, const vec3& p, const vec3& n) const;
  bool sample_entry(uint32_t entry, float pmf, const vec3& p, const vec3& n, vec2 u, LightSample& ls,
                    const vec3* above) const;
  std::vector<Light> lights_;
  std::vector<EmissiveTriangle> triangles_;
  std::vector<uint64_t> triangle_keys_;  // (instance << 32 | prim), sorted, for lookups on hit
  std::vector<uint32_t> triangle_order_; // key rank -> triangle index
  std::vector<uint32_t> hittable_lights_;  // area lights, and point/spot lights with a radius
  bool camera_sees_lights_ = false;
  std::vector<std::pair<uint32_t, float>> sun_disks_;  // suns with an angle: light index, selection pmf
  const Background* world_ = nullptr;
  // First step: the BVH (kTopBVH), the world (kTopWorld) or a sun (its light index).
  static constexpr uint32_t kTopBVH = ~0u, kTopWorld = ~0u - 1;
  std::vector<uint32_t> top_entries_;
  AliasTable top_;
  float top_bvh_pmf_ = 0.0f, top_world_pmf_ = 0.0f;
  LightBVH bvh_;  // over entries: lights (suns left out), then triangles
};

}  // namespace tessera
