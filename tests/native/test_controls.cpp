// Speed/accuracy controls: sample count, per-kind bounce limits, clamping,
// adaptive sampling, time limit, error target and the error estimate.
// Correctness only, never wall-clock.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <tuple>

#include "core/render.h"
#include "render_fixtures.h"
#include "scene_fixtures.h"

using namespace tessera;
using fixtures::mean_rgb;
using fixtures::render;
using fixtures::Result;

namespace {
// A linear congruential generator: uniform floats in [0, 1) from a seed,
// the same on every platform (the film tests' pixel values).
struct Rng {
  uint32_t state;
  float operator()() { return float((state = state * 1664525u + 1013904223u) >> 8) / float(1 << 24); }
};

double rmse(const std::vector<float>& a, const std::vector<float>& b) {
  double e = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (i % 4 == 3) continue;
    e += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    ++n;
  }
  return std::sqrt(e / n);
}
// A synthetic film rendered pass by pass as render_tile does it: each pixel
// gets its samples image(i, s) up to the pass's end, then every stream k of
// its replicate slot is brought up to that count with replicate(i, s, k);
// after each pass between() (the estimate, as RenderSession::render calls it).
template <typename Image, typename Replicate, typename Between>
void render_passes(Film& film, int w, int h, std::initializer_list<int> passes, Image image, Replicate replicate,
                   Between between) {
  int done = 0;
  for (int pass : passes) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const size_t i = size_t(y) * w + x;
        for (int s = done; s < done + pass; ++s) film.add(i, s, image(i, s));
        film.set_count(i, done + pass);
        const int slot = film.replicate_slot(x, y);
        if (slot < 0) continue;
        for (int k = 0; k < film.replicate_streams(slot); ++k)
          for (int s = film.replicate_samples(slot); s < done + pass; ++s) film.add_replicate(slot, k, replicate(i, s, k));
        film.set_replicate_samples(slot, done + pass);
      }
    done += pass;
    between();
  }
}
}  // namespace

TEST(Controls, MoreSamplesNeverRaiseTheError) {
  Scene s;
  fixtures::build_cornell_box(s, 24, 24);
  RenderOptions opt;
  opt.seed = 1234;  // reference independent of the test renders
  opt.samples = 1024;
  const std::vector<float> ref = render(s, opt).px;
  opt.seed = 0;
  double prev = 1e30;
  for (int spp : {2, 8, 32, 128}) {
    opt.samples = spp;
    const double e = rmse(render(s, opt).px, ref);
    EXPECT_LT(e, prev * 1.05) << spp << " samples";  // beyond noise: must fall, 4x samples ~ half the error
    prev = e;
  }
}

TEST(Controls, DiffuseBounceLimitActsLikeTotalLimitInAllDiffuseScene) {
  Scene s;
  fixtures::build_cornell_box(s, 16, 16);
  for (Material& m : s.materials) m.specular = 0.0f;  // diffuse only
  RenderOptions opt;
  opt.samples = 16;
  opt.max_bounces = 1;
  const Result total = render(s, opt);
  opt.max_bounces = 8;
  opt.max_diffuse_bounces = 1;
  const Result diffuse = render(s, opt);
  EXPECT_EQ(0, std::memcmp(total.px.data(), diffuse.px.data(), total.px.size() * sizeof(float)));
  // Glossy and transmission limits do not touch diffuse paths.
  opt.max_diffuse_bounces = 1024;
  opt.max_glossy_bounces = 0;
  opt.max_transmission_bounces = 0;
  const Result other = render(s, opt);
  opt.max_glossy_bounces = opt.max_transmission_bounces = 1024;
  const Result unlimited = render(s, opt);
  EXPECT_EQ(0, std::memcmp(other.px.data(), unlimited.px.data(), other.px.size() * sizeof(float)));
  EXPECT_GT(mean_rgb(unlimited.px), mean_rgb(total.px) * 1.05);
}

TEST(Controls, ClampingBoundsPixelValues) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 32);
  RenderOptions opt;
  opt.samples = 16;
  opt.max_bounces = 0;
  float unclamped_max = 0.0f;
  for (float v : render(s, opt).px) unclamped_max = std::max(unclamped_max, v);
  EXPECT_GT(unclamped_max, 5.0f);  // the light (10) is seen directly
  opt.clamp_direct = 1.0f;
  opt.clamp_indirect = 0.5f;
  // With max_bounces = 0 a sample has at most: emission and light sampling
  // at the first hit (direct) and emission at the second (indirect).
  const float bound = 2 * opt.clamp_direct + opt.clamp_indirect;
  for (float v : render(s, opt).px) EXPECT_LE(v, bound + 1e-5f);
  // Many bounces: at most two direct contributions plus two indirect ones per further vertex.
  opt.max_bounces = 6;
  const float bound6 = 2 * opt.clamp_direct + 2 * 7 * opt.clamp_indirect;
  for (float v : render(s, opt).px) EXPECT_LE(v, bound6 + 1e-5f);
}

