// Pixel filter and film. The filter is importance-sampled (Ernst et al.
// 2006, "Filter importance sampling"), as Cycles does, so every sample has
// weight one and a pixel's value is the plain mean of its samples.
#pragma once
#include <vector>
#include "math.h"

namespace tessera {

class PixelFilter {
 public:
  explicit PixelFilter(float width);
  // Offset from the pixel centre, in pixels.
  vec2 sample(vec2 u) const { return vec2(warp(u.x), warp(u.y)); }

 private:
  float warp(float u) const;
  std::vector<float> inverse_cdf_;  // tabulated, 1D and separable
};

}  // namespace tessera
