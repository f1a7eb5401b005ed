#include "texture.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

namespace tessera {

float kByteToLinear[2][256];

namespace {
const bool kByteTablesFilled = [] {
  for (int k = 0; k < 256; ++k) {
    const double c = k / 255.0;
    kByteToLinear[0][k] = float(c);
    kByteToLinear[1][k] = float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
  }
  return true;
}();
}  // namespace

void Texture::set_bytes(const float* rgba, int w, int h, bool is_srgb) {
  width = w, height = h, srgb = is_srgb;
  texels.clear();
  bytes.resize(size_t(w) * size_t(h));
  tbb::parallel_for(tbb::blocked_range<size_t>(0, bytes.size(), 1 << 14), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      uint32_t packed = 0;
      for (int c = 0; c < 4; ++c) {
        const float v = std::clamp(rgba[4 * i + c], 0.0f, 1.0f) * 255.0f + 0.5f;
        packed |= uint32_t(v) << (8 * c);
      }
      bytes[i] = packed;
    }
  });
}

vec4 Texture::average() const {
  const size_t n = bytes.empty() ? texels.size() : bytes.size();
  if (n == 0) return vec4(0.0f);
  const glm::dvec4 sum = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, n, 1 << 14), glm::dvec4(0.0),
      [&](const tbb::blocked_range<size_t>& r, glm::dvec4 acc) {
        for (size_t i = r.begin(); i < r.end(); ++i)
          acc += glm::dvec4(bytes.empty() ? texels[i] : texel_at(i));
        return acc;
      },
      [](const glm::dvec4& a, const glm::dvec4& b) { return a + b; });
  return vec4(sum / double(n));
}


vec4 Texture::texel(int x, int y) const {
  switch (extension) {
    case Extension::Repeat:
      // Integer division only off the image: eval() brings uv into [0, 1),
      // so nearly every texel is inside already (four divisions per texel,
      // sixteen per bilinear lookup, were most of the texture time).
      if (uint32_t(x) >= uint32_t(width)) x = ((x % width) + width) % width;
      if (uint32_t(y) >= uint32_t(height)) y = ((y % height) + height) % height;
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
  return texel_at(size_t(y) * width + x);
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
