#include "film.h"

#include <type_traits>

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

namespace tessera {

void Film::resize(int width, int height, bool estimate_error) {
  const size_t n = size_t(width) * size_t(height);
  width_ = width;
  sum_.assign(n, vec3(0.0f));
  sum_a_.assign(n, vec3(0.0f));
  sum_sq_.assign(n, 0.0);
  max_.assign(n, vec3(0.0f));
  count_.assign(n, 0);
  active_.assign(n, 1);
  // The widest grid that still has kMinReplicatePixels pixels (all pixels
  // of a tiny image): a 1080p frame replicates 1/256 of its pixels, 120 x
  // 68 pixels 1/16 (with 512 it was 1/4 there: 25% more samples).
  stride_ = 1;
  while (stride_ < kMaxReplicateStride &&
         size_t((width + 2 * stride_ - 1) / (2 * stride_)) * ((height + 2 * stride_ - 1) / (2 * stride_)) >=
             size_t(kMinReplicatePixels))
    stride_ *= 2;
  replicate_columns_ = (width + stride_ - 1) / stride_;
  replicate_sum_.assign(estimate_error ? size_t(replicate_columns_) * ((height + stride_ - 1) / stride_) : 0,
                        vec3(0.0f));
  replicate_max_.assign(replicate_sum_.size(), vec3(0.0f));
}

float Film::pixel_error(size_t i) const {
  const int n = count_[i];
  const int n_a = class_a_count(n);
  if (n_a == 0) return kInf;
  const vec3 full = sum_[i] / float(n), half = sum_a_[i] / float(n_a);
  const vec3 d = glm::abs(full - half);
  const float norm = std::sqrt(std::max(0.0f, full.x + full.y + full.z));
  return (d.x + d.y + d.z) / (1e-4f + norm);
}

double Film::sample_variance(size_t i) const {
  const int n = count_[i];
  if (n < 2) return 0.0;
  const vec3 m = sum_[i] / float(n);
  const double mean_sq = double(m.x) * m.x + double(m.y) * m.y + double(m.z) * m.z;
  return std::max(0.0, (sum_sq_[i] - n * mean_sq) / double(n - 1));
}

// The image's mean variance per pixel and channel in two parts.
//
// Fireflies: a pixel's brightest sample, when it is over the threshold
// (firefly_threshold x the image's mean pixel value, RGB summed) and over
// twice the sum of all its other samples, is a rare event that the pixel's
// mean carries as (brightest - mean of the others) / n of error: counted as
// that, from every pixel. Such samples are few, land on few pixels and so
// swing one image's error; the replicate grid (1/16 of the pixels or fewer)
// saw them or missed them by chance (estimate/true 0.24-1.38 on
// bunny_glass.blend at 16-128 spp with the grid alone, 0.92-1.40 with the
// term: docs/convergence/ADAPTIVE.md). A looser test (over 4x the mean of
// the other samples) also took the edges of directly seen lights for
// fireflies (1.8x on cbox_mitsuba.blend at 16 spp).
//
// The rest: the replicated pixels' (x1 - x2)^2 / 2 with each side's firefly
// taken out (unbiased for the variance of a pixel's mean: x1, x2 are
// independent estimates of it), over the replicate grid as a systematic
// sample of the image. Scaling the cheap half-buffer estimates of all pixels
// by the replicates' ratio instead was biased either way on the shared
// scenes (0.5-0.9x on McGuire's Cornell box, where a few firefly pixels carry
// the error and the Sobol points' gain differs from pixel to pixel; per-group
// ratios 2.4-4.3x on the Mitsuba box).
double Film::estimated_relative_error(double firefly_threshold) const {
  if (replicate_sum_.empty()) return 0.0;
  double mean = 0.0;
  for (size_t i = 0; i < sum_.size(); ++i) {
    const vec3 m = this->mean(i);
    mean += double(m.x) + m.y + m.z;
  }
  const double n_pixels = double(sum_.size());
  if (mean <= 0.0) return 0.0;
  const double threshold = firefly_threshold > 0.0 ? firefly_threshold * mean / n_pixels : kInf;
  // A pixel's firefly: its brightest sample when it is over the threshold and
  // over twice the sum of all the pixel's other samples.
  auto firefly = [&](const vec3& sum, const vec3& max, int n) {
    if (n < 2) return false;
    const double s = double(max.x) + max.y + max.z;
    const vec3 rest = sum - max;
    return s > threshold && s > kFireflyDominance * (double(rest.x) + rest.y + rest.z);
  };
  double replicated = 0.0, fireflies = 0.0;
  size_t replicates = 0;
  for (size_t i = 0; i < sum_.size(); ++i) {
    const int n = count_[i];
    if (n == 0) continue;
    const bool ff = firefly(sum_[i], max_[i], n);
    if (ff) {
      const vec3 rest = (sum_[i] - max_[i]) / float(n - 1);
      const vec3 d = (max_[i] - rest) / float(n);
      fireflies += double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z;
    }
    const int slot = replicate_slot(int(i % size_t(width_)), int(i / size_t(width_)));
    if (slot < 0) continue;
    const vec3& rsum = replicate_sum_[size_t(slot)];
    const vec3& rmax = replicate_max_[size_t(slot)];
    const bool rff = firefly(rsum, rmax, n);
    // Without their fireflies (counted above, from every pixel).
    const vec3 m1 = ff ? (sum_[i] - max_[i]) / float(n - 1) : sum_[i] / float(n);
    const vec3 m2 = rff ? (rsum - rmax) / float(n - 1) : rsum / float(n);
    const vec3 d = m1 - m2;
    replicated += 0.5 * (double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z);
    ++replicates;
  }
  if (replicates == 0) return 0.0;
  const double variance = (replicated / double(replicates) + fireflies / n_pixels) / 3.0;
  return std::sqrt(variance) / (mean / (3.0 * n_pixels));
}

}  // namespace tessera

