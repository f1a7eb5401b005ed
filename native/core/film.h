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
  // The density of one coordinate of sample() at offset x (per pixel): the
  // warp is piecewise linear, so its density is piecewise constant.
  float density(float x) const;
  float radius() const { return -inverse_cdf_.front(); }

 private:
  float warp(float u) const;
  std::vector<float> inverse_cdf_;  // tabulated, 1D and separable
};

}  // namespace tessera

namespace tessera {

// Per-pixel accumulation: the sum of all samples, the sum of the class-A
// samples (half of them, for adaptive sampling), the sample count and
// whether adaptive sampling still wants samples. A pixel is only ever written
// by the tile that owns it.
//
// The image-wide error estimate. All of a pixel's samples come from one
// Owen-scrambled Sobol stream, whose mean converges faster than independent
// samples would, so a pixel's own samples cannot tell its error: the
// difference of two halves of one stream overestimated it 1.2-4.7x on the
// shared scenes. Independent replicates measure it: a regular grid of pixels
// (every stride-th column and row, at least kMinReplicatePixels of them)
// also renders the same samples from an independently scrambled stream, kept
// apart from the image. The grid is a systematic sample of the image, which
// misses error that sits on a few pixels (a small bright light seen directly
// puts nearly all of veach_mis.blend's error on ~10 pixels), so replicates
// also follow the error: from each estimate on, the pixels near a bright
// sample with the largest sample variance over n get kFollowStreams
// replicate streams each (as many streams as the grid has, at most), traced
// from sample 0 (catching up when the pixel is followed). Their mean is a
// reference for this image's pixel, not only for its expected error
// (film.cpp). The other pixels near a bright sample count a systematic
// sample of them (kNearStratumPixels, one stream each, the grid's there
// among them), which a sparse grid alone did not give.
class Film {
 public:
  static constexpr int kMinReplicatePixels = 256;
  static constexpr int kMaxReplicateStride = 16;
  static constexpr int kFollowStreams = 8;  // replicate streams of a followed pixel
  static constexpr double kFollowShare = 0.25;  // followed while the pixels near bright samples carry this much
  // The pixels near a bright sample that stand for the ones not followed:
  // the grid's there, and a systematic sample of the others (one stream
  // each) until they number this many (film.cpp).
  static constexpr int kNearStratumPixels = 128;

  // n = width * height pixels; replicates only with estimate_error; the
  // camera emission statistics only with camera_emission; the alpha sums only
  // with transparent_background (Film > Transparent).
  void resize(int width, int height, bool estimate_error, bool camera_emission = false,
              bool transparent_background = false);
  size_t size() const { return sum_.size(); }

  void add(size_t i, int sample, const vec3& L) {
    sum_[i] += L;
    sum_sq_[i] += double(L.x) * L.x + double(L.y) * L.y + double(L.z) * L.z;
    if (class_a(sample)) sum_a_[i] += L;
    if (L.x + L.y + L.z > max_[i].x + max_[i].y + max_[i].z) max_[i] = L, max_index_[i] = sample;
  }
  // The sample classes that adaptive sampling compares (Cycles'
  // sample_is_class_A, after Christensen et al. 2018, "Progressive
  // multi-jittered sample sequences", 10.2.1): the parity of the odd bits
  // of the sample index. Each class is itself well stratified in the
  // shuffled Sobol stream; odd against even indices would not be (the even
  // samples of a pixel all lie in one half of its footprint).
  static bool class_a(int sample) { return __builtin_popcount(uint32_t(sample) & 0xaaaaaaaaU) & 1; }
  // How many of the samples 0 .. n-1 are class A: two of every aligned four,
  // and of the partial four the pair whose bit 1 differs from the block's parity.
  static int class_a_count(int n) {
    const int q = n / 4, r = n % 4;
    return 2 * q + (class_a(4 * q) ? std::min(r, 2) : std::max(r - 2, 0));
  }
  void set_count(size_t i, int n) { count_[i] = n; }
  int count(size_t i) const { return count_[i]; }
  bool active(size_t i) const { return active_[i] != 0; }
  void deactivate(size_t i) { active_[i] = 0; }
  vec3 mean(size_t i) const { return count_[i] > 0 ? sum_[i] / float(count_[i]) : vec3(0.0f); }
  // Film > Transparent: a sample's weight where its camera ray saw the world
  // (Li's transparency); the pixel's alpha is 1 minus their mean.
  bool has_transparency() const { return !transparency_.empty(); }
  void add_transparency(size_t i, float t) { transparency_[i] += t; }
  float alpha(size_t i) const {
    return transparency_.empty() || count_[i] == 0 ? 1.0f : 1.0f - float(transparency_[i] / count_[i]);
  }

