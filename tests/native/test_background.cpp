// The world's environment image: importance sampling by luminance x
// sin(theta), and the density and radiance it reports for each direction.
#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>
#include <cstdio>
#include <random>

#include "core/background.h"

using namespace tessera;

namespace {
// A 64 x 32 sky with a small bright sun and a dark band, turned by a rotation.
Background sky() {
  const int w = 64, h = 32;
  std::vector<vec3> px(size_t(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      vec3 c(0.2f + 0.01f * x, 0.3f, 0.5f + 0.01f * y);
      if (y < 4) c = vec3(0.0f);                       // black ground band
      if (x >= 50 && x < 52 && y >= 22 && y < 24) c = vec3(2000.0f, 1800.0f, 1500.0f);  // the sun
      px[size_t(y) * w + x] = c;
    }
  Background bg;
  const glm::mat3 rotation = glm::mat3(glm::rotate(mat4(1.0f), 0.7f, vec3(0.3f, 0.2f, 1.0f)));
  bg.set_image(px, w, h, rotation, vec3(1.5f));
  return bg;
}
}  // namespace

TEST(Background, SampledDensityAndRadianceAgreeWithTheirLookups) {
  const Background bg = sky();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (int i = 0; i < 20000; ++i) {
    vec3 wi, le;
    float pdf;
    if (!bg.sample(vec2(U(rng), U(rng)), &wi, &pdf, &le)) continue;
    ASSERT_NEAR(glm::length(wi), 1.0f, 1e-5f);
    float pdf2;
    const vec3 le2 = bg.Le(wi, &pdf2);
    // The same texel, up to the rounding of the direction round trip.
    EXPECT_NEAR(pdf, bg.pdf(wi), 2e-3f * pdf + 1e-6f);
    EXPECT_EQ(pdf2, bg.pdf(wi));
    EXPECT_NEAR(le.x, le2.x, 1e-2f * le.x + 1e-4f);
    EXPECT_EQ(le2, bg.Le(wi));
  }
}

TEST(Background, ImportanceSamplingIsUnbiasedAndTheDensityIntegratesToOne) {
  const Background bg = sky();
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  // Uniform directions: the mean of pdf / (1 / 4 pi) is the density's integral,
  // the mean of Le / (1 / 4 pi) the world's total radiance.
  const int N = 1 << 20;
  double pdf_integral = 0.0, uniform_total = 0.0;
  for (int i = 0; i < N; ++i) {
    const vec3 w = sample_uniform_sphere(vec2(U(rng), U(rng)));
    pdf_integral += bg.pdf(w) / kUniformSpherePdf;
    uniform_total += bg.Le(w).y / kUniformSpherePdf;
  }
  pdf_integral /= N, uniform_total /= N;
  EXPECT_NEAR(pdf_integral, 1.0, 0.01);
  // Importance-sampled: the same total, with far less spread (the sun).
  double total = 0.0, total2 = 0.0;
  int n = 0;
  for (int i = 0; i < (1 << 16); ++i, ++n) {
    vec3 wi, le;
    float pdf;
    if (!bg.sample(vec2(U(rng), U(rng)), &wi, &pdf, &le)) continue;
    const double x = le.y / pdf;
    total += x, total2 += x * x;
  }
  const double mean = total / n, se = std::sqrt((total2 / n - mean * mean) / n);
  std::printf("world total %.4f (uniform directions %.4f), relative standard error %.5f at %d samples\n", mean,
              uniform_total, se / mean, n);
  EXPECT_NEAR(mean, uniform_total, 4.0 * se + 0.02 * uniform_total);
  // Texel weights from the texels alone (not the bilinear cell means) gave 0.065.
  EXPECT_LT(se, 0.01 * mean);
}

TEST(Background, ColumnsWrapAroundTheSeam) {
  // A ramp in u: just either side of the seam (u = 0 and u = 1 are one
  // direction) the bilinear lookup blends the first and last columns.
  const int w = 8, h = 4;
  std::vector<vec3> px(size_t(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) px[size_t(y) * w + x] = vec3(float(x));
  Background bg;
  bg.set_image(px, w, h, glm::mat3(1.0f), vec3(1.0f));
  // Blender's mapping: u = -atan2(y, x) / 2pi + 1/2, so u = 0 and 1 lie along -x.
  const float eps = 1e-3f;
  const vec3 a = bg.Le(glm::normalize(vec3(-1.0f, eps, 0.0f))), b = bg.Le(glm::normalize(vec3(-1.0f, -eps, 0.0f)));
  EXPECT_NEAR(a.x, 3.5f, 0.01f);  // halfway between column 7 and column 0
  EXPECT_NEAR(b.x, 3.5f, 0.01f);
}