// Cycles' Light Threshold: light samples adding less than the threshold
// trace their shadow ray with probability (their contribution / threshold)
// and count for its inverse, so the image keeps its mean with fewer rays;
// 0 traces every one, and a threshold below every sample's contribution
// changes nothing (the number deciding it is a coordinate no other choice
// reads).
TEST(Controls, LightThresholdSkipsWeakShadowRaysAndKeepsTheMean) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 32);
  RenderOptions opt;
  opt.samples = 256;
  opt.estimate_error = false;
  opt.light_threshold = 0.0f;
  const Result all = render(s, opt);
  opt.light_threshold = 1e-12f;
  const Result tiny = render(s, opt);
  EXPECT_EQ(0, std::memcmp(all.px.data(), tiny.px.data(), all.px.size() * sizeof(float)));
  EXPECT_EQ(all.stats.rays, tiny.stats.rays);
  opt.light_threshold = 1.0f;  // about the box's typical light sample
  const Result some = render(s, opt);
  EXPECT_LT(double(some.stats.rays), 0.97 * double(all.stats.rays));
  const double m_all = mean_rgb(all.px), m_some = mean_rgb(some.px);
  std::printf("light threshold 1: rays %.3f of all, mean %.5f against %.5f\n", double(some.stats.rays) / double(all.stats.rays), m_some, m_all);
  EXPECT_NEAR(m_some, m_all, 0.01 * m_all);
  // Not the same image: the skipped samples' share went to the kept ones.
  EXPECT_NE(0, std::memcmp(all.px.data(), some.px.data(), all.px.size() * sizeof(float)));
}

TEST(Controls, TimeLimitStopsTheRender) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 32);
  RenderOptions opt;
  opt.samples = 1 << 24;  // would take hours
  opt.time_limit = 0.3;
  const Result r = render(s, opt);
  EXPECT_STREQ("time limit", r.stats.stop_reason);
  EXPECT_LT(r.stats.samples_done, opt.samples);
  EXPECT_GT(r.stats.samples_done, 0);
  for (size_t i = 0; i < r.px.size(); ++i) ASSERT_TRUE(std::isfinite(r.px[i]));
}

TEST(Controls, AdaptiveSamplingStopsConvergedPixelsAndIsDeterministic) {
  Scene s;
  fixtures::build_cornell_box(s, 40, 24);
  RenderOptions opt;
  opt.samples = 512;
  opt.adaptive_threshold = 0.1f;
  opt.adaptive_min_samples = 16;
  const Result one = fixtures::render_on_one_and_all_threads(s, opt);
  const uint64_t full = uint64_t(opt.samples) * 40 * 24;
  std::printf("adaptive, threshold 0.1: %.1f%% of the uniform samples\n", 100.0 * one.stats.pixel_samples / full);
  EXPECT_LT(one.stats.pixel_samples, full * 3 / 4);  // converged pixels stopped early
  EXPECT_GE(one.stats.pixel_samples, uint64_t(opt.adaptive_min_samples) * 40 * 24);
  // Off: every pixel gets every sample.
  opt.adaptive_threshold = 0.0f;
  opt.samples = 32;
  EXPECT_EQ(uint64_t(32) * 40 * 24, render(s, opt).stats.pixel_samples);
}

TEST(Controls, AdaptiveSamplingSpendsSamplesWhereTheNoiseIs) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 32);
  RenderOptions opt;
  opt.samples = 256;
  // At 256 samples the median pixel error of this box is ~0.03 and the 90th percentile ~0.09 (class-A
  // split of one Sobol stream): some pixels stop early, the noisy ones not.
  opt.adaptive_threshold = 0.06f;
  const Result r = render(s, opt);
  std::printf("adaptive, threshold 0.06: %.1f%% of the uniform samples\n",
              100.0 * double(r.stats.pixel_samples) / (256.0 * 32 * 32));
  EXPECT_LT(r.stats.pixel_samples, uint64_t(256) * 32 * 32);
  EXPECT_GT(r.stats.pixel_samples, uint64_t(16) * 32 * 32);
}

TEST(Controls, FilmSampleVarianceOfKnownSamples) {
  // Samples (1,0,0), (3,0,0), (0,2,0), (0,0,4): per-channel means (1, 0.5, 1),
  // unbiased variances 2, 1, 4 summed = 7.
  Film film;
  film.resize(2, 1, false);
  const vec3 samples[] = {{1, 0, 0}, {3, 0, 0}, {0, 2, 0}, {0, 0, 4}};
  for (int s = 0; s < 4; ++s) film.add(0, s, samples[s]);
  film.set_count(0, 4);
  EXPECT_NEAR(7.0, film.sample_variance(0), 1e-9);
  // Constant samples: no variance; fewer than two samples: none known.
  for (int s = 0; s < 5; ++s) film.add(1, s, vec3(0.25f, 0.5f, 2.0f));
  film.set_count(1, 5);
  EXPECT_NEAR(0.0, film.sample_variance(1), 1e-9);
  Film one;
  one.resize(1, 1, false);
  one.add(0, 0, vec3(5.0f));
  one.set_count(0, 1);
  EXPECT_EQ(0.0, one.sample_variance(0));
}

// Adaptive sampling with a budget (time limit or error target): after the
// minimum, each pass goes to the pixels by estimated error; no pixel gets fewer
// than the minimum or more than the samples setting.
TEST(Controls, AdaptiveWithATimeLimitSpendsItByErrorWithinMinAndMaxSamples) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 24);
  RenderOptions opt;
  opt.samples = 96;
  opt.adaptive_threshold = 1e-4f;  // no pixel converges: the budget decides
  opt.adaptive_min_samples = 16;
  opt.time_limit = 60.0;  // ends by samples long before
  RenderSession session(s, opt);
  session.render();
  const std::vector<int> counts = session.sample_counts();
  const int lo = *std::min_element(counts.begin(), counts.end());
  const int hi = *std::max_element(counts.begin(), counts.end());
  std::printf("adaptive, time limit: samples per pixel %d .. %d, stopped by %s\n", lo, hi, session.stats().stop_reason);
  EXPECT_GE(lo, opt.adaptive_min_samples);
  EXPECT_LE(hi, opt.samples);
  // Everything until every pixel has the most samples: then it ends by samples.
  EXPECT_EQ(opt.samples, lo);
  EXPECT_STREQ("samples", session.stats().stop_reason);
  uint64_t sum = 0;
  for (int c : counts) sum += uint64_t(c);
  EXPECT_EQ(sum, session.stats().pixel_samples);
}

