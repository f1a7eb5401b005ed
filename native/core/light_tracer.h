// Light tracing for caustics seen directly: paths from small point and spot
// lights (the ones with a radius, that BSDF-sampled rays can hit) through
// smooth (delta) surfaces to the first rough surface, connected to the camera
// and splatted into a light image (the t = 1 strategy of bidirectional path
// tracing: Veach 1997, 10.2; pbrt-v4, 13.4). The path tracer drops the same
// paths (camera -> rough vertex -> delta vertices -> traced light, which it
// finds only by BSDF sampling: Li's caustic_chain), so the two estimators
// partition the paths and the image's expectation stays what it was.
//
// The light model is the disk of the light's radius facing the receiver
// (Cycles 3.x; lights.cpp). Light paths start on rays uniform in direction
// (within the spot's cone) and in projected area across it (a point on the
// disk of the radius perpendicular to the direction), and keep those that
// cross the disk facing the surface they reach: the rays the path tracer's
// test from that surface accepts.
//
// Used (active()) only when the scene has such lights and surfaces that can
// scatter by a delta lobe, a pinhole perspective camera, the full frame, a
// pixel filter at least a pixel wide (a splat lands in a pixel by the filter's
// density there; a pinpoint filter would take almost none), and
// none of what would make the two halves count different paths: transparent
// surfaces, clamping, per-kind bounce limits under the total, instances or
// lights hidden from some rays, textures whose blurred level paths read
// after a diffuse bounce on smooth surfaces.
#pragma once
#include <cstdint>
#include <vector>

#include "film.h"
#include "integrator.h"
#include "options.h"
#include "sampling.h"
#include "scene.h"

namespace tessera {

class LightTracer {
 public:
  // A connection: the raster position of the surface point the camera sees
  // (full-frame pixels) and what it adds before the pixel filter.
  struct Splat {
    vec2 raster;
    vec3 value;
  };

  LightTracer(const Scene& scene, const RenderOptions& options, const PixelFilter& filter, int x0, int y0, int x1,
              int y1);
  bool active() const { return !lights_.empty(); }
  // Per light index: 1 if its caustics are light-traced (Li drops them).
  const std::vector<uint8_t>& traced() const { return traced_; }
  // Light paths [first, first + count): their connections, in path order.
  // Path j's random numbers depend only on (seed, j): the same paths with
  // any number of threads.
  void trace(uint64_t first, uint64_t count, uint32_t seed, std::vector<Splat>& out, PathCounters& counters) const;
  // Adds a splat to the region's image (row-major), weighted by the pixel
  // filter of every pixel it reaches in rows [y_begin, y_end) (full-frame rows).
  void splat(const Splat& s, std::vector<vec3>& image, int y_begin, int y_end) const;
  // What the summed splats are multiplied by after n light paths in all:
  // the camera's importance is per unit of film area, a pixel 1 / (w h) of it.
  double scale(uint64_t n) const { return n ? double(full_w_) * double(full_h_) / double(n) : 0.0; }

 private:
  void trace_path(uint64_t index, uint32_t seed, std::vector<Splat>& out, PathCounters& counters) const;
  void connect(const vec3& beta, const SurfaceInteraction& si, const Material& material, const vec3& w_light,
               std::vector<Splat>& out, PathCounters& counters) const;

  const Scene& scene_;
  const RenderOptions& options_;
  const PixelFilter& filter_;
  int x0_, y0_, x1_, y1_, full_w_, full_h_;
  std::vector<uint32_t> lights_;  // traced light indices
  AliasTable choice_;             // over lights_, by power
  std::vector<float> cos_cone_;   // per traced light: the cone its directions are drawn in
  std::vector<uint8_t> traced_;
  glm::mat4 to_camera_{1.0f};
  vec3 camera_pos_{0.0f};
  float film_area_ = 1.0f;  // the image's area on the plane at distance 1
};

}  // namespace tessera