  // The replicate slot of pixel (x, y) of the film, or -1 if it has none:
  // the grid's pixels, and from each estimate on the pixels it chose to
  // follow. A slot has replicate_streams(slot) independently scrambled
  // streams (stream k: seed + (k + 1) kReplicateSeed, render.h), each with the
  // pixel's samples 0 .. replicate_samples(slot) - 1; the renderer brings
  // them up to the pixel's count (add_replicate, then set_replicate_samples).
  // Read by the tiles during a pass; slots are only added between passes.
  int replicate_slot(int x, int y) const {
    return slot_of_.empty() ? -1 : slot_of_[size_t(y) * size_t(width_) + size_t(x)];
  }
  int replicate_streams(int slot) const { return replicate_streams_[size_t(slot)]; }
  int replicate_samples(int slot) const { return replicate_samples_[size_t(slot)]; }
  void set_replicate_samples(int slot, int n) { replicate_samples_[size_t(slot)] = n; }
  void add_replicate(int slot, int stream, const vec3& L) {
    const size_t k = size_t(replicate_first_[size_t(slot)] + stream);
    replicate_sum_[k] += L;
    vec3& m = replicate_max_[k];
    if (L.x + L.y + L.z > m.x + m.y + m.z) m = L;
  }
  int replicate_stride() const { return stride_; }

  // Emitter antialiasing (render.cpp): per pixel, the emission its camera
  // rays found at their first surface (Li's camera_le), the rest of their
  // paths' radiance and the rays the paths traced, and the number of extra
  // camera rays each of its samples traces for that emission (0, or a power
  // of two once the pixel is split).
  bool has_camera_emission() const { return !le_stats_.empty(); }
  void add_camera_emission(size_t i, const vec3& le, const vec3& rest) {
    CameraEmissionStats& st = le_stats_[i];
    const float e = le.x + le.y + le.z, r = rest.x + rest.y + rest.z;
    st.sum_le += e;
    st.sum_le_sq += e * e;
    st.sum_le_rest += e * r;
    st.sum_rest_sq += r * r;
  }
  void add_path_rays(size_t i, uint64_t rays) { le_stats_[i].path_rays += float(rays); }
  // log2 of the extra camera rays per sample that make pixel i's error over
  // its time least, from its own samples (film.cpp), at most max_log2; 0:
  // not split.
  int wanted_camera_rays_log2(size_t i, int max_log2) const;
  static constexpr double kSplitNoiseFloor = 0.1;
  // Starts pixel i over (emitter antialiasing, once it is split): its
  // samples, their statistics and its replicates' samples are dropped.
  void restart(size_t i);
  int extra_camera_rays(size_t i) const { return split_.empty() || split_[i] == 0 ? 0 : 1 << split_[i]; }
  int extra_camera_rays_log2(size_t i) const { return split_[i]; }
  void set_extra_camera_rays_log2(size_t i, int log2) { split_[i] = uint8_t(log2); }
  size_t replicate_grid_size() const { return grid_slots_; }
  // Replicate streams, the grid's, the near stratum's and the followed
  // pixels' (what they cost: each stream traces its pixel's samples once
  // more), and of those the followed pixels'.
  size_t replicate_count() const { return replicate_sum_.size(); }
  size_t followed_replicate_count() const { return followed_streams_; }

