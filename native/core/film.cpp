#include "film.h"

#include <algorithm>
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

float PixelFilter::density(float x) const {
  const size_t n = inverse_cdf_.size();
  if (!(x >= inverse_cdf_.front() && x < inverse_cdf_.back())) return 0.0f;
  const size_t i = size_t(std::upper_bound(inverse_cdf_.begin(), inverse_cdf_.end(), x) - inverse_cdf_.begin()) - 1;
  const float dx = inverse_cdf_[i + 1] - inverse_cdf_[i];
  return dx > 0.0f ? 1.0f / (float(n - 1) * dx) : 0.0f;
}

}  // namespace tessera

namespace tessera {

void Film::resize(int width, int height, bool estimate_error, bool camera_emission, bool transparent_background) {
  const size_t n = size_t(width) * size_t(height);
  width_ = width;
  transparency_.assign(transparent_background ? n : 0, 0.0);
  le_stats_.assign(camera_emission ? n : 0, CameraEmissionStats());
  split_.assign(camera_emission ? n : 0, 0);
  sum_.assign(n, vec3(0.0f));
  sum_a_.assign(n, vec3(0.0f));
  sum_sq_.assign(n, 0.0);
  max_.assign(n, vec3(0.0f));
  max_index_.assign(n, 0);
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
  const int replicate_columns = (width + stride_ - 1) / stride_;
  slot_of_.assign(estimate_error ? n : 0, -1);
  for (auto* v : {&replicate_pixel_, &replicate_first_, &replicate_streams_, &replicate_samples_}) v->clear();
  replicate_kind_.clear(), replicate_sum_.clear(), replicate_max_.clear();
  followed_streams_ = stratum_drawn_from_ = 0;
  grid_slots_ = estimate_error ? size_t(replicate_columns) * ((height + stride_ - 1) / stride_) : 0;
  if (!estimate_error) return;
  for (int y = 0; y < height; y += stride_)
    for (int x = 0; x < width; x += stride_) add_slot(size_t(y) * size_t(width) + size_t(x), SlotKind::Grid, 1);
}

// A new slot for the pixel, with its streams at sample 0 (the renderer
// catches them up); a slot the pixel had before is superseded.
int Film::add_slot(size_t pixel, SlotKind kind, int streams) {
  const int slot = int(replicate_pixel_.size());
  slot_of_[pixel] = slot;
  replicate_pixel_.push_back(int(pixel)), replicate_first_.push_back(int(replicate_sum_.size()));
  replicate_streams_.push_back(streams), replicate_samples_.push_back(0), replicate_kind_.push_back(kind);
  for (int k = 0; k < streams; ++k) replicate_sum_.push_back(vec3(0.0f)), replicate_max_.push_back(vec3(0.0f));
  if (kind == SlotKind::Followed) followed_streams_ += size_t(streams);
  return slot;
}

float Film::pixel_error(size_t i) const {
  const int n = count_[i];
  const int n_a = class_a_count(n);
  if (n_a == 0) return kInf;
  const vec3 full = sum_[i] / float(n), half = sum_a_[i] / float(n_a);
  const vec3 d = abs(full - half);
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

void Film::restart(size_t i) {
  sum_[i] = sum_a_[i] = max_[i] = vec3(0.0f);
  sum_sq_[i] = 0.0;
  max_index_[i] = 0;
  count_[i] = 0;
  if (!transparency_.empty()) transparency_[i] = 0.0;
  if (!le_stats_.empty()) le_stats_[i] = CameraEmissionStats();
  if (slot_of_.empty() || slot_of_[i] < 0) return;
  const size_t slot = size_t(slot_of_[i]);
  replicate_samples_[slot] = 0;
  for (int k = 0; k < replicate_streams_[slot]; ++k)
    replicate_sum_[size_t(replicate_first_[slot] + k)] = replicate_max_[size_t(replicate_first_[slot] + k)] = vec3(0.0f);
}

// A sample Le + rest (Le: the emission its camera ray sees first) has
// variance V_e + V_r + 2 cov; with K more camera rays for the emission it is
// rest + the mean of K + 1 Le, of variance ~ V_r + G / (K + 1), G = V_e +
// 2 cov(Le, rest) (negative where the two make up for each other, as a
// light's edge against the ceiling it lights: then it is not split), at a
// cost of ~ 1 + K c (c: one camera ray against the path's rays). The
// product, the pixel's squared error times its time, is least at K + 1 =
// sqrt(G (1 - c) / (V_r c)) (d/dK = 0), here to the power of two below.
// From the pixel's own samples only, so that a region render makes the
// choices of the full frame.
int Film::wanted_camera_rays_log2(size_t i, int max_log2) const {
  const int n = count_[i];
  if (n < 2) return 0;
  // Of the RGB sums of Le and the rest.
  const CameraEmissionStats& st = le_stats_[i];
  const double m = double(sum_[i].x) + sum_[i].y + sum_[i].z;
  const double le = double(st.sum_le) / n, rest = m / n - le;  // the rest's mean: the pixel's, split or not
  const double var_le = (double(st.sum_le_sq) - n * le * le) / double(n - 1);
  const double cov = (double(st.sum_le_rest) - n * le * rest) / double(n - 1);
  const double var_rest = std::max(0.0, (double(st.sum_rest_sq) - n * rest * rest) / double(n - 1));
  const double g = var_le + 2.0 * cov;
  if (!(g > 0.0)) return 0;
  // The rest's variance counts as at least (kSplitNoiseFloor x the pixel's
  // value)^2: a pixel whose path finds little besides the emission (a sky
  // seen directly through a window, an HDRI's texture) is split only where
  // that emission varies a lot next to its value, not for variations too
  // small to matter to the image's error.
  const double floor = kSplitNoiseFloor * kSplitNoiseFloor * (m / n) * (m / n);
  const double c = std::min(0.5, double(n) / std::max(double(st.path_rays), 1.0));
  const double k = std::sqrt(g * (1.0 - c) / (std::max(var_rest, floor) * c)) - 1.0;
  if (!(k >= 0.0)) return 0;
  int l = 0;
  while (l < max_log2 && double(2 << l) <= k) ++l;
  return l;
}

// The image's mean variance per pixel and channel in three parts.
//
// Fireflies: a pixel's brightest sample, when it is over the threshold
// (firefly_threshold x the image's mean pixel value, RGB summed) and over
// twice the sum of all its other samples, is a rare event that the pixel's
// mean carries as (brightest - mean of the others) / n of error: counted as
// that, from every pixel (not next to a light seen directly: below, at the
// lambda). Such samples are few, land on few pixels and so
// swing one image's error; the replicate grid (1/16 of the pixels or fewer)
// saw them or missed them by chance (estimate/true 0.24-1.38 on
// bunny_glass.blend at 16-128 spp with the grid alone, 0.92-1.40 with the
// term: docs/convergence/ADAPTIVE.md). A looser test (over 4x the mean of
// the other samples) also took the edges of directly seen lights for
// fireflies (1.8x on cbox_mitsuba.blend at 16 spp).
//
// Near bright samples: a small light seen directly (veach_mis.blend's
// smallest sphere, 2,500x the image's mean) puts nearly all of the image's
// error on the ~10 pixels its filter footprint covers, and not as fireflies:
// each of those pixels gets the light in a well stratified share of its
// samples (33-38 of 128 over 8 seeds where the reference expects 35.2), or
// none yet where it expects under one, and its error is that count's last
// unit or two, about the light's value / n. The grid held one of them, which
// stood for 16 pixels (estimate/true 0.09-3.69 at 4-128 spp, 8 seeds;
// docs/convergence/ADAPTIVE.md). And since that count is set by the Sobol
// points (often the same for every seed), one image's error strays far from
// the expected error (0.40-1.51x at 4 spp): an estimate of the expected
// error cannot be within 1.5x of every image's. So the pixels near a bright
// sample (one over the threshold within one pixel) are a stratum apart, and
// the ones that carry the most are followed: kFollowStreams streams each,
// traced from sample 0, whose mean is a reference for this image's pixel
// (below); the stratum's other pixels count the mean of the grid's pixels
// in it and of a sample of its own (sample_near_stratum), the remaining
// pixels the mean of the grid's other pixels. A grid
// pixel's single stream gives the expected error only; 8 streams a followed
// pixel held veach_mis.blend within 0.68-1.39x at 16-128 spp (4 streams:
// 0.67-1.55; 16, on half as many pixels: 0.67-1.57).
//
// A replicate pair: x1 - x2 over the samples both have, each side's firefly
// taken out (x1, x2 independent estimates of the pixel's mean: (x1 - x2)^2 / 2
// is unbiased for its variance). Scaling the cheap half-buffer estimates of
// all pixels by the replicates' ratio instead was biased either way on the
// shared scenes (0.5-0.9x on McGuire's Cornell box, where a few firefly pixels
// carry the error and the Sobol points' gain differs from pixel to pixel;
// per-group ratios 2.4-4.3x on the Mitsuba box).
double Film::estimated_relative_error(double firefly_threshold) {
  if (replicate_pixel_.empty()) return 0.0;
  const size_t n_pixels = sum_.size();
  double mean = 0.0;
  for (size_t i = 0; i < n_pixels; ++i) {
    const vec3 m = this->mean(i);
    mean += double(m.x) + m.y + m.z;
  }
  if (mean <= 0.0) return 0.0;
  const double threshold = firefly_threshold > 0.0 ? firefly_threshold * mean / double(n_pixels) : kInf;
  auto rgb = [](const vec3& v) { return double(v.x) + v.y + v.z; };
  // near_bright[i]: the brightest sample over the threshold in i's 3x3
  // neighbourhood, 0 if none; lit_edge[i]: a neighbour is lit (a light or
  // other bright surface seen directly). Scratch of 5 bytes a pixel, freed
  // on return.
  const int w = width_, h = int(n_pixels / size_t(std::max(w, 1)));
  std::vector<float> near_bright(n_pixels, 0.0f);
  std::vector<uint8_t> lit_edge(n_pixels, 0);
  if (threshold < kInf)
    for (size_t i = 0; i < n_pixels; ++i) {
      const int n = count_[i];
      const double bright = rgb(max_[i]);
      if (n == 0 || !(bright > threshold)) continue;  // (a lit pixel has a bright sample)
      // Lit: the mean of its samples but the brightest (a firefly of its own
      // does not make a pixel a light) is over the threshold.
      const bool lit = n > 1 && rgb(sum_[i] - max_[i]) > threshold * double(n - 1);
      const int x = int(i % size_t(w)), y = int(i / size_t(w));
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
          const size_t j = size_t(ny) * w + nx;
          near_bright[j] = std::max(near_bright[j], float(bright));
          if (lit && (dx != 0 || dy != 0)) lit_edge[j] = 1;
        }
    }
  // A pixel's firefly: its brightest sample when it is over the threshold and
  // over twice the sum of all the pixel's other samples, and no neighbour is
  // lit. Next to a light seen directly, a pixel that
  // sees the light in one of its samples has no firefly: its samples see the
  // light in a well stratified share, and its error is the fraction of a
  // sample by which that share misses its footprint's, not the sample (the
  // term was 1.8-2.3x the true error on cbox_mitsuba.blend at 8 spp, where
  // the light's edge pixels see it in one sample; 1.0-1.4x without them).
  auto firefly = [&](size_t i, const vec3& sum, const vec3& max, int n) {
    if (n < 2 || lit_edge[i]) return false;
    const double s = rgb(max);
    return s > threshold && s > kFireflyDominance * rgb(sum - max);
  };
  // Followed pixels (a slot past the grid's whose streams have all the
  // pixel's samples) count their own error, fireflies included.
  auto followed = [&](size_t i) { return followed_slot(i) && replicate_samples_[size_t(slot_of_[i])] == count_[i]; };
  // Room for more followed pixels (below), and if there is, the sum over
  // pixels of the sample variance / n, all and near a bright sample.
  const size_t room = (grid_slots_ - std::min(grid_slots_, followed_streams_)) / size_t(kFollowStreams);
  const bool may_follow = room > 0 && threshold < kInf;
  double fireflies = 0.0, near_proxy = 0.0, all_proxy = 0.0;
  size_t near = 0;
  for (size_t i = 0; i < n_pixels; ++i) {
    near += near_bright[i] > 0.0f;
    const int n = count_[i];
    if (may_follow && n > 1) {
      const double v = sample_variance(i) / double(n);
      all_proxy += v;
      if (near_bright[i] > 0.0f) near_proxy += v;
    }
    if (n == 0 || !firefly(i, sum_[i], max_[i], n) || followed(i)) continue;
    const vec3 rest = (sum_[i] - max_[i]) / float(n - 1);
    const vec3 d = (max_[i] - rest) / float(n);
    fireflies += rgb(d * d);
  }
  // A followed pixel: its mean x against the mean r of its K streams' means
  // r_k (each an independent estimate of the pixel's value from the same
  // samples): E[|x - r|^2 | x] = |x - truth|^2 + var(r), and var(r) is
  // estimated by the streams' sample variance / K, so the difference is an
  // unbiased estimate of this image's squared error at the pixel, whatever
  // made the pixel be chosen (the streams are independent of the image).
  // A grid or near-stratum pixel: its mean against its one stream's, without
  // either side's firefly: (d^2 / 2) estimates the variance of the pixel's
  // mean (the expected error), which these pixels stand for over their
  // stratum.
  double own = 0.0, grid_near = 0.0, grid_far = 0.0, stratum_near = 0.0;
  size_t own_near = 0, own_far = 0, n_grid_near = 0, n_grid_far = 0, n_stratum_near = 0;
  for (size_t slot = 0; slot < replicate_pixel_.size(); ++slot) {
    const size_t i = size_t(replicate_pixel_[slot]);
    const int n = count_[i];
    if (slot_of_[i] != int(slot) || replicate_samples_[slot] != n || n == 0) continue;  // superseded or behind
    const size_t first = size_t(replicate_first_[slot]);
    const bool is_near = near_bright[i] > 0.0f;
    if (replicate_kind_[slot] == SlotKind::Followed) {
      const int k_streams = replicate_streams_[slot];
      vec3 r(0.0f);
      for (int k = 0; k < k_streams; ++k) r += replicate_sum_[first + k];
      r /= float(k_streams) * float(n);
      double spread = 0.0;
      for (int k = 0; k < k_streams; ++k) {
        const vec3 d = replicate_sum_[first + k] / float(n) - r;
        spread += rgb(d * d);
      }
      const vec3 d = this->mean(i) - r;
      own += rgb(d * d) - spread / double(k_streams - 1) / double(k_streams);
      ++(is_near ? own_near : own_far);
      continue;
    }
    vec3 x1 = sum_[i], x2 = replicate_sum_[first];
    int m1 = n, m2 = n;
    // Without their fireflies (counted above, from every pixel).
    if (firefly(i, sum_[i], max_[i], n)) x1 -= max_[i], --m1;
    if (firefly(i, x2, replicate_max_[first], n)) x2 -= replicate_max_[first], --m2;
    if (m1 == 0 || m2 == 0) continue;
    const vec3 d = x1 / float(m1) - x2 / float(m2);
    const double r = 0.5 * rgb(d * d);
    if (replicate_kind_[slot] == SlotKind::NearStratum) {
      if (is_near) stratum_near += r, ++n_stratum_near;  // (no longer near: a sample of nothing)
    } else if (is_near) {
      grid_near += r, ++n_grid_near;
    } else {
      grid_far += r, ++n_grid_far;
    }
  }
  if (n_grid_far + n_grid_near == 0) return 0.0;
  // The pixels not followed, by the replicated pixels of their stratum: near
  // a bright sample, the grid's there and the near stratum's sample (fewer
  // than kMinNearGridPixels of them: the whole grid's); away from one, the
  // grid's (none: the whole grid's). One pixel's (d^2 / 2) is a
  // one-degree-of-freedom figure: standing for the 77 unfollowed pixels near
  // cbox_mitsuba.blend's light once emitter antialiasing had taken their
  // error off, it put the estimate at 1.7-1.8x the true error in 3 of 8
  // seeds (0.91-0.99 with the whole grid's;
  // Controls.ErrorEstimateDoesNotLetOneGridPixelStandForThePixelsNearALight).
  // The grid alone was too sparse there: at 240 x 135 pixels, 8 of its
  // pixels near cbox_mitsuba.blend's light, mostly inside it (no error),
  // stood for the light's edge pixels, which carry two thirds of the
  // image's error at 4 spp (before emitter antialiasing splits them): the
  // estimate was 0.53-0.64x the true error.
  // The followed pixels' sum can be under 0 (each is unbiased, not
  // positive): not below 0.
  const double grid_mean = (grid_near + grid_far) / double(n_grid_near + n_grid_far);
  const double rest_near = double(near - own_near), rest_far = double(n_pixels - near - own_far);
  const size_t n_near = n_grid_near + n_stratum_near;
  double variance = std::max(0.0, own) + fireflies;
  variance += rest_near * (n_near >= kMinNearGridPixels ? (grid_near + stratum_near) / double(n_near) : grid_mean);
  variance += rest_far * (n_grid_far > 0 ? grid_far / double(n_grid_far) : grid_mean);
  variance /= 3.0 * double(n_pixels);
  // Follow the error: kFollowStreams streams each for the unfollowed pixels
  // near a bright sample with the largest sample variance over n (the error
  // they would have with independent samples), while the followed pixels'
  // streams number fewer than the grid's. A grid pixel chosen gets a slot of
  // its own (its grid slot is dropped from the grid's figures).
  // Only while the pixels near a bright sample carry kFollowShare of the
  // image's error or more, by the sample variance over n of the pixels (a
  // measure that does not depend on the grid having seen them): elsewhere
  // the grid's figure for them is good enough for the image's, and their
  // streams would cost samples for nothing (modern_hall.blend).
  if (may_follow && near_proxy >= kFollowShare * all_proxy && near_proxy > 0.0) {
    // The key: the pixel's sample variance over n (its error were its samples
    // independent) or, if larger, the error one bright sample puts in it,
    // (b / n)^2, b its own brightest sample or half the brightest within a
    // pixel, if more (a pixel next to a small light that has not seen it
    // yet; half: ranked after the pixels that have); ties to the pixel with
    // the brighter sample of its own, then the lower index. From two samples
    // on (one sample has no variance).
    struct Wanted {
      double key, own;
      int i;
      bool operator<(const Wanted& q) const { return key > q.key || (key == q.key && (own > q.own || (own == q.own && i < q.i))); }
    };
    std::vector<Wanted> wanted;
    for (size_t i = 0; i < n_pixels; ++i)
      if (near_bright[i] > 0.0f && !followed_slot(i) && active_[i] && count_[i] > 1) {
        const double n = double(count_[i]), one = std::max(rgb(max_[i]), 0.5 * double(near_bright[i])) / n;
        wanted.push_back({std::max(sample_variance(i) / n, one * one), rgb(max_[i]), int(i)});
      }
    // At most half the room now: a pixel whose rare samples have not shown
    // up yet may rank low at this pass and high at the next.
    const size_t now = (room + 1) / 2;
    if (wanted.size() > now) {
      std::nth_element(wanted.begin(), wanted.begin() + now, wanted.end());
      wanted.resize(now);
    }
    std::sort(wanted.begin(), wanted.end(), [](const Wanted& p, const Wanted& q) { return p.i < q.i; });
    for (const Wanted& p : wanted) add_slot(size_t(p.i), SlotKind::Followed, kFollowStreams);
  }
  if (threshold < kInf) sample_near_stratum(near_bright);
  return std::sqrt(variance) / (mean / (3.0 * double(n_pixels)));
}

// The near stratum's sample: while fewer than kNearStratumPixels of the
// pixels near a bright sample that are not followed have a replicate (the
// grid's there, and this sample's), a slot of one stream for more of them,
// every k-th in scan order of those without a slot (a systematic sample, so
// that the pixels inside a light and on its edge are sampled in the share
// they have). Chosen from where the bright samples are, not from the
// pixels' errors: their (d^2 / 2) stands for the stratum's unfollowed
// pixels. The stratum grows as bright samples turn up (on
// cornell_mcguire.blend at 64 spp, from the light's pixels to 4,677 of 8,160
// pixels): a sample drawn from it when it was under half its size stands for
// the part it was drawn from (there, 7x the error of the stratum's mean
// pixel; the estimate was 2x the true error), so it is drawn again.
void Film::sample_near_stratum(const std::vector<float>& near_bright) {
  const size_t n_pixels = sum_.size();
  size_t unfollowed = 0;
  for (size_t i = 0; i < n_pixels; ++i) unfollowed += near_bright[i] > 0.0f && !followed_slot(i);
  if (unfollowed > 2 * stratum_drawn_from_) {
    for (size_t slot = grid_slots_; slot < replicate_pixel_.size(); ++slot)
      if (replicate_kind_[slot] == SlotKind::NearStratum && slot_of_[size_t(replicate_pixel_[slot])] == int(slot))
        slot_of_[size_t(replicate_pixel_[slot])] = -1;
    stratum_drawn_from_ = unfollowed;
  }
  size_t have = 0, candidates = 0;
  for (size_t i = 0; i < n_pixels; ++i) {
    if (!(near_bright[i] > 0.0f)) continue;
    if (slot_of_[i] >= 0) have += !followed_slot(i);
    else candidates += active_[i] && count_[i] > 0;
  }
  const size_t want = size_t(kNearStratumPixels) - std::min(size_t(kNearStratumPixels), have);
  if (want == 0 || candidates == 0) return;
  const size_t take = std::min(want, candidates);
  // Candidate c (in scan order) is taken where c take / candidates passes a
  // whole number: take of them, evenly spread.
  size_t c = 0;
  for (size_t i = 0; i < n_pixels; ++i) {
    if (!(near_bright[i] > 0.0f) || slot_of_[i] >= 0 || !active_[i] || count_[i] == 0) continue;
    if ((c + 1) * take / candidates > c * take / candidates) add_slot(i, SlotKind::NearStratum, 1);
    ++c;
  }
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

void DataPasses::restart(size_t i) {
  for (auto* b : {&depth_, &denoising_depth_})
    if (!b->empty()) (*b)[i] = 0.0f;
  if (!depth_count_.empty()) depth_count_[i] = 0;
  for (auto* b : {&normal_, &diffuse_color_, &emission_, &denoising_normal_, &denoising_albedo_})
    if (!b->empty()) (*b)[i] = vec3(0.0f);
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
