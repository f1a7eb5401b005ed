// Image textures as Blender's Image Texture node samples them: texels in
// linear RGBA (colour space converted once at export), closest / linear /
// cubic interpolation, repeat / extend / clip / mirror extension. UV (0,0)
// is the bottom-left corner, as Blender stores image rows bottom to top.
#pragma once
#include <vector>
#include "math.h"

namespace tessera {

struct Texture {
  enum class Interpolation : uint32_t { Closest, Linear, Cubic };
  enum class Extension : uint32_t { Repeat, Extend, Clip, Mirror };
  int width = 0, height = 0;
  std::vector<vec4> texels;  // rows bottom to top
  Interpolation interpolation = Interpolation::Linear;
  Extension extension = Extension::Repeat;

  vec4 eval(vec2 uv) const;

 private:
  vec4 texel(int x, int y) const;
};

}  // namespace tessera