TEST(Controls, AdaptiveWithAnErrorTargetGivesNoisyPixelsMoreSamplesAndIsDeterministic) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 24);
  RenderOptions opt;
  opt.samples = 1 << 16;
  opt.adaptive_threshold = 1e-4f;
  opt.adaptive_min_samples = 16;
  opt.error_target = 0.05f;
  opt.threads = 1;
  RenderSession one(s, opt);
  one.render();
  opt.threads = 0;
  opt.tile_size = 5;
  RenderSession all(s, opt);
  all.render();
  EXPECT_STREQ("error target", one.stats().stop_reason);
  const std::vector<int> counts = one.sample_counts();
  EXPECT_EQ(counts, all.sample_counts());
  const std::vector<float> px = one.pixels(), px_all = all.pixels();
  EXPECT_EQ(0, std::memcmp(px.data(), px_all.data(), px.size() * sizeof(float)));
  const int lo = *std::min_element(counts.begin(), counts.end());
  const int hi = *std::max_element(counts.begin(), counts.end());
  std::printf("adaptive, error target: samples per pixel %d .. %d\n", lo, hi);
  EXPECT_GE(lo, opt.adaptive_min_samples);
  EXPECT_GT(hi, 2 * lo);  // not uniform: the noisy pixels got more
}

// The Debug Sample Count pass is each pixel's samples over the Samples
// setting (Cycles' scaling), and turning it on changes nothing else: the
// integrator records nothing for it.
TEST(Controls, SampleCountPassIsEachPixelsSamplesOverTheSetting) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 24);
  RenderOptions opt;
  opt.samples = 4096;
  opt.adaptive_threshold = 1e-4f;  // no pixel converges: the error target's budget goes to the noisy ones
  opt.error_target = 0.05f;
  opt.adaptive_min_samples = 16;
  RenderSession plain(s, opt);
  plain.render();
  opt.passes = kPassSampleCount;
  RenderSession counted(s, opt);
  counted.render();
  const std::vector<int> counts = counted.sample_counts();
  const std::vector<float> pass = counted.pass_pixels(kPassSampleCount);
  ASSERT_EQ(counts.size(), pass.size());
  for (size_t i = 0; i < counts.size(); ++i) EXPECT_FLOAT_EQ(float(counts[i]) / opt.samples, pass[i]) << "pixel " << i;
  const auto [lo, hi] = std::minmax_element(pass.begin(), pass.end());
  std::printf("sample count pass: %.3f .. %.3f\n", *lo, *hi);
  EXPECT_LT(*lo, *hi);  // adaptive sampling shows in it
  EXPECT_EQ(counts, plain.sample_counts());
  const std::vector<float> a = plain.pixels(), b = counted.pixels();
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(float)));
  EXPECT_TRUE(plain.pass_pixels(kPassSampleCount).empty());  // not written unless asked for
}

// At equal total samples the error-driven allocation has a lower RMSE than
// uniform sampling on the box (deterministic seeds, no timing).
TEST(Controls, AdaptiveByErrorBeatsUniformAtEqualSamples) {
  Scene s;
  fixtures::build_cornell_box(s, 24, 16);
  RenderOptions opt;
  opt.seed = 4321;
  opt.samples = 2048;
  const std::vector<float> ref = render(s, opt).px;
  double adaptive_mse = 0.0, uniform_mse = 0.0;
  for (uint32_t seed = 0; seed < 3; ++seed) {
    opt.seed = seed;
    opt.samples = 1 << 16;
    opt.adaptive_threshold = 0.01f;
    opt.adaptive_min_samples = 16;
    opt.error_target = 0.04f;
    const Result a = render(s, opt);
    const int spp = int(std::lround(double(a.stats.pixel_samples) / (24 * 16)));
    opt.adaptive_threshold = 0.0f;
    opt.error_target = 0.0f;
    opt.samples = spp;
    const Result u = render(s, opt);
    const double ea = rmse(a.px, ref), eu = rmse(u.px, ref);
    std::printf("seed %u: %d samples per pixel, RMSE adaptive %.5f uniform %.5f\n", seed, spp, ea, eu);
    adaptive_mse += ea * ea, uniform_mse += eu * eu;
  }
  EXPECT_LT(adaptive_mse, uniform_mse);
}

