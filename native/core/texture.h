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

  vec4 eval(vec2 uv) const;
  // Stores Blender's float read-back of an 8-bit image (exactly k / 255 per
  // channel) as bytes, in parallel.
  void set_bytes(const float* rgba, int w, int h, bool is_srgb);
  // Mean linear RGBA over the texels.
  vec4 average() const;

 private:
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
