// Unidirectional path tracing with next-event estimation and multiple
// importance sampling (Veach 1997, ch. 9; pbrt-v4, 13.4).
#pragma once
#include "options.h"
#include "passes.h"
#include "sampler.h"
#include "scene.h"

namespace tessera {

struct PathCounters {
  uint64_t rays = 0;          // closest-hit and shadow rays
  uint64_t invalid_samples = 0;  // NaN/Inf radiance dropped
  uint64_t skipped_rays = 0;  // continuation rays not traced (SceneFeatures)
};

// What the scene needs the integrator to model, decided once per render
// (RenderSession's constructor) from the committed scene.
struct SceneFeatures {
  bool emits = true;  // any light, emissive triangle or emitting world
  // Whether a BSDF-sampled ray can hit an emitter (emissive triangles, area
  // lights, point/spot lights with a radius, an emitting world). If not, the
  // ray after a path's last bounce would only look for emission and is not
  // traced.
  bool hittable_emitters = true;
  // Whether any material lets rays through (Transparent BSDF, Principled
  // Alpha): shadow rays then pass such surfaces, attenuated (Cycles'
  // transparent shadows). Without any, shadow rays stay any-hit occlusion tests.
  bool transparent = false;
  // Whether a camera ray can see emission (an emissive material or an
  // emitting world): only then are pixels' camera emission statistics kept
  // and their edges supersampled (RenderSession, emitter antialiasing).
  bool camera_emission = true;
  // Per light: 1 if light tracing (light_tracer.h) takes the paths camera ->
  // rough surface -> delta surfaces -> that light, which Li then drops.
  const uint8_t* traced_lights = nullptr;
  // Every feature modelled, whatever the scene has (RenderOptions::specialise off).
  static SceneFeatures all() { return {true, true, true, true}; }
};
SceneFeatures scene_features(const Scene& scene);

// first: when not null, filled with what the render passes need (passes.h).
// camera_le: when not null, set to the part of the result that is the
// emission the camera ray finds at its first surface (or the world's, if it
// hits nothing), as camera_emission gives it: Li = that + the rest of the path.
// transparency: when not null, set to the path's weight where the camera
// saw the world through Film > Transparent (RenderOptions::film_transparent),
// else 0: the sample's alpha is 1 minus it.
vec3 Li(const Scene& scene, Ray ray, Sampler& sampler, const RenderOptions& options, PathCounters& counters,
        const SceneFeatures& features = SceneFeatures(), FirstHit* first = nullptr, vec3* camera_le = nullptr,
        float* transparency = nullptr);

// The emission a camera ray sees at its first surface, or the world's
// radiance along it if it hits nothing (none with Film > Transparent),
// clamped as Li clamps direct light: the first term of Li alone, for a
// pixel's extra camera rays (emitter antialiasing, render.cpp).
vec3 camera_emission(const Scene& scene, const Ray& ray, const RenderOptions& options, PathCounters& counters);

}  // namespace tessera