// The image estimate on a synthetic film whose truth is known: every pixel's
// samples are 1 + uniform noise (independent, so the replicates see the same
// noise as the image), and one pixel off the replicate grid has a firefly. The
// replicates alone cannot see it (the estimate was 0.2x the truth before the
// firefly term); with it the estimate is within 1.5x.
TEST(Controls, ErrorEstimateCountsFirefliesOffTheReplicateGrid) {
  const int w = 32, h = 32, n = 64;
  Film film;
  film.resize(w, h, true);
  ASSERT_EQ(2, film.replicate_stride());
  uint32_t state = 12345;
  auto noise = [&] {
    state = state * 1664525u + 1013904223u;
    return 0.5f * (float(state >> 8) / float(1 << 24) - 0.5f);
  };
  const int fx = 5, fy = 7;  // odd: not a replicate pixel
  ASSERT_LT(film.replicate_slot(fx, fy), 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = size_t(y) * w + x;
      const int slot = film.replicate_slot(x, y);
      for (int s = 0; s < n; ++s) {
        film.add(i, s, vec3(1.0f + noise(), 1.0f + noise(), 1.0f + noise()));
        if (slot >= 0) film.add_replicate(slot, 0, vec3(1.0f + noise(), 1.0f + noise(), 1.0f + noise()));
      }
      if (slot >= 0) film.set_replicate_samples(slot, n);
      if (x == fx && y == fy) film.add(i, n, vec3(2000.0f));  // one firefly sample among n + 1
      film.set_count(i, x == fx && y == fy ? n + 1 : n);
    }
  auto truth = [&] {
    double mse = 0.0;
    for (size_t i = 0; i < film.size(); ++i) {
      const vec3 d = film.mean(i) - vec3(1.0f);
      mse += double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z;
    }
    return std::sqrt(mse / (3.0 * film.size()));  // the true mean is 1
  };
  const double t = truth();
  const double estimate = film.estimated_relative_error(), replicates_only = film.estimated_relative_error(0.0);
  std::printf("synthetic film with a firefly: true %.4f, estimate %.4f, replicates only %.4f\n", t, estimate, replicates_only);
  EXPECT_LT(replicates_only, t / 1.5);
  EXPECT_GT(estimate, t / 1.5);
  EXPECT_LT(estimate, t * 1.5);
  // Without the firefly, both are the replicates' estimate and honest.
  Film plain;
  plain.resize(w, h, true);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = size_t(y) * w + x;
      const int slot = plain.replicate_slot(x, y);
      for (int s = 0; s < n; ++s) {
        plain.add(i, s, vec3(1.0f + noise(), 1.0f + noise(), 1.0f + noise()));
        if (slot >= 0) plain.add_replicate(slot, 0, vec3(1.0f + noise(), 1.0f + noise(), 1.0f + noise()));
      }
      if (slot >= 0) plain.set_replicate_samples(slot, n);
      plain.set_count(i, n);
    }
  double mse = 0.0;
  for (size_t i = 0; i < plain.size(); ++i) {
    const vec3 d = plain.mean(i) - vec3(1.0f);
    mse += double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z;
  }
  const double t_plain = std::sqrt(mse / (3.0 * plain.size()));
  EXPECT_EQ(plain.estimated_relative_error(), plain.estimated_relative_error(0.0));
  EXPECT_GT(plain.estimated_relative_error(), t_plain / 1.5);
  EXPECT_LT(plain.estimated_relative_error(), t_plain * 1.5);
}

// Bright pixels off the replicate grid, each seeing a light in a share of its
// samples (as the pixels around veach_mis.blend's smallest light): no sample
// outweighs the rest of its pixel, so the firefly term does not count them,
// and the grid does not hold them (the estimate was 0.01x the truth with the
// grid and the firefly term alone). Rendered in passes as RenderSession
// does, the estimate between passes gives the pixels near bright samples
// replicates of their own (never more than the grid has), and from then on
// counts them: within 1.5x of the expected error (known here; this image's
// is 1.10x it; over five seeds 0.90-1.10x, the estimate 0.87-1.15x).
TEST(Controls, ErrorEstimateFollowsBrightPixelsOffTheGrid) {
  const int w = 48, h = 48;
  // Pixels (odd x and y: off the grid) that see a 300x bright light in 30% of
  // their samples; every other pixel 1 + uniform noise.
  std::vector<std::pair<int, int>> lit;
  for (int k = 0; k < 23; ++k) lit.emplace_back(1 + 2 * ((7 * k + 3) % 23), 1 + 2 * ((11 * k + 5) % 23));
  std::vector<float> share(size_t(w) * h, 0.0f);
  for (auto [x, y] : lit) share[size_t(y) * w + x] = 0.3f;
  auto sample = [&](size_t i, Rng& u) {
    const float n = 0.25f * (u() - 0.5f);
    return share[i] > 0.0f && u() < share[i] ? vec3(300.0f + n) : vec3(1.0f + n);
  };
  // Rendered in passes as RenderSession does: replicate samples for the
  // pixels that have a slot, the estimate between passes. follow = false:
  // firefly_threshold 0, so nothing is followed (the grid alone).
  auto run = [&](Film& film, bool follow) {
    film.resize(w, h, true);
    Rng image{987654321u}, replicate{12345u};
    double estimate = 0.0;
    render_passes(
        film, w, h, {1, 1, 2, 4, 8, 16, 16, 16}, [&](size_t i, int) { return sample(i, image); },
        [&](size_t i, int, int) { return sample(i, replicate); },
        [&] { estimate = follow ? film.estimated_relative_error() : film.estimated_relative_error(0.0); });
    return estimate;
  };
  Film film, grid;
  const double estimate = run(film, true), grid_only = run(grid, false);
  ASSERT_EQ(2, film.replicate_stride());
  for (auto [x, y] : lit) ASSERT_LT(grid.replicate_slot(x, y), 0);
  // The expected error: per pixel and channel, the variance of one sample
  // (the noise's 1/48 and the light's share (1 - share) 299^2) over 64.
  double mse = 0.0, expected = 0.0, mean = 0.0;
  for (size_t i = 0; i < film.size(); ++i) {
    const vec3 d = film.mean(i) - vec3(1.0f + 299.0f * share[i]);
    mse += (double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z) / 3.0;
    expected += (0.25 * 0.25 / 12.0 + share[i] * (1.0 - share[i]) * 299.0 * 299.0) / 64.0;
    mean += 1.0 + 299.0 * share[i];
    ASSERT_EQ(film.mean(i), grid.mean(i));
  }
  const double t = std::sqrt(expected / mean * film.size() / mean), image = std::sqrt(mse / film.size()) / (mean / film.size());
  std::printf("64 samples: expected error %.4f, this image's %.4f, estimate %.4f, grid alone %.4f; %zu replicates (grid %zu)\n",
              t, image, estimate, grid_only, film.replicate_count(), film.replicate_grid_size());
  EXPECT_EQ(grid.replicate_count(), grid.replicate_grid_size());
  EXPECT_GT(film.followed_replicate_count(), 0u);
  EXPECT_LE(film.followed_replicate_count(), film.replicate_grid_size());
  for (auto [x, y] : lit) EXPECT_GE(film.replicate_slot(x, y), 0) << x << ", " << y;
  EXPECT_LT(grid_only, t / 1.5);
  EXPECT_GT(estimate, t / 1.5);
  EXPECT_LT(estimate, t * 1.5);
}