  // Cycles' adaptive sampling error of one pixel (film_adaptive_sampling_
  // convergence_check, after Dammertz et al. 2010): |full - half| summed over
  // RGB, normalised by sqrt of the RGB sum.
  float pixel_error(size_t i) const;
  // The variance of one sample of pixel i, summed over RGB: the plain sample
  // variance of its samples (0 under two samples). Over-states the error of
  // the Owen-scrambled mean where the integrand is smooth, not where rare
  // bright samples (fireflies) carry it.
  double sample_variance(size_t i) const;
  // Estimated relative RMSE of the image: sqrt(mean variance over pixels and
  // channels) / mean pixel value. A followed pixel counts its own error: its
  // mean against its streams' mean, less the variance of that mean (from
  // the streams' spread). Fireflies (a sample over firefly_threshold x the
  // image's mean pixel value and over kFireflyDominance x the sum of the
  // pixel's other samples, in a pixel with no neighbour whose samples but the
  // brightest have a mean over the threshold) count as the error they put
  // into their pixel, from every other pixel; the rest from the grid: the
  // pixels near a bright sample (over the threshold, within one pixel) by the
  // grid's pixels near one, the remaining pixels by the grid's others
  // (film.cpp). Then, for the passes after this call, gives streams to the
  // unfollowed pixels near a bright sample with the largest sample variance
  // over n (as many streams as the grid has, at most). firefly_threshold 0:
  // the grid alone, nothing added. 0 without replicates.
  static constexpr double kFireflyThreshold = 16.0;
  static constexpr double kFireflyDominance = 2.0;  // x the sum of the pixel's other samples
  // Fewer replicated pixels than this near a bright sample: the unfollowed
  // pixels there count the whole grid's mean (film.cpp).
  static constexpr size_t kMinNearGridPixels = 4;
  double estimated_relative_error(double firefly_threshold = kFireflyThreshold);

 private:
  int width_ = 0, stride_ = 1;
  std::vector<vec3> sum_, sum_a_;
  std::vector<double> sum_sq_;  // per pixel: sum over samples of |L|^2 (RGB)
  std::vector<int> count_;
  std::vector<double> transparency_;  // per pixel: sum of its samples' transparency (empty: opaque film)
  std::vector<uint8_t> active_;
  std::vector<vec3> max_;  // per pixel: its brightest sample (largest RGB sum)
  std::vector<int> max_index_;  // per pixel: that sample's index
  // Per pixel, sums over its samples (of RGB sums, 20 bytes): camera
  // emission, its square, its product with the rest of the path, the rest's
  // square, and the rays of the paths (not counting extra camera rays).
  struct CameraEmissionStats {
    float sum_le = 0.0f, sum_le_sq = 0.0f, sum_le_rest = 0.0f, sum_rest_sq = 0.0f, path_rays = 0.0f;
  };
  std::vector<CameraEmissionStats> le_stats_;  // empty: not kept
  std::vector<uint8_t> split_;                 // per pixel: log2 of its extra camera rays per sample (0: none)
  std::vector<int> slot_of_;    // per pixel: its replicate slot or -1 (empty: no replicates)
  size_t grid_slots_ = 0;       // slots 0 .. grid_slots_ - 1 are the grid's
  size_t followed_streams_ = 0;  // streams of the followed pixels' slots
  size_t stratum_drawn_from_ = 0;  // unfollowed pixels near a bright sample when the near stratum's sample was drawn
  // What a slot past the grid's is: one stream for the near stratum, or
  // kFollowStreams for a followed pixel.
  enum class SlotKind : uint8_t { Grid, NearStratum, Followed };
  std::vector<SlotKind> replicate_kind_;
  int add_slot(size_t pixel, SlotKind kind, int streams);
  bool followed_slot(size_t i) const { return slot_of_[i] >= 0 && replicate_kind_[size_t(slot_of_[i])] == SlotKind::Followed; }
  void sample_near_stratum(const std::vector<float>& near_bright);
  // Per slot: the pixel, its first stream, its number of streams and the
  // samples each stream has. Per stream: the sum and the brightest sample.
  std::vector<int> replicate_pixel_, replicate_first_, replicate_streams_, replicate_samples_;
  std::vector<vec3> replicate_sum_, replicate_max_;
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
  // Drops pixel i's records (Film::restart).
  void restart(size_t i);
  // The pass's value at pixel i over n samples: pass_channels(pass) floats.
  void resolve(size_t i, int n, uint32_t pass, float* out) const;

 private:
  uint32_t mask_ = 0;
  vec3 camera_origin_{0.0f}, camera_x_{1, 0, 0}, camera_y_{0, 1, 0}, camera_forward_{0, 0, -1};
  std::vector<float> depth_, denoising_depth_;
  std::vector<int> depth_count_;  // samples that found a surface for Depth
  std::vector<vec3> normal_, diffuse_color_, emission_, denoising_normal_, denoising_albedo_;
};

}  // namespace tessera
