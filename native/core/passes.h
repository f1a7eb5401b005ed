// Render passes besides Combined, as Cycles writes them (kernel/film/
// data_passes.h, denoising_passes.h): what a camera path finds at its first
// surface (depth, normal, diffuse colour, emission) and at its first surface
// that is not mostly specular (the denoising features), summed over a
// pixel's samples and divided by its sample count. Enabled per render
// (RenderOptions::passes); with none enabled the integrator records nothing.
#pragma once
#include <cstdint>

#include "camera.h"
#include "material.h"
#include "scene.h"

namespace tessera {

enum PassBits : uint32_t {
  kPassDepth = 1u << 0,             // "Depth": camera-space z of the first hit (1e10 where nothing is hit)
  kPassNormal = 1u << 1,            // "Normal": world-space shading normal, towards the camera
  kPassDiffuseColor = 1u << 2,      // "DiffCol": diffuse closure weights (base colour x diffuse weight)
  kPassEmission = 1u << 3,          // "Emit": emission the camera sees directly
  kPassDenoisingNormal = 1u << 4,   // "Denoising Normal": camera-space normal at the feature vertex
  kPassDenoisingAlbedo = 1u << 5,   // "Denoising Albedo": albedo of diffuse-like closures there
  kPassDenoisingDepth = 1u << 6,    // "Denoising Depth": that vertex's segment length
};
constexpr int kNumDataPasses = 7;
constexpr uint32_t kPassAllData = (1u << kNumDataPasses) - 1;
// "Debug Sample Count": the samples each pixel took over the Samples setting
// (Cycles' PASS_SAMPLE_COUNT, film_get_pass_pixel_sample_count: the count
// scaled by 1 / num_samples), where adaptive sampling and the time limit put
// the work. Read off the film's counts between passes; the integrator
// records nothing for it.
constexpr uint32_t kPassSampleCount = 1u << kNumDataPasses;
constexpr uint32_t kPassAll = kPassAllData | kPassSampleCount;

// Blender's name of each pass (the render result's pass names, as Cycles registers them).
inline const char* pass_name(uint32_t pass) {
  switch (pass) {
    case kPassDepth: return "Depth";
    case kPassNormal: return "Normal";
    case kPassDiffuseColor: return "DiffCol";
    case kPassEmission: return "Emit";
    case kPassDenoisingNormal: return "Denoising Normal";
    case kPassDenoisingAlbedo: return "Denoising Albedo";
    case kPassDenoisingDepth: return "Denoising Depth";
    case kPassSampleCount: return "Debug Sample Count";
    default: return "";
  }
}

// Number of float channels of one pass (1 or 3).
inline int pass_channels(uint32_t pass) {
  return (pass == kPassDepth || pass == kPassDenoisingDepth || pass == kPassSampleCount) ? 1 : 3;
}

// Albedos of a material's closures as Cycles sums them for its passes
// (Principled BSDF, Cycles 3.x weights, see bsdf.h).
struct ClosureAlbedo {
  vec3 diffuse_color;   // the diffuse closure's weight (DiffCol)
  vec3 diffuse_like;    // closures rougher than Cycles' 0.075 (squared roughness), x Fresnel
  vec3 specular_like;   // the smoother ones
  float sample_weight, nonspecular_sample_weight;
};
ClosureAlbedo closure_albedo(const Material& m);

// What one camera sample records for the passes, filled by Li (integrator.h)
// at each surface until complete().
struct FirstHit {
  // alpha_threshold: Blender's pass alpha threshold (View Layer > Passes):
  // Depth, Normal and Diffuse Color come from the first surface at least this
  // opaque (1 - average transparency), as Cycles' film_write_data_passes;
  // 0 takes the first surface whatever its alpha.
  explicit FirstHit(uint32_t passes, float alpha_threshold = 0.0f)
      : denoising_done((passes & (kPassDenoisingNormal | kPassDenoisingAlbedo | kPassDenoisingDepth)) == 0),
        alpha_threshold(alpha_threshold) {}
  bool complete() const { return (hit || !camera_ray) && denoising_done; }
  // A surface the path reached along ray at distance t; le: its emission
  // towards the ray.
  void surface(const Ray& ray, float t, const SurfaceInteraction& si, const Material& m, const vec3& le);
  // The path left the scene; le: the world's radiance along it.
  void miss(const vec3& le);
  // The path scattered off a surface (not straight through a transparent
  // one): it is no longer the camera ray, whose first surface at least
  // alpha_threshold opaque the data passes wanted; they get nothing now.
  void scattered() { camera_ray = false; }

  bool hit = false;
  vec3 position{0.0f}, normal{0.0f}, diffuse_color{0.0f}, emission{0.0f};
  bool emission_done = false;  // the first surface's emission, whatever its alpha
  bool camera_ray = true;      // the path has only passed transparent surfaces so far
  bool denoising_done;
  // Cycles adds the emission and world seen before the feature vertex (at
  // it included) to the albedo (film_write_emission_or_background_pass),
  // here weighted by the specular albedos passed (not the path throughput).
  vec3 denoising_normal{0.0f}, denoising_albedo{0.0f};  // normal in world space here
  float denoising_depth = 0.0f;
  vec3 denoising_throughput{1.0f};  // specular albedos passed before the feature vertex
  float alpha_threshold;
};

}  // namespace tessera
