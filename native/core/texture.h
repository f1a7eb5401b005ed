// Image textures as Blender's Image Texture node samples them: closest /
// linear / cubic interpolation, repeat / extend / clip / mirror extension.
// UV (0,0) is the bottom-left corner, as Blender stores image rows bottom to
// top. Float images keep linear RGBA floats; 8-bit images keep their bytes
// (a quarter of the memory, as Cycles' byte textures) and are converted to
// linear per texel through a 256-entry table: sRGB, or k / 255 for data.
#pragma once
#include <cstdint>
#include <vector>
#include "math.h"

namespace tessera {

struct Texture {
  enum class Interpolation : uint32_t { Closest, Linear, Cubic };
  enum class Extension : uint32_t { Repeat, Extend, Clip, Mirror };
  int width = 0, height = 0;
  std::vector<vec4> texels;     // float images: linear RGBA, rows bottom to top
  std::vector<uint32_t> bytes;  // 8-bit images: RGBA bytes (R lowest), rows bottom to top
  bool srgb = false;            // 8-bit colour in sRGB (else linear k / 255)
  Interpolation interpolation = Interpolation::Linear;
  Extension extension = Extension::Repeat;

  // Diffuse texture blur (as Cycles' texture cache, texture_blur_diffuse):
  // what paths see after a diffuse bounce is the image box-filtered over
  // `blur` of its width and height, stored as its own small level of
  // coarse_width x coarse_height linear texels, each the mean of the image's
  // texels under it. Such paths integrate over far more of the surface than
  // a texel, so the level changes their estimate at second order, and its
  // few kilobytes stay in cache where the image's texels, fetched at random
  // from a diffuse bounce, miss it. Empty when the blur asks for nothing
  // coarser than the image.
  int coarse_width = 0, coarse_height = 0;
  std::vector<vec4> coarse;

  vec4 eval(vec2 uv) const;
  // eval() as seen after a diffuse bounce: from the coarse level if there is one.
  vec4 eval(vec2 uv, bool diffuse) const { return diffuse && !coarse.empty() ? eval_coarse(uv) : eval(uv); }
  // Stores Blender's float read-back of an 8-bit image (exactly k / 255 per
  // channel) as bytes, in parallel.
  void set_bytes(const float* rgba, int w, int h, bool is_srgb);
  // Builds the coarse level for a blur of `blur` (a fraction of the image's
  // size: ceil(1 / blur) texels across, if fewer than the image has; 0: none).
  void set_diffuse_blur(float blur);
  // Mean linear RGBA over the texels.
  vec4 average() const;

 private:
  vec4 eval_coarse(vec2 uv) const;
  vec4 texel(int x, int y) const;
  vec4 texel_at(size_t i) const;
};

// Linear value of each byte: [0] k / 255, [1] sRGB's EOTF (IEC 61966-2-1);
// filled when the module loads (texture.cpp).
extern float kByteToLinear[2][256];

inline vec4 Texture::texel_at(size_t i) const {
  if (bytes.empty()) return texels[i];
  const uint32_t b = bytes[i];
  const float* t = kByteToLinear[srgb ? 1 : 0];
  return vec4(t[b & 0xff], t[(b >> 8) & 0xff], t[(b >> 16) & 0xff], kByteToLinear[0][b >> 24]);
}

}  // namespace tessera
