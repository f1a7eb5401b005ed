// Speed/accuracy controls: sample count, per-kind bounce limits, clamping,
// adaptive sampling, time limit, error target and the error estimate.
// Correctness only, never wall-clock.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <tuple>

#include "core/render.h"
#include "scene_fixtures.h"

using namespace tessera;

namespace {
struct Result {
  std::vector<float> px;
  RenderStats stats;
};
Result render(const Scene& s, RenderOptions opt) {
  RenderSession session(s, opt);
  session.render();
  return {session.pixels(), session.stats()};
}
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
double mean_rgb(const std::vector<float>& a) {
  double m = 0.0;
  for (size_t i = 0; i < a.size(); ++i)
    if (i % 4 != 3) m += a[i];
  return m / (a.size() / 4 * 3);
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
  opt.threads = 1;
  const Result one = render(s, opt);
  opt.threads = 0;
  opt.tile_size = 5;
  const Result all = render(s, opt);
  ASSERT_EQ(one.px.size(), all.px.size());
  EXPECT_EQ(0, std::memcmp(one.px.data(), all.px.data(), one.px.size() * sizeof(float)));
  EXPECT_EQ(one.stats.pixel_samples, all.stats.pixel_samples);
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
  fixtures::build_cornell_box(s, 16, 16);
  s.materials[3].emission_front = s.materials[3].emission_back = vec3(0.0f);
  Light point;
  point.type = LightType::Point;
  point.position = vec3(0.0f, 0.8f, 0.0f);
  point.radiance = vec3(5.0f);
  s.lights.push_back(point);
  s.commit();
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
