// A material as the core evaluates it: the parameters of Blender's Principled
// BSDF after the add-on has folded the node graph into constants (and texture
// references). Emission is stored per side, so one-sided emitters (Geometry >
// Backfacing feeding the strength) cost nothing at render time.
#pragma once
#include "math.h"

namespace tessera {

struct Material {
  vec3 base_color{0.8f};
  float metallic = 0.0f;
  float roughness = 0.5f;
  float specular = 0.5f;
  float ior = 1.45f;
  float transmission = 0.0f;
  vec3 emission_front{0.0f};  // radiance leaving the front face (colour x strength)
  vec3 emission_back{0.0f};   // ... and the back face

  bool is_emissive() const { return max_component(emission_front) > 0.0f || max_component(emission_back) > 0.0f; }
  vec3 emission(bool back_face) const { return back_face ? emission_back : emission_front; }
};

}  // namespace tessera