// Pixels that see a light in a stratified share of their samples (as Sobol
// points give veach_mis.blend's pixels around its smallest light), in an
// image that got two hits too many in each: its error is that image's, over
// 2x what such an image has on average, and the same for every seed there
// (the hit count is set by the stratification). An estimate of the expected
// error cannot see that; the followed pixels' streams are a reference for
// this image's pixel, so the estimate follows this image's error (0.97x it
// here; the estimate before, one replicate stream per followed pixel from
// when it was followed, compared in pairs: 0.36x).
TEST(Controls, ErrorEstimateFollowsThisImagesErrorNotTheExpectedOne) {
  const int w = 48, h = 48;
  std::vector<std::pair<int, int>> lit;
  for (int k = 0; k < 23; ++k) lit.emplace_back(1 + 2 * ((7 * k + 3) % 23), 1 + 2 * ((11 * k + 5) % 23));
  std::vector<float> share(size_t(w) * h, 0.0f);
  for (size_t k = 0; k < lit.size(); ++k) share[size_t(lit[k].second) * w + lit[k].first] = 0.15f + 0.01f * float(k);
  // Sample s of a stream with phase u hits the light when the stratified
  // count floor(s p + u) steps up: any n samples hit it floor or ceil of n p
  // times. The image's streams also hit it at samples 0 and 1.
  auto stratified = [&](size_t i, int s, float u, bool image, Rng& noise) {
    const float p = share[i], n = 0.25f * (noise() - 0.5f);
    if (p == 0.0f) return vec3(1.0f + n);
    const bool hit = std::floor((s + 1) * p + u) > std::floor(s * p + u) || (image && s < 2);
    return vec3(hit ? 300.0f + n : 1.0f + n);
  };
  Film film;
  film.resize(w, h, true);
  Rng image{987654321u}, replicate{12345u}, phase{777u};
  std::vector<float> image_phase(film.size());
  for (float& u : image_phase) u = phase();
  std::vector<std::vector<float>> stream_phase(film.size());
  double estimate = 0.0;
  render_passes(
      film, w, h, {1, 1, 2, 4, 8, 16, 16, 16}, [&](size_t i, int s) { return stratified(i, s, image_phase[i], true, image); },
      [&](size_t i, int s, int k) {
        // Each stream's phase drawn when the stream first samples (streams start at sample 0).
        while (stream_phase[i].size() <= size_t(k)) stream_phase[i].push_back(phase());
        return stratified(i, s, stream_phase[i][size_t(k)], false, replicate);
      },
      [&] { estimate = film.estimated_relative_error(); });
  // This image's error, and what an image with its phases random and no
  // extra hits has on average (the stratified count's, (1/6) 299^2 / n^2 at
  // most: its fractional part's).
  double mse = 0.0, expected = 0.0, mean = 0.0;
  for (size_t i = 0; i < film.size(); ++i) {
    const vec3 d = film.mean(i) - vec3(1.0f + 299.0f * share[i]);
    mse += (double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z) / 3.0;
    expected += share[i] > 0.0f ? 299.0 * 299.0 / 6.0 / (64.0 * 64.0) : 0.25 * 0.25 / 12.0 / 64.0;
    mean += 1.0 + 299.0 * share[i];
  }
  const double t = std::sqrt(mse / film.size()) / (mean / film.size());
  const double t_expected = std::sqrt(expected / film.size()) / (mean / film.size());
  std::printf("64 samples: this image's error %.4f (an average image's at most %.4f), estimate %.4f (%.2fx)\n", t, t_expected,
              estimate, estimate / t);
  ASSERT_GT(t, 2.0 * t_expected);
  for (auto [x, y] : lit) EXPECT_GE(film.replicate_slot(x, y), 0) << x << ", " << y;
  EXPECT_GT(estimate, t / 1.25);
  EXPECT_LT(estimate, t * 1.25);
}

