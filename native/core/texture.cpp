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
    // max(0, x) first: NaN becomes 0. The value is in [0.5, 255.5], so the
    // signed conversion truncates as the unsigned one would, and the loop
    // vectorises (SSE2 has no float-to-unsigned conversion).
    for (size_t i = r.begin(); i < r.end(); ++i) {
      uint32_t packed = 0;
      for (int c = 0; c < 4; ++c) {
        const float v = std::min(std::max(0.0f, rgba[4 * i + c]), 1.0f) * 255.0f + 0.5f;
        packed |= uint32_t(int32_t(v)) << (8 * c);
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


namespace {
// The index of texel (x, y) of a w x h grid under extension mode e; -1 where
// Clip leaves the image.
inline long texel_index(int x, int y, int w, int h, Texture::Extension e) {
  switch (e) {
    case Texture::Extension::Repeat:
      // Integer division only off the image: eval() brings uv into [0, 1),
      // so nearly every texel is inside already (four divisions per texel,
      // sixteen per bilinear lookup, were most of the texture time).
      if (uint32_t(x) >= uint32_t(w)) x = ((x % w) + w) % w;
      if (uint32_t(y) >= uint32_t(h)) y = ((y % h) + h) % h;
      break;
    case Texture::Extension::Mirror: {
      auto mirror = [](int i, int n) {
        int period = 2 * n;
        i = ((i % period) + period) % period;
        return i < n ? i : period - 1 - i;
      };
      x = mirror(x, w);
      y = mirror(y, h);
      break;
    }
    case Texture::Extension::Extend:
      x = std::clamp(x, 0, w - 1);
      y = std::clamp(y, 0, h - 1);
      break;
    case Texture::Extension::Clip:
      if (x < 0 || y < 0 || x >= w || y >= h) return -1;
      break;
  }
  return long(y) * w + x;
}

// uv's position *p on a w x h grid (texel centres at half-integers) under
// extension mode e; false where the lookup is 0: a non-finite uv, or off the
// image under Clip. Repeat first brings uv into [0, 1), keeping coordinates
// small before they become ints (repeat is periodic anyway).
inline bool grid_position(vec2 uv, int w, int h, Texture::Extension e, vec2* p) {
  if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) return false;
  if (e == Texture::Extension::Clip && (uv.x < 0.0f || uv.x > 1.0f || uv.y < 0.0f || uv.y > 1.0f)) return false;
  if (e == Texture::Extension::Repeat) uv -= glm::floor(uv);
  *p = vec2(uv.x * w, uv.y * h);
  return true;
}

// Bilinear interpolation of texel(x, y) around grid position p.
template <class Texel>
inline vec4 bilinear(vec2 p, const Texel& texel) {
  const float fx = p.x - 0.5f, fy = p.y - 0.5f;
  const int ix = int(std::floor(fx)), iy = int(std::floor(fy));
  const float tx = fx - ix, ty = fy - iy;
  return (1 - ty) * ((1 - tx) * texel(ix, iy) + tx * texel(ix + 1, iy)) +
         ty * ((1 - tx) * texel(ix, iy + 1) + tx * texel(ix + 1, iy + 1));
}
}  // namespace

vec4 Texture::texel(int x, int y) const {
  const long i = texel_index(x, y, width, height, extension);
  return i < 0 ? vec4(0.0f) : texel_at(size_t(i));
}

void Texture::set_diffuse_blur(float blur) {
  coarse.clear();
  coarse_width = coarse_height = 0;
  if (!(blur > 0.0f) || width <= 0 || height <= 0) return;
  const int n = int(std::min(std::ceil(1.0f / std::min(blur, 1.0f)), 65536.0f));
  if (n >= width && n >= height) return;  // no coarser than the image
  const int cw = std::min(n, width), ch = std::min(n, height);
  coarse.resize(size_t(cw) * size_t(ch));
  // Coarse texel (cx, cy) covers uv [cx / cw, (cx + 1) / cw) x [cy / ch, (cy + 1) / ch):
  // it is the mean of the image's texels x in [ceil(cx W / cw), ceil((cx + 1) W / cw)),
  // likewise in y: at least one each way and inside the image, as cw <= W and ch <= H.
  auto first = [](int c, int size, int coarse_size) { return int((int64_t(c) * size + coarse_size - 1) / coarse_size); };
  tbb::parallel_for(tbb::blocked_range<int>(0, ch), [&](const tbb::blocked_range<int>& r) {
    for (int cy = r.begin(); cy < r.end(); ++cy) {
      const int y0 = first(cy, height, ch), y1 = first(cy + 1, height, ch);
      for (int cx = 0; cx < cw; ++cx) {
        const int x0 = first(cx, width, cw), x1 = first(cx + 1, width, cw);
        glm::dvec4 sum(0.0);
        for (int y = y0; y < y1; ++y)
          for (int x = x0; x < x1; ++x) sum += glm::dvec4(texel_at(size_t(y) * width + x));
        const double count = double(y1 - y0) * double(x1 - x0);
        coarse[size_t(cy) * cw + cx] = vec4(sum / count);
      }
    }
  });
  coarse_width = cw, coarse_height = ch;
}

vec4 Texture::eval_coarse(vec2 uv) const {
  vec2 p;
  if (!grid_position(uv, coarse_width, coarse_height, extension, &p)) return vec4(0.0f);
  auto texel = [&](int x, int y) {
    const long i = texel_index(x, y, coarse_width, coarse_height, extension);
    return i < 0 ? vec4(0.0f) : coarse[size_t(i)];
  };
  // Closest stays closest; Linear and Cubic filter the blurred level linearly.
  if (interpolation == Interpolation::Closest) return texel(int(std::floor(p.x)), int(std::floor(p.y)));
  return bilinear(p, texel);
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
  vec2 p;
  if (!grid_position(uv, width, height, extension, &p)) return vec4(0.0f);
  if (interpolation == Interpolation::Closest) return texel(int(std::floor(p.x)), int(std::floor(p.y)));
  if (interpolation == Interpolation::Linear) return bilinear(p, [this](int x, int y) { return texel(x, y); });
  const float fx = p.x - 0.5f, fy = p.y - 0.5f;
  const int ix = int(std::floor(fx)), iy = int(std::floor(fy));
  const float tx = fx - ix, ty = fy - iy;
  float wx[4], wy[4];
  cubic_weights(tx, wx);
  cubic_weights(ty, wy);
  vec4 sum(0.0f);
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) sum += wx[i] * wy[j] * texel(ix - 1 + i, iy - 1 + j);
  return sum;
}

}  // namespace tessera
