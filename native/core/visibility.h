// Ray visibility, as Blender's Visibility > Ray Visibility panels (objects,
// lights, the world) and Cycles' PATH_RAY_* flags have it. A ray is of one
// kind: the camera's (and its continuation through transparent surfaces),
// one leaving a diffuse, glossy or transmission bounce (Cycles'
// path_state_next and path_state_ray_visibility: a transmission ray is seen
// by the transmission flag only, a reflection by diffuse or glossy), or a
// shadow ray. Each object, light and the world carries the set of kinds
// that see it:
// - an object is passed by rays whose kind it is hidden from (Scene);
// - a light, an emissive object or the world hidden from a kind adds nothing
//   to rays of that kind that reach it, and light sampling leaves out the
//   BSDF lobes of that kind (Cycles' SHADER_EXCLUDE_* and
//   _surface_shader_exclude), so both estimators of MIS agree.
// For a light the shadow kind means that it casts shadows (Blender's Cast
// Shadow, Cycles' SHADER_CAST_SHADOW): without it, light sampling traces
// no shadow ray towards it. Emissive objects and the world always do.
#pragma once
#include <cstdint>

namespace tessera {

enum RayKind : uint8_t {
  kRayCamera = 1,
  kRayDiffuse = 2,
  kRayGlossy = 4,
  kRayTransmission = 8,
  kRayShadow = 16,
};

// What scattered rays (and so light sampling's BSDF lobes) are.
constexpr uint8_t kScatteredRays = kRayDiffuse | kRayGlossy | kRayTransmission;
constexpr uint8_t kVisibleToAll = kRayCamera | kScatteredRays | kRayShadow;
// Blender's default for lights: every kind but the camera's.
constexpr uint8_t kLightDefaultVisibility = kScatteredRays | kRayShadow;

}  // namespace tessera
