// Light sources and light sampling for next-event estimation. Blender lights
// (point, spot, sun, area) and emissive triangles share one power-weighted
// alias table, built only when the scene has emitters; the world is sampled
// as one more entry when it emits. Conversions from Blender's Watts follow
// Cycles, so that a file is as bright in both engines.
#pragma once
#include <vector>
#include "material.h"
#include "sampling.h"

namespace tessera {

enum class LightType : uint32_t { Point, Spot, Sun, Area, Triangle, Background };

// One Blender light, already converted to radiometric quantities.
struct Light {
  LightType type = LightType::Point;
  vec3 position{0.0f};
  vec3 direction{0.0f, 0.0f, -1.0f};  // emission axis (spot, sun, area): the light's -Z
  vec3 axis_u{1, 0, 0}, axis_v{0, 1, 0};  // area: half-extent vectors
  float radius = 0.0f;      // point/spot: sphere radius; sun: tan(half angle)
  float spot_cos = -1.0f;   // spot: cos(half cone angle)
  float spot_smooth = 0.0f; // spot: width of the smooth edge in cosine
  // spot: Cycles 3.x multiplies the smooth edge by the cosine to the axis;
  // Cycles 4.0+ (kernel/light/spot.h) uses the smoothstep alone.
  bool spot_cosine = true;
  bool ellipse = false;     // area: disk/ellipse instead of square/rectangle
  vec3 radiance{0.0f};      // emitted radiance (area, sphere, sun disk) or intensity (radius 0)
  float area = 0.0f;        // area lights: surface area
};

struct EmissiveTriangle {
  vec3 p0, e1, e2;  // world space
  vec3 n;           // unit geometric normal (front side)
  float area;
  vec3 le_front, le_back;
  uint32_t instance, prim;  // prim in leaf order
  // Bound on the rounding, in world units, of points on the triangle as the
  // BVH tests them in its instance's space (large when the mesh's own
  // coordinates are large, whatever the world position).
  float local_error = 0.0f;
};

struct LightSample {
  vec3 wi;        // direction from the shading point
  float dist;     // distance to the light point (kInf for sun and world)
  vec3 li;        // incident radiance (or intensity / dist^2 for delta lights)
  float pdf;      // solid-angle pdf including selection; for delta lights, selection pmf only
  bool is_delta;  // no MIS: BSDF sampling cannot hit it (delta lights, the sun disk)
};

class Background;

class LightSampler {
 public:
  void build(std::vector<Light> lights, std::vector<EmissiveTriangle> triangles, const Background* world,
             float scene_radius);
  bool empty() const { return table_.empty(); }
  const std::vector<Light>& lights() const { return lights_; }
  const std::vector<EmissiveTriangle>& triangles() const { return triangles_; }

  bool sample(const vec3& p, float u_select, vec2 u, LightSample& ls) const;

  // Density with which sample() from point p would have produced the
  // direction hitting the emissive triangle (instance, prim) at distance
  // dist with cosine cos_l.
  float pdf_triangle(const vec3& p, uint32_t instance, uint32_t prim, float dist, float cos_l) const;
  float pdf_area(uint32_t light, float dist, float cos_l) const;
  // Point and spot lights with a radius, seen as the disk facing the ray origin (Cycles 3.x).
  float pdf_sphere(uint32_t light, float dist, float cos_l) const;
  float pdf_background(const vec3& wi) const;

  // Nearest area light, or point/spot light with a radius, hit by the ray
  // before tmax (BSDF-sampled rays see them, so they take part in MIS);
  // returns the light index or -1, with the hit distance, radiance and the
  // light's solid-angle pdf for MIS.
  int intersect_lights(const vec3& o, const vec3& d, float tmax, float* t, vec3* le, float* pdf) const;

 private:
  float selection_pmf(uint32_t entry) const { return table_.pmf(entry); }
  std::vector<Light> lights_;
  std::vector<EmissiveTriangle> triangles_;
  std::vector<uint64_t> triangle_keys_;  // (instance << 32 | prim), sorted, for lookups on hit
  std::vector<uint32_t> triangle_order_; // key rank -> triangle index
  std::vector<uint32_t> hittable_lights_;  // area lights, and point/spot lights with a radius
  const Background* world_ = nullptr;
  uint32_t world_entry_ = ~0u;
  AliasTable table_;  // entries: lights, then triangles, then the world
};

}  // namespace tessera
