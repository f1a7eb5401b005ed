// A material as the core evaluates it: a short list of weighted closures, as
// Cycles' closure list, after the add-on has flattened Mix and Add Shader
// nodes into weights and folded the value nodes into constants (and texture
// references). Closure 0 is stored in the Material's own fields (a single
// Principled BSDF is just that); Mix/Add Shader add up to kMaxClosures - 1
// more. Emission is stored per side, so one-sided emitters (Geometry >
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

// Whose definitions of the closures to follow: Cycles changed them in
// Blender 4.0, and the add-on picks the running Blender's (bpy.app.version),
// per closure.
enum class ShadingModel : uint8_t {
  Cycles3,   // Blender 3.x: Principled v1 (Burley diffuse, interpolated Fresnel), separable Smith
             // masking, Glass split by the Fresnel factor at wo
  Cycles4,   // Blender 4.0 to 4.2: Principled v2 (layered: coat, metal with F82 tint, glass, dielectric
             // specular over Lambert), height-correlated Smith masking, Fresnel at the microfacet,
             // Multiscatter GGX as energy compensation (ggx_energy.h)
  Cycles4_3, // Blender 4.3 on: as 4.0, and rough diffuse is the energy-preserving Oren-Nayar
             // (Fujii's, with OpenPBR's multiple-scattering term); Principled Diffuse Roughness
};

// Blender's shader nodes that the core evaluates (bsdf.cpp).
enum class ClosureKind : uint8_t {
  Principled,   // Principled BSDF (Cycles 3.x, or 4.x's principled v2)
  Diffuse,      // Diffuse BSDF: Lambert, Oren-Nayar when roughness > 0
  Glossy,       // Glossy BSDF: GGX reflection, Fresnel 1, tinted by the colour
  Glass,        // Glass BSDF: GGX reflection F(wo) + refraction 1 - F(wo), both tinted
  Transparent,  // Transparent BSDF: the ray goes on straight, tinted
};

// One closure: its kind, its weight (the product of the Mix Shader factors on
// its way to the output) and the parameters its kind reads.
struct Closure {
  ClosureKind kind = ClosureKind::Principled;
  float weight = 1.0f;
  vec3 color{0.8f};  // Principled base colour, or the node's Color
  float metallic = 0.0f;
  float roughness = 0.5f;
  float specular = 0.5f;
  float ior = 1.45f;
  float transmission = 0.0f;
  ShadingModel model = ShadingModel::Cycles3;
  bool multiscatter = false;  // the Multiscatter GGX distribution (Glossy, Glass, Principled 4.x)
  // Principled v2 only (Blender 4.x inputs; their defaults leave them out):
  vec3 specular_tint{1.0f};
  float coat = 0.0f, coat_roughness = 0.03f, coat_ior = 1.5f;
  vec3 coat_tint{1.0f};
  float diffuse_roughness = 0.0f;
};

constexpr int kMaxClosures = 8;

struct Material {
  // Closure 0 (the one image textures drive).
  ClosureKind kind = ClosureKind::Principled;
  float weight = 1.0f;
  vec3 base_color{0.8f};
  float metallic = 0.0f;
  float roughness = 0.5f;
  float specular = 0.5f;
  float ior = 1.45f;
  float transmission = 0.0f;
  ShadingModel model = ShadingModel::Cycles3;
  bool multiscatter = false;
  vec3 specular_tint{1.0f};
  float coat = 0.0f, coat_roughness = 0.03f, coat_ior = 1.5f;
  vec3 coat_tint{1.0f};
  float diffuse_roughness = 0.0f;
  // Principled Alpha of closure 0 (Cycles: a transparent closure of weight
  // weight x (1 - alpha), and closure 0 scaled by alpha). The add-on folds a
  // constant alpha into the weights; this is for an alpha read per texel.
  float alpha = 1.0f;
  // Closures 1 .. num_more.
  uint32_t num_more = 0;
  Closure more[kMaxClosures - 1];

