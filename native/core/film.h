// Pixel filter and film. The filter is importance-sampled (Ernst et al.
// 2006, "Filter importance sampling"), as Cycles does, so every sample has
// weight one and a pixel's value is the plain mean of its samples.
#pragma once
#include <vector>
#include "math.h"
#include "passes.h"

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

namespace tessera {

// Per-pixel accumulation: the sum of all samples, the sum of the odd-indexed
// samples (Cycles' "A" half, for the error estimate), the sample count and
// whether adaptive sampling still wants samples. A pixel is only ever written
// by the tile that owns it.
class Film {
 public:
  void resize(size_t num_pixels);
  size_t size() const { return sum_.size(); }

  void add(size_t i, int sample, const vec3& L) {
    sum_[i] += L;
    if (sample & 1) sum_odd_[i] += L;
  }
  void set_count(size_t i, int n) { count_[i] = n; }
  int count(size_t i) const { return count_[i]; }
  bool active(size_t i) const { return active_[i] != 0; }
  void deactivate(size_t i) { active_[i] = 0; }
  vec3 mean(size_t i) const { return count_[i] > 0 ? sum_[i] / float(count_[i]) : vec3(0.0f); }

  // Cycles' adaptive sampling error of one pixel (film_adaptive_sampling_
  // convergence_check, after Dammertz et al. 2010): |full - half| summed over
  // RGB, normalised by sqrt of the RGB sum.
  float pixel_error(size_t i) const;
  // Estimated variance of the pixel's mean, per channel, from the two halves:
  // Var(mean) = (mean_odd - mean_even)^2 n_odd n_even / n^2 (unbiased for
  // independent samples). Zero below two samples.
  vec3 mean_variance(size_t i) const;
  // Estimated relative RMSE of the image: sqrt(mean of mean_variance over
  // pixels and channels) / mean pixel value.
  double estimated_relative_error() const;

 private:
  std::vector<vec3> sum_, sum_odd_;
  std::vector<int> count_;
  std::vector<uint8_t> active_;
};

}  // namespace tessera

namespace tessera {

// Per-pixel sums of the enabled data passes (passes.h), one buffer per pass,
// none allocated for a pass that is off. Written like Film: a pixel only by
// the tile that owns it.
class DataPasses {
 public:
  // Allocates the buffers of the passes in mask for num_pixels pixels.
  void configure(uint32_t mask, size_t num_pixels, const Camera& camera);
  uint32_t mask() const { return mask_; }

  // Adds one sample's record; a sample that hit nothing adds nothing.
  void add(size_t i, const FirstHit& h);
  // The pass's value at pixel i over n samples: pass_channels(pass) floats.
  void resolve(size_t i, int n, uint32_t pass, float* out) const;

 private:
  uint32_t mask_ = 0;
  vec3 camera_origin_{0.0f}, camera_x_{1, 0, 0}, camera_y_{0, 1, 0}, camera_forward_{0, 0, -1};
  std::vector<float> depth_, denoising_depth_;
  std::vector<vec3> normal_, diffuse_color_, emission_, denoising_normal_, denoising_albedo_;
};

}  // namespace tessera
