// A material as the core evaluates it: the parameters of Blender's Principled
// BSDF after the add-on has folded the node graph into constants (and texture
// references). Emission is stored per side, so one-sided emitters (Geometry >
// Backfacing feeding the strength) cost nothing at render time.
#pragma once
#include "math.h"

namespace tessera {

// A material input read from an image texture: its colour (or, for a scalar
// input, the colour's luminance) or its alpha.
struct TextureRef {
  int32_t texture = -1;  // index into Scene::textures; -1: none
  uint32_t channel = 0;  // 0: colour / luminance, 1: alpha
  bool valid() const { return texture >= 0; }
};

struct Material {
  vec3 base_color{0.8f};
  float metallic = 0.0f;
  float roughness = 0.5f;
  float specular = 0.5f;
  float ior = 1.45f;
  float transmission = 0.0f;
  vec3 emission_front{0.0f};  // radiance leaving the front face (colour x strength)
  vec3 emission_back{0.0f};   // ... and the back face

  // Inputs driven by image textures (sampled with the mesh's UV map).
  TextureRef base_color_tex, metallic_tex, roughness_tex, emission_tex;
  TextureRef normal_tex;       // tangent-space normal map
  float normal_strength = 1.0f;
  float emission_strength_front = 1.0f, emission_strength_back = 0.0f;  // for emission_tex

  bool has_textures() const {
    return base_color_tex.valid() || metallic_tex.valid() || roughness_tex.valid() || emission_tex.valid() ||
           normal_tex.valid();
  }

  bool is_emissive() const {
    return max_component(emission_front) > 0.0f || max_component(emission_back) > 0.0f ||
           (emission_tex.valid() && (emission_strength_front > 0.0f || emission_strength_back > 0.0f));
  }
  vec3 emission(bool back_face) const { return back_face ? emission_back : emission_front; }
};

}  // namespace tessera
