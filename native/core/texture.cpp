#include "texture.h"

namespace tessera {

vec4 Texture::texel(int x, int y) const {
  switch (extension) {
    case Extension::Repeat:
      x = ((x % width) + width) % width;
      y = ((y % height) + height) % height;
      break;
    case Extension::Mirror: {
      auto mirror = [](int i, int n) {
        int period = 2 * n;
        i = ((i % period) + period) % period;
        return i < n ? i : period - 1 - i;
      };
      x = mirror(x, width);
      y = mirror(y, height);
      break;
    }
    case Extension::Extend:
      x = std::clamp(x, 0, width - 1);
      y = std::clamp(y, 0, height - 1);
      break;
    case Extension::Clip:
      if (x < 0 || y < 0 || x >= width || y >= height) return vec4(0.0f);
      break;
  }
  return texels[size_t(y) * width + x];
}

// Catmull-Rom-like cubic B-spline weights as Cycles uses for Cubic (a uniform
// cubic B-spline, which smooths slightly).
static void cubic_weights(float t, float w[4]) {
  float t2 = t * t, t3 = t2 * t;
  w[0] = (1.0f / 6.0f) * (-t3 + 3 * t2 - 3 * t + 1);
  w[1] = (1.0f / 6.0f) * (3 * t3 - 6 * t2 + 4);
  w[2] = (1.0f / 6.0f) * (-3 * t3 + 3 * t2 + 3 * t + 1);
  w[3] = (1.0f / 6.0f) * t3;
}

vec4 Texture::eval(vec2 uv) const {
  if (width <= 0 || height <= 0) return vec4(1.0f, 0.0f, 1.0f, 1.0f);  // Blender's missing-image pink
  if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) return vec4(0.0f);
  if (extension == Extension::Clip && (uv.x < 0.0f || uv.x > 1.0f || uv.y < 0.0f || uv.y > 1.0f)) return vec4(0.0f);
  // Keep coordinates small before converting to int (repeat is periodic anyway).
  if (extension == Extension::Repeat) uv -= glm::floor(uv);
  const float x = uv.x * width, y = uv.y * height;
  if (interpolation == Interpolation::Closest) return texel(int(std::floor(x)), int(std::floor(y)));
  const float fx = x - 0.5f, fy = y - 0.5f;
  const int ix = int(std::floor(fx)), iy = int(std::floor(fy));
  const float tx = fx - ix, ty = fy - iy;
  if (interpolation == Interpolation::Linear) {
    return (1 - ty) * ((1 - tx) * texel(ix, iy) + tx * texel(ix + 1, iy)) +
           ty * ((1 - tx) * texel(ix, iy + 1) + tx * texel(ix + 1, iy + 1));
  }
  float wx[4], wy[4];
  cubic_weights(tx, wx);
  cubic_weights(ty, wy);
  vec4 sum(0.0f);
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) sum += wx[i] * wy[j] * texel(ix - 1 + i, iy - 1 + j);
  return sum;
}

}  // namespace tessera
