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
  // Every feature modelled, whatever the scene has (RenderOptions::specialise off).
  static SceneFeatures all() { return {true, true, true}; }
};
SceneFeatures scene_features(const Scene& scene);

// first: when not null, filled with what the render passes need (passes.h).
vec3 Li(const Scene& scene, Ray ray, Sampler& sampler, const RenderOptions& options, PathCounters& counters,
        const SceneFeatures& features = SceneFeatures(), FirstHit* first = nullptr);

}  // namespace tessera