// Where the pixels near bright samples carry little of the image's error
// (a noisy image with a few steady bright pixels, as modern_hall.blend's
// lamps), none is followed: their streams would cost samples and change
// the estimate by little. The same film with the bright pixels noisy is
// followed.
// A bright pixel on the replicate grid whose neighbours are quiet (as the
// pixels near cbox_mitsuba.blend's light once emitter antialiasing took their
// error off): it is the only grid pixel near a bright sample, and nothing is
// followed (its samples are all alike, so their variance puts nothing near
// it). Standing alone for its stratum, its one-degree-of-freedom figure
// counted its error nine times (1.7-1.8x the true error in 3 of 8 seeds
// there); with fewer than Film::kMinNearGridPixels grid pixels near a bright
// sample the stratum counts the whole grid's mean.
TEST(Controls, ErrorEstimateDoesNotLetOneGridPixelStandForThePixelsNearALight) {
  const int w = 48, h = 48, bx = 24, by = 24;
  // Every pixel 1 + uniform noise; the bright one 300 + 0.43 in the image
  // (its error: half the image's squared error) and 300 in its replicate.
  auto value = [&](size_t i, Rng& u, float offset) {
    return i == size_t(by) * w + bx ? vec3(300.0f + offset) : vec3(1.0f + 0.25f * (u() - 0.5f));
  };
  Film film;
  film.resize(w, h, true);
  ASSERT_GE(film.replicate_slot(bx, by), 0);
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx)
      if (dx != 0 || dy != 0) ASSERT_LT(film.replicate_slot(bx + dx, by + dy), 0);
  Rng image{987654321u}, replicate{12345u};
  double estimate = 0.0;
  render_passes(
      film, w, h, {1, 1, 2, 4, 8, 16, 16, 16}, [&](size_t i, int) { return value(i, image, 0.43f); },
      [&](size_t i, int, int) { return value(i, replicate, 0.0f); }, [&] { estimate = film.estimated_relative_error(); });
  EXPECT_EQ(film.followed_replicate_count(), 0u);  // nothing followed
  double mse = 0.0, mean = 0.0;
  for (size_t i = 0; i < film.size(); ++i) {
    const float truth = i == size_t(by) * w + bx ? 300.0f : 1.0f;
    const vec3 d = film.mean(i) - vec3(truth);
    mse += (double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z) / 3.0;
    mean += truth;
  }
  const double truth = std::sqrt(mse / film.size()) / (mean / film.size());
  std::printf("estimate %.4f, this image's error %.4f\n", estimate, truth);
  EXPECT_LT(estimate, 1.5 * truth);
  EXPECT_GT(estimate, truth / 1.5);
}

// A light seen directly whose edge pixels carry the image's error (as
// cbox_mitsuba.blend's at 240 x 135 pixels and 4 spp, before emitter
// antialiasing splits them: two thirds of it), and whose grid pixels are
// inside it (no error) or beside it: the grid alone stood for the edge with
// pixels that have none of its error (the estimate was 0.53-0.64x the true
// error there, 0.58x here). The near stratum's own sample of its pixels
// (every k-th, inside and on the edge in their shares) stands for them.
TEST(Controls, ErrorEstimateSamplesThePixelsNearALightBeyondTheGrid) {
  const int w = 96, h = 96, x0 = 9, x1 = 34, y0 = 9, y1 = 22;  // the light's pixels; its edge off the grid
  // The light covers a share of its edge pixels, which their samples find
  // in a stratified count (floor((s + 1) p + u) steps up; u: each stream's
  // phase); inside it every sample sees it; elsewhere 1 + uniform noise.
  Rng cover{31337u};
  std::vector<float> share(size_t(w) * h, 0.0f);
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x)
      share[size_t(y) * w + x] = x == x0 || x == x1 || y == y0 || y == y1 ? 0.1f + 0.8f * cover() : 1.0f;
  Rng phase{777u}, image{987654321u}, replicate{12345u};
  std::vector<float> image_phase(share.size());
  for (float& u : image_phase) u = phase();
  std::vector<std::vector<float>> stream_phase(share.size());
  auto sample = [&](size_t i, int s, float u, Rng& noise) {
    const float p = share[i];
    if (p == 0.0f) return vec3(1.0f + 0.25f * (noise() - 0.5f));
    return vec3(std::floor((s + 1) * p + u) > std::floor(s * p + u) ? 300.0f : 1.0f);
  };
  Film film;
  film.resize(w, h, true);
  double estimate = 0.0;
  render_passes(
      film, w, h, {1, 1, 2}, [&](size_t i, int s) { return sample(i, s, image_phase[i], image); },
      [&](size_t i, int s, int k) {
        while (stream_phase[i].size() <= size_t(k)) stream_phase[i].push_back(phase());
        return sample(i, s, stream_phase[i][size_t(k)], replicate);
      },
      [&] { estimate = film.estimated_relative_error(); });
  ASSERT_EQ(4, film.replicate_stride());
  ASSERT_TRUE(x0 % 4 && x1 % 4 && y0 % 4 && y1 % 4);  // the edge's columns and rows off the grid
  double mse = 0.0, edge = 0.0, mean = 0.0;
  for (size_t i = 0; i < film.size(); ++i) {
    const float truth = 1.0f + 299.0f * share[i];
    const vec3 d = film.mean(i) - vec3(truth);
    const double e = (double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z) / 3.0;
    mse += e, mean += truth;
    if (share[i] > 0.0f && share[i] < 1.0f) edge += e;
  }
  const double truth = std::sqrt(mse / film.size()) / (mean / film.size());
  size_t stratum = 0;
  for (int y = y0 - 1; y <= y1 + 1; ++y)
    for (int x = x0 - 1; x <= x1 + 1; ++x) stratum += film.replicate_slot(x, y) >= 0;
  std::printf("4 samples: this image's error %.4f (%.0f%% on the light's edge), estimate %.4f (%.2fx); %zu replicated pixels near the light\n",
              truth, 100.0 * edge / mse, estimate, estimate / truth, stratum);
  ASSERT_GT(edge, 0.5 * mse);
  EXPECT_GE(stratum, size_t(Film::kNearStratumPixels));
  EXPECT_GT(estimate, truth / 1.5);
  EXPECT_LT(estimate, truth * 1.5);
}

