// Unidirectional path tracing with next-event estimation and multiple
// importance sampling (Veach 1997, ch. 9; pbrt-v4, 13.4).
#pragma once
#include "options.h"
#include "sampler.h"
#include "scene.h"

namespace tessera {

struct PathCounters {
  uint64_t rays = 0;          // closest-hit and shadow rays
  uint64_t invalid_samples = 0;  // NaN/Inf radiance dropped
};

vec3 Li(const Scene& scene, Ray ray, Sampler& sampler, const RenderOptions& options, PathCounters& counters);

}  // namespace tessera