  vec3 emission_front{0.0f};  // radiance leaving the front face (colour x strength)
  vec3 emission_back{0.0f};   // ... and the back face

  // Inputs of closure 0 driven by image textures (sampled with the mesh's UV map).
  TextureRef base_color_tex, metallic_tex, roughness_tex, emission_tex, alpha_tex;
  TextureRef normal_tex;       // tangent-space normal map
  float normal_strength = 1.0f;
  float emission_strength_front = 1.0f, emission_strength_back = 0.0f;  // for emission_tex

  int num_closures() const { return 1 + int(num_more); }
  Closure closure(int i) const {
    if (i > 0) return more[i - 1];
    Closure c;
    c.kind = kind;
    c.weight = weight;
    c.color = base_color;
    c.metallic = metallic;
    c.roughness = roughness;
    c.specular = specular;
    c.ior = ior;
    c.transmission = transmission;
    c.model = model;
    c.multiscatter = multiscatter;
    c.specular_tint = specular_tint;
    c.coat = coat;
    c.coat_roughness = coat_roughness;
    c.coat_ior = coat_ior;
    c.coat_tint = coat_tint;
    c.diffuse_roughness = diffuse_roughness;
    return c;
  }
  // Makes c closure 0 (its fields; the textures stay).
  void set_first_closure(const Closure& c) {
    kind = c.kind, weight = c.weight, base_color = c.color, metallic = c.metallic, roughness = c.roughness;
    specular = c.specular, ior = c.ior, transmission = c.transmission, model = c.model;
    multiscatter = c.multiscatter, specular_tint = c.specular_tint, coat = c.coat;
    coat_roughness = c.coat_roughness, coat_ior = c.coat_ior, coat_tint = c.coat_tint;
    diffuse_roughness = c.diffuse_roughness;
  }
  bool add_closure(const Closure& c) {
    if (num_more >= kMaxClosures - 1) return false;
    more[num_more++] = c;
    return true;
  }

  bool has_textures() const {
    return base_color_tex.valid() || metallic_tex.valid() || roughness_tex.valid() || emission_tex.valid() ||
           normal_tex.valid() || alpha_tex.valid();
  }

  // Whether rays can pass through the surface (a Transparent closure or a
  // Principled Alpha below 1): the integrator then needs transparent shadows.
  bool may_be_transparent() const {
    if (alpha_tex.valid() || (alpha < 1.0f && weight > 0.0f) || (kind == ClosureKind::Transparent && weight > 0.0f))
      return true;
    for (uint32_t i = 0; i < num_more; ++i)
      if (more[i].kind == ClosureKind::Transparent && more[i].weight > 0.0f) return true;
    return false;
  }
  // What a shadow ray keeps when it passes the surface: the sum of the
  // transparent closures' weights (Cycles' shader_bsdf_transparency).
  vec3 transparency() const {
    const float a = std::clamp(alpha, 0.0f, 1.0f);
    vec3 t(std::max(weight, 0.0f) * (1.0f - a));
    if (kind == ClosureKind::Transparent) t += glm::clamp(base_color, vec3(0.0f), vec3(1.0f)) * (std::max(weight, 0.0f) * a);
    for (uint32_t i = 0; i < num_more; ++i)
      if (more[i].kind == ClosureKind::Transparent)
        t += glm::clamp(more[i].color, vec3(0.0f), vec3(1.0f)) * std::max(more[i].weight, 0.0f);
    return glm::min(t, vec3(1.0f));
  }

  bool is_emissive() const {
    return max_component(emission_front) > 0.0f || max_component(emission_back) > 0.0f ||
           (emission_tex.valid() && (emission_strength_front > 0.0f || emission_strength_back > 0.0f));
  }
  vec3 emission(bool back_face) const { return back_face ? emission_back : emission_front; }
};

}  // namespace tessera