namespace tessera {

void DataPasses::configure(uint32_t mask, size_t n, const Camera& camera) {
  mask_ = mask & kPassAllData;
  auto size = [&](uint32_t pass, auto& buffer) {
    using T = typename std::decay_t<decltype(buffer)>::value_type;
    buffer.assign((mask_ & pass) ? n : 0, T(0.0f));
  };
  size(kPassDepth, depth_);
  size(kPassDenoisingDepth, denoising_depth_);
  depth_count_.assign((mask_ & kPassDepth) ? n : 0, 0);
  size(kPassNormal, normal_);
  size(kPassDiffuseColor, diffuse_color_);
  size(kPassEmission, emission_);
  size(kPassDenoisingNormal, denoising_normal_);
  size(kPassDenoisingAlbedo, denoising_albedo_);
  // Camera space as Cycles' (x right, y up, z forward): Blender's camera
  // looks down its -z.
  camera_origin_ = vec3(camera.to_world[3]);
  camera_x_ = glm::normalize(vec3(camera.to_world[0]));
  camera_y_ = glm::normalize(vec3(camera.to_world[1]));
  camera_forward_ = -glm::normalize(vec3(camera.to_world[2]));
}

void DataPasses::add(size_t i, const FirstHit& h) {
  if (h.hit) {
    // Cycles' camera_z_depth: the hit's z in camera space.
    if (mask_ & kPassDepth) {
      depth_[i] += glm::dot(h.position - camera_origin_, camera_forward_);
      ++depth_count_[i];
    }
    if (mask_ & kPassNormal) normal_[i] += h.normal;
    if (mask_ & kPassDiffuseColor) diffuse_color_[i] += h.diffuse_color;
    if (mask_ & kPassEmission) emission_[i] += h.emission;
  }
  // Denoising features: the normal and depth where the feature vertex was
  // found, the albedo also from emission and world seen before it.
  const vec3 n = h.denoising_normal;
  if (mask_ & kPassDenoisingNormal)
    denoising_normal_[i] += vec3(glm::dot(n, camera_x_), glm::dot(n, camera_y_), glm::dot(n, camera_forward_));
  if (mask_ & kPassDenoisingAlbedo) denoising_albedo_[i] += h.denoising_albedo;
  if (mask_ & kPassDenoisingDepth) denoising_depth_[i] += h.denoising_depth;
}

void DataPasses::resolve(size_t i, int n, uint32_t pass, float* out) const {
  const float scale = n > 0 ? 1.0f / float(n) : 0.0f;
  auto put3 = [&](const std::vector<vec3>& b) {
    const vec3 v = b[i] * scale;
    out[0] = v.x, out[1] = v.y, out[2] = v.z;
  };
  switch (pass) {
    case kPassDepth:
      // Cycles' film_get_pass_pixel_depth: 1e10 where no sample hit anything.
      // The mean over the samples that found a surface (Cycles keeps its
      // first sample's): samples that missed, or scattered off a surface
      // below the pass alpha threshold, would pull it towards 0.
      out[0] = depth_count_[i] == 0 ? 1e10f : depth_[i] / float(depth_count_[i]);
      break;
    case kPassDenoisingDepth: out[0] = denoising_depth_[i] * scale; break;
    case kPassNormal: put3(normal_); break;
    case kPassDiffuseColor: put3(diffuse_color_); break;
    case kPassEmission: put3(emission_); break;
    case kPassDenoisingNormal: put3(denoising_normal_); break;
    case kPassDenoisingAlbedo: put3(denoising_albedo_); break;
    default: break;
  }
}

}  // namespace tessera