// The pixels near a bright sample grow in number as rare bright samples turn
// up (cornell_mcguire.blend at 64 spp: from its light's to 4,677 of 8,160
// pixels). Here a noisy light's pixels are near from the first sample, and
// the lower half of the image, quieter, from when its rare bright samples
// come: the near stratum's sample drawn around the light stood for the half
// it was not drawn from (1.64x the true error); drawn again once the
// stratum has doubled, it does not.
TEST(Controls, ErrorEstimateDrawsTheNearStratumAgainAsItGrows) {
  const int w = 96, h = 96;
  // The light: pixels (9..34, 9..22) at 300 +- 200; the lower half (y >=
  // 40): 5, or 400 in one sample of 1024 (over the bright threshold);
  // elsewhere 1 + uniform noise.
  auto light = [](int x, int y) { return x >= 9 && x <= 34 && y >= 9 && y <= 22; };
  auto sample = [&](size_t i, Rng& u) {
    const int x = int(i % w), y = int(i / w);
    if (light(x, y)) return vec3(300.0f + 400.0f * (u() - 0.5f));
    if (y >= 40) return vec3(u() < 1.0f / 1024.0f ? 400.0f : 5.0f);
    return vec3(1.0f + 0.25f * (u() - 0.5f));
  };
  Film film;
  film.resize(w, h, true);
  Rng image{987654321u}, replicate{12345u};
  double estimate = 0.0;
  render_passes(
      film, w, h, {1, 1, 2, 4, 8, 16, 16, 16}, [&](size_t i, int) { return sample(i, image); },
      [&](size_t i, int, int) { return sample(i, replicate); }, [&] { estimate = film.estimated_relative_error(); });
  double mse = 0.0, mean = 0.0;
  size_t stratum_light = 0, stratum_lower = 0;  // replicated pixels off the grid
  for (size_t i = 0; i < film.size(); ++i) {
    const int x = int(i % w), y = int(i / w);
    const float truth = light(x, y) ? 300.0f : y >= 40 ? 5.0f + 395.0f / 1024.0f : 1.0f;
    const vec3 d = film.mean(i) - vec3(truth);
    mse += (double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z) / 3.0;
    mean += truth;
    if (film.replicate_slot(x, y) >= 0 && (x % 4 || y % 4)) ++(y >= 40 ? stratum_lower : stratum_light);
  }
  const double truth = std::sqrt(mse / film.size()) / (mean / film.size());
  std::printf("64 samples: this image's error %.4f, estimate %.4f (%.2fx); replicated off the grid: %zu around the light, %zu below\n",
              truth, estimate, estimate / truth, stratum_light, stratum_lower);
  EXPECT_GT(estimate, truth / 1.25);
  EXPECT_LT(estimate, truth * 1.25);
}

TEST(Controls, ErrorEstimateFollowsOnlyWhereTheBrightPixelsCarryTheError) {
  const int w = 48, h = 48;
  auto run = [&](float bright_noise) {
    Film film;
    film.resize(w, h, true);
    Rng u{4242u};
    auto sample = [&](int x, int y) {
      const bool bright = x % 7 == 3 && y % 7 == 3;
      return bright ? vec3(100.0f + bright_noise * (u() - 0.5f)) : vec3(1.0f + 2.0f * (u() - 0.5f));
    };
    auto pixel_sample = [&](size_t i) { return sample(int(i % w), int(i / w)); };
    render_passes(
        film, w, h, {1, 1, 2, 4, 8}, [&](size_t i, int) { return pixel_sample(i); },
        [&](size_t i, int, int) { return pixel_sample(i); }, [&] { film.estimated_relative_error(); });
    return film.followed_replicate_count();
  };
  EXPECT_EQ(0u, run(1.0f));
  EXPECT_GT(run(200.0f), 0u);
}

// The followed pixels' streams are traced by the tile that owns the pixel,
// caught up from sample 0 whether or not the pixel gets samples of its own
// in that pass (error-driven passes give some none): the estimate, the rays
// and the image are the same with one thread and big tiles as with all
// threads and small ones.
TEST(Controls, ErrorEstimateDoesNotDependOnThreadsOrTiles) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 32);
  RenderOptions opt;
  opt.samples = 256;
  opt.adaptive_threshold = 0.05f;
  opt.error_target = 0.05f;
  opt.threads = 1, opt.tile_size = 32;
  const Result one = render(s, opt);
  opt.threads = 0, opt.tile_size = 5;
  const Result all = render(s, opt);
  std::printf("estimate %.5f, %llu rays, %d samples\n", one.stats.estimated_error, (unsigned long long)one.stats.rays,
              one.stats.samples_done);
  EXPECT_GT(one.stats.estimated_error, 0.0);
  EXPECT_EQ(one.stats.estimated_error, all.stats.estimated_error);
  EXPECT_EQ(one.stats.rays, all.stats.rays);
  EXPECT_EQ(0, std::memcmp(one.px.data(), all.px.data(), one.px.size() * sizeof(float)));
}

