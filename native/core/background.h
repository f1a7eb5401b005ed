// The world: a constant colour or an equirectangular environment image
// (Blender's Environment Texture, with an optional rotation from a Mapping
// node), times the Background strength. The image is importance-sampled by
// its luminance times sin(theta) (pbrt-v4, 12.5.2).
#pragma once
#include <vector>
#include "sampling.h"
#include "visibility.h"

namespace tessera {

class Background {
 public:
  // Constant world.
  void set_color(const vec3& c) { color_ = c; }
  // Environment image: width x height RGB floats, rows bottom to top as
  // Blender stores them; rotation maps world directions into texture space.
  void set_image(std::vector<vec3> pixels, int width, int height, const glm::mat3& rotation, const vec3& strength);

  bool emits() const { return has_image_ ? max_component(strength_) > 0.0f : max_component(color_) > 0.0f; }
  bool has_image() const { return has_image_; }
  vec3 Le(const vec3& dir) const { return Le(dir, nullptr); }
  // Le, and when pdf is given also the density sample() has for dir: one
  // direction-to-texture mapping for both (a ray that escapes needs both).
  vec3 Le(const vec3& dir, float* pdf) const;
  // A direction by importance, its density (solid angle) and, when le is
  // given, the radiance from it.
  bool sample(vec2 u, vec3* wi, float* pdf, vec3* le = nullptr) const;
  float pdf(const vec3& wi) const;
  float average_luminance() const;
  // World Properties > Ray Visibility (visibility.h): the ray kinds that see
  // the world when they escape, and that it lights.
  void set_visibility(uint8_t v) { visibility_ = v & (kRayCamera | kScatteredRays); }
  bool seen_by(RayKind kind) const { return visibility_ & kind; }
  uint8_t visibility() const { return visibility_; }

 private:
  // Texture coordinates and back, each with the sin of the polar angle
  // that the density's Jacobian needs.
  vec2 direction_to_uv(const vec3& dir, float* sin_theta) const;
  vec3 uv_to_direction(vec2 uv, float* sin_theta) const;
  vec3 lookup(vec2 uv) const;
  float pdf_uv(vec2 uv, float sin_theta) const;

  uint8_t visibility_ = kRayCamera | kScatteredRays;
  vec3 color_{0.0f};
  bool has_image_ = false;
  std::vector<vec3> pixels_;
  int width_ = 0, height_ = 0;
  glm::mat3 rotation_{1.0f};
  vec3 strength_{1.0f};
  Distribution1D marginal_;                // over rows
  std::vector<Distribution1D> conditional_; // per row, over columns
};

}  // namespace tessera
