#include "film.h"

namespace tessera {

// Blackman-Harris window over [-width/2, width/2] (Cycles' filter_func_blackman_harris).
static float blackman_harris(float x, float width) {
  float t = 2.0f * kPi * (x / width + 0.5f);
  return 0.35875f - 0.48829f * std::cos(t) + 0.14128f * std::cos(2 * t) - 0.01168f * std::cos(3 * t);
}

PixelFilter::PixelFilter(float width) {
  constexpr int kTable = 256, kSteps = 4096;
  // Cycles stretches the Blackman-Harris window over twice the filter width
  // (film.cpp, filter_table), so 1.5 px spans 3 px; match its look.
  width = 2.0f * std::max(width, 1e-3f);
  std::vector<double> cdf(kSteps + 1, 0.0);
  for (int i = 0; i < kSteps; ++i) {
    float x = -0.5f * width + width * (i + 0.5f) / kSteps;
    cdf[i + 1] = cdf[i] + std::max(0.0f, blackman_harris(x, width));
  }
  inverse_cdf_.resize(kTable);
  int j = 0;
  for (int i = 0; i < kTable; ++i) {
    double target = cdf[kSteps] * (i + 0.5) / kTable;
    while (j < kSteps && cdf[j + 1] < target) ++j;
    double frac = (target - cdf[j]) / std::max(1e-30, cdf[j + 1] - cdf[j]);
    inverse_cdf_[i] = float(-0.5 * width + width * (j + frac) / kSteps);
  }
}

float PixelFilter::warp(float u) const {
  float x = u * (inverse_cdf_.size() - 1);
  int i = std::min(int(x), int(inverse_cdf_.size()) - 2);
  float t = x - i;
  return (1 - t) * inverse_cdf_[i] + t * inverse_cdf_[i + 1];
}

}  // namespace tessera