TEST(Controls, ErrorTargetStopsWhenTheEstimateIsBelowIt) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 32);
  RenderOptions opt;
  opt.samples = 1 << 16;
  opt.error_target = 0.1f;
  const Result r = render(s, opt);
  EXPECT_STREQ("error target", r.stats.stop_reason);
  EXPECT_LT(r.stats.estimated_error, 0.1);
  EXPECT_LT(r.stats.samples_done, opt.samples);
}

TEST(Controls, ErrorEstimateIsHonest) {
  // The estimate from the two half buffers against the true relative RMSE
  // against a high-sample reference: within a factor 1.5.
  Scene s;
  fixtures::build_cornell_box(s, 24, 24);
  RenderOptions opt;
  opt.seed = 77;
  opt.samples = 2048;
  const std::vector<float> ref = render(s, opt).px;
  opt.seed = 0;
  for (int spp : {16, 64}) {
    opt.samples = spp;
    const Result r = render(s, opt);
    const double truth = rmse(r.px, ref) / mean_rgb(ref);
    const double ratio = r.stats.estimated_error / truth;
    std::printf("%d samples: estimated relative error %.4f, true %.4f, ratio %.3f\n", spp, r.stats.estimated_error, truth, ratio);
    EXPECT_GT(ratio, 1 / 1.5) << spp << " samples: estimate " << r.stats.estimated_error << " true " << truth;
    EXPECT_LT(ratio, 1.5) << spp << " samples: estimate " << r.stats.estimated_error << " true " << truth;
  }
}

TEST(Controls, ErrorEstimateReplicatesFollowTheImageSizeAndCanBeSwitchedOff) {
  // The replicate grid: every pixel of a small image, sparser on larger ones,
  // never fewer than Film::kMinReplicatePixels pixels.
  for (auto [w, h, stride] : {std::tuple{24, 24, 1}, {64, 64, 4}, {120, 120, 4}, {120, 68, 4}, {512, 512, 16}, {1920, 1080, 16}}) {
    Film film;
    film.resize(w, h, true);
    EXPECT_EQ(stride, film.replicate_stride()) << w << "x" << h;
    int replicated = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) replicated += film.replicate_slot(x, y) >= 0;
    EXPECT_GE(replicated, std::min(w * h, Film::kMinReplicatePixels));
  }
  // The class-A count in closed form against counting.
  for (int n = 0, count = 0; n < 300; count += Film::class_a(n), ++n) ASSERT_EQ(count, Film::class_a_count(n)) << n;
  // Off: no replicate samples are traced and nothing is estimated, and the
  // image is the same bit for bit; the error target turns them back on.
  Scene s;
  fixtures::build_cornell_box(s, 16, 16);
  RenderOptions opt;
  opt.samples = 8;
  const Result on = render(s, opt);
  opt.estimate_error = false;
  const Result off = render(s, opt);
  EXPECT_GT(on.stats.estimated_error, 0.0);
  EXPECT_EQ(0.0, off.stats.estimated_error);
  EXPECT_LT(off.stats.rays, on.stats.rays);
  EXPECT_EQ(0, std::memcmp(on.px.data(), off.px.data(), on.px.size() * sizeof(float)));
  opt.error_target = 1e-6f;
  EXPECT_GT(render(s, opt).stats.estimated_error, 0.0);
}

TEST(Controls, SceneWithoutHittableEmittersSkipsTheLastRay) {
  // Lit by a point light only: a BSDF-sampled ray can hit no emitter, so the
  // ray after the last bounce is not traced. Same radiance, fewer rays.
  Scene s;
  fixtures::build_cornell_box_lit_by_a_point_light(s, 16, 16);
  const SceneFeatures f = scene_features(s);
  EXPECT_TRUE(f.emits);
  EXPECT_FALSE(f.hittable_emitters);
  for (int bounces : {1, 4, 8}) {
    RenderOptions opt;
    opt.max_bounces = bounces;
    opt.rr_depth = 100;  // paths end at the bounce limit
    PathCounters all, needed;
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x)
        for (int i = 0; i < 4; ++i) {
          Sampler a(x, y, i, 0), b(x, y, i, 0);
          const Ray ray = s.camera.generate_ray(vec2(x + 0.5f, y + 0.5f));
          const vec3 la = Li(s, ray, a, opt, all, SceneFeatures());
          const vec3 lb = Li(s, ray, b, opt, needed, f);
          ASSERT_EQ(0, std::memcmp(&la, &lb, sizeof(vec3)));
        }
    EXPECT_LT(needed.rays, all.rays);
    std::printf("point light only, %d bounces: %llu rays instead of %llu (%.1f%% fewer)\n", bounces,
                (unsigned long long)needed.rays, (unsigned long long)all.rays,
                100.0 * (1.0 - double(needed.rays) / all.rays));
  }
  // Nothing emits: nothing is traced, the image is black.
  Scene dark;
  fixtures::build_cornell_box(dark, 8, 8);
  dark.materials[3].emission_front = dark.materials[3].emission_back = vec3(0.0f);
  dark.commit();
  EXPECT_FALSE(scene_features(dark).emits);
  RenderOptions opt;
  const Result r = render(dark, opt);
  EXPECT_EQ(0u, r.stats.rays);
  for (size_t i = 0; i < r.px.size(); ++i) EXPECT_EQ(i % 4 == 3 ? 1.0f : 0.0f, r.px[i]);
}
