// The per-(pixel, sample) sampler: its Sobol dimensions and the net property
// the Owen scrambling must keep.
#include <gtest/gtest.h>

#include <algorithm>

#include "core/sampler.h"
#include "core/sampling.h"

using namespace tessera;

// The table form of the second Sobol dimension on the bit-reversed index
// equals the bit-serial definition (and the shift-and-mask reversal the
// bit-by-bit one).
TEST(Sampler, SobolDim1ReversedTableEqualsTheBitSerialConstruction) {
  uint32_t w = 12345;
  for (int i = 0; i < 200000; ++i) {
    w = hash_u32(w + uint32_t(i));
    ASSERT_EQ(reverse_bits(w), reverse_bits_serial(w)) << w;
    ASSERT_EQ(sobol_dim1_reversed(w), reverse_bits(sobol_dim1(reverse_bits(w)))) << w;
  }
  for (uint32_t i = 0; i < 4096; ++i) ASSERT_EQ(sobol_dim1_reversed(reverse_bits(i)), reverse_bits(sobol_dim1(i)));
  EXPECT_EQ(sobol_dim1_reversed(0xffffffffU), reverse_bits(sobol_dim1(0xffffffffU)));
}

// Sobol dimensions 2 to 5 are those of Joe and Kuo's table (their first
// points; in their 1-based numbering dimensions 3 to 6), and their reversed
// tables the definition's.
TEST(Sampler, SobolDims2To5AreJoeKuosAndTheirTablesTheDefinition) {
  // Points 0..7 times 8, worked by hand: v = 1/2, 3/4, 3/8 (m = 1 3, then
  // m_3 = 2 m_2 ^ 4 m_1 ^ m_1 = 3); 1/2, 3/4, 1/8 (m = 1 3 1); 1/2, 1/4, 1/8
  // (m = 1 1 1); 1/2, 1/4, 3/8 (m = 1 1 3): each point the XOR of the v of
  // its index's bits.
  const uint32_t points[4][8] = {
      {0, 4, 6, 2, 3, 7, 5, 1}, {0, 4, 6, 2, 1, 5, 7, 3}, {0, 4, 2, 6, 1, 5, 3, 7}, {0, 4, 2, 6, 3, 7, 1, 5}};
  for (int d = 2; d < 6; ++d)
    for (uint32_t i = 0; i < 8; ++i) EXPECT_EQ(sobol_dim(d, i) >> 29, points[d - 2][i]) << "dim " << d << " index " << i;
  uint32_t w = 999;
  for (int i = 0; i < 100000; ++i) {
    w = hash_u32(w + uint32_t(i));
    for (int d = 2; d < 6; ++d) ASSERT_EQ(sobol_dim_reversed(d, w), reverse_bits(sobol_dim(d, reverse_bits(w)))) << w;
  }
}

// The joint pairs are the definition: Sobol dimensions 2 and 3, then 4 and
// 5, of the first pair's shuffled index, each coordinate scrambled with its
// own pair's seeds, the pairs around them untouched; then, or without a
// first pair drawn, ordinary pairs.
TEST(Sampler, JointPairsAreTheFirstPairsNextSobolDimensions) {
  for (uint32_t sample : {0U, 1U, 5U, 63U, 1000U, 65537U}) {
    const uint32_t pixel_seed = hash_combine(hash_combine(hash_u32(42), 2), 3);
    const uint32_t index = nested_uniform_scramble(sample, hash_combine(pixel_seed, 0));
    Sampler joint(2, 3, sample, 42), plain(2, 3, sample, 42);
    ASSERT_EQ(joint.get_2d(), plain.get_2d());
    ASSERT_EQ(joint.get_2d(), plain.get_2d());
    for (uint32_t pair : {2U, 5U}) {
      const uint32_t s = hash_combine(pixel_seed, pair);
      const int dim = pair == 2 ? 2 : 4;
      const vec2 j = joint.get_2d_joint();
      plain.get_2d();
      EXPECT_EQ(j.x, u32_to_unit_float(nested_uniform_scramble(sobol_dim(dim, index), hash_combine(s, 1))));
      EXPECT_EQ(j.y, u32_to_unit_float(nested_uniform_scramble(sobol_dim(dim + 1, index), hash_combine(s, 2))));
      for (int d = 0; d < 2; ++d) ASSERT_EQ(joint.get_2d(), plain.get_2d()) << "after pair " << pair;
    }
    ASSERT_EQ(joint.get_2d_joint(), plain.get_2d()) << "the third joint draw";
    Sampler fresh(2, 3, sample, 42), ordinary(2, 3, sample, 42);
    EXPECT_EQ(fresh.get_2d_joint(), ordinary.get_2d());
  }
}

// The first pair and each joint pair are one scrambled 4D Sobol sequence:
// in 2^m samples of a pixel, every cell of a 2 x 2 x 2 x 2 grid over the
// four coordinates holds 2^m / 16 of them once boxes that size are
// guaranteed their share (Sobol's dimensions 0 1 2 3 have t = 3, 0 1 4 5
// t = 5: boxes of volume 2^(t - m) hold 2^t points). With independent
// shuffles, as any two other pairs, the cells' counts scatter.
TEST(Sampler, FirstAndJointPairsAreStratifiedTogether) {
  for (int m : {7, 9}) {
    const uint32_t n = 1U << m;
    for (uint32_t pixel = 0; pixel < 4; ++pixel) {
      std::vector<int> first_cells(16, 0), second_cells(16, 0), plain_cells(16, 0);
      auto cell = [](vec2 u, vec2 v) { return int(u.x * 2) + 2 * int(u.y * 2) + 4 * int(v.x * 2) + 8 * int(v.y * 2); };
      for (uint32_t s = 0; s < n; ++s) {
        Sampler a(pixel, 9, s, 5), b(pixel, 9, s, 5);
        const vec2 p = a.get_2d(), q = b.get_2d();
        a.get_2d(), b.get_2d();
        const vec2 j1 = a.get_2d_joint(), k = b.get_2d();
        a.get_2d();
        const vec2 j2 = a.get_2d_joint();
        ++first_cells[cell(p, j1)];
        ++second_cells[cell(p, j2)];
        ++plain_cells[cell(q, k)];
      }
      int spread = 0;
      for (int c = 0; c < 16; ++c) {
        ASSERT_EQ(first_cells[c], int(n / 16)) << "m=" << m << " pixel " << pixel << " cell " << c;
        if (m >= 9) ASSERT_EQ(second_cells[c], int(n / 16)) << "m=" << m << " pixel " << pixel << " cell " << c;
        spread += std::abs(plain_cells[c] - int(n / 16));
      }
      EXPECT_GT(spread, 0) << "independent pairs came out stratified together: the test sees nothing";
    }
  }
}

// GFNI's bit reversal and the sampler's draws with it are the portable
// ones, bit for bit (the sampler takes them wherever the CPU has GFNI).
TEST(Sampler, GfniDrawsArePortableDraws) {
  if (!g_cpu_has_gfni) GTEST_SKIP() << "no GFNI on this CPU (or TESSERA_SIMD=sse2)";
  uint32_t w = 777;
  for (uint32_t x : {0U, 1U, 0x80000000U, 0xffffffffU, 0x12345678U}) ASSERT_EQ(reverse_bits_gfni(x), reverse_bits(x)) << x;
  for (int i = 0; i < 200000; ++i) {
    w = hash_u32(w + uint32_t(i));
    ASSERT_EQ(reverse_bits_gfni(w), reverse_bits(w)) << w;
  }
  for (uint32_t sample : {0U, 1U, 5U, 64U, 1000U, 65537U, 0xfffffffeU}) {
    Sampler a(3, 4, sample, 9), b(3, 4, sample, 9);
    for (int d = 0; d < 50; ++d) {
      if (d % 4 == 3) {
        ASSERT_EQ(a.get_1d_with<true>(), b.get_1d_with<false>()) << "sample " << sample << " dim " << d;
      } else if (d == 2 || d == 6) {
        ASSERT_EQ(a.get_2d_joint_with<true>(), b.get_2d_joint_with<false>()) << "sample " << sample << " dim " << d;
      } else {
        const vec2 u = a.get_2d_with<true>(), v = b.get_2d_with<false>();
        ASSERT_EQ(u.x, v.x) << "sample " << sample << " dim " << d;
        ASSERT_EQ(u.y, v.y) << "sample " << sample << " dim " << d;
      }
    }
  }
}

// The stream as the definition spells it (Burley 2020): index =
// nested_uniform_scramble(sample, s), x = nested_uniform_scramble(
// sobol_dim0(index), s1), y = nested_uniform_scramble(sobol_dim1(index), s2);
// the sampler computes it without the reversals that cancel.
TEST(Sampler, StreamEqualsTheNestedScrambleDefinition) {
  for (uint32_t pixel = 0; pixel < 4; ++pixel)
    for (uint32_t sample : {0U, 1U, 2U, 3U, 63U, 64U, 1000U, 65537U, 0xfffffffeU}) {
      Sampler sampler(pixel, 3, sample, 42);
      const uint32_t pixel_seed = hash_combine(hash_combine(hash_u32(42), pixel), 3);
      for (uint32_t dim = 0; dim < 12; ++dim) {
        const uint32_t s = hash_combine(pixel_seed, dim);
        const uint32_t index = nested_uniform_scramble(sample, s);
        const float x = u32_to_unit_float(nested_uniform_scramble(sobol_dim0(index), hash_combine(s, 1)));
        const float y = u32_to_unit_float(nested_uniform_scramble(sobol_dim1(index), hash_combine(s, 2)));
        if (dim % 3 == 2) {
          ASSERT_EQ(sampler.get_1d(), x) << "sample " << sample << " dim " << dim;
        } else {
          const vec2 u = sampler.get_2d();
          ASSERT_EQ(u.x, x) << "sample " << sample << " dim " << dim;
          ASSERT_EQ(u.y, y) << "sample " << sample << " dim " << dim;
        }
      }
    }
}

// A pixel's samples drawn through one StreamSeeds (render.cpp) give the
// numbers of samplers that hash every seed: for paths of any length, in any
// order, past the dimensions it caches, and after a short path left the
// cache part-filled.
TEST(Sampler, SharedSeedsGiveTheSameStream) {
  for (uint32_t pixel = 0; pixel < 3; ++pixel) {
    StreamSeeds shared(pixel, 5, 7);
    uint32_t lengths = 0x2468ace1U;
    for (uint32_t sample : {0U, 9U, 1U, 2U, 1000U, 3U, 65537U, 4U}) {
      lengths = hash_u32(lengths);
      const uint32_t dims = sample == 0 ? 3 : lengths % (StreamSeeds::kCached + 20);
      Sampler own(pixel, 5, sample, 7), cached(shared, sample);
      for (uint32_t d = 0; d < dims; ++d) {
        if ((d * 7 + sample) % 3 == 0) {
          ASSERT_EQ(cached.get_1d(), own.get_1d()) << "sample " << sample << " dim " << d;
        } else {
          const vec2 a = cached.get_2d(), b = own.get_2d();
          ASSERT_EQ(a.x, b.x) << "sample " << sample << " dim " << d;
          ASSERT_EQ(a.y, b.y) << "sample " << sample << " dim " << d;
        }
      }
    }
    EXPECT_EQ(shared.cached, StreamSeeds::kCached);
  }
}

// The first 2^m samples of every dimension pair of a pixel form a (0, m, 2)-net:
// each of the 2^m elementary intervals of every shape (2^k by 2^(m-k) cells)
// holds exactly one point (Burley 2020: shuffled and scrambled Sobol keeps it).
TEST(Sampler, EveryDimensionPairIsANetOverPowerOfTwoSampleCounts) {
  for (int m : {4, 6, 8}) {
    const uint32_t n = 1U << m;
    for (uint32_t pixel = 0; pixel < 3; ++pixel) {
      for (int pair = 0; pair < 6; ++pair) {
        std::vector<vec2> points;
        for (uint32_t s = 0; s < n; ++s) {
          Sampler sampler(pixel, 7, s, 99);
          vec2 u(0.0f);
          for (int d = 0; d <= pair; ++d) u = sampler.get_2d();
          ASSERT_GE(u.x, 0.0f);
          ASSERT_LT(u.x, 1.0f);
          points.push_back(u);
        }
        for (int k = 0; k <= m; ++k) {
          const uint32_t nx = 1U << k, ny = n >> k;
          std::vector<int> cells(n, 0);
          for (const vec2& p : points) ++cells[uint32_t(p.y * ny) * nx + uint32_t(p.x * nx)];
          for (uint32_t c = 0; c < n; ++c)
            ASSERT_EQ(cells[c], 1) << "m=" << m << " pair " << pair << " shape " << nx << "x" << ny;
        }
      }
    }
  }
}

// The guide table finds the same segment as a binary search over the CDF
// (the last one whose start is <= u), zero-weight segments included.
TEST(Sampler, Distribution1DGuideTableFindsTheBinarySearchSegment) {
  uint32_t x = 7;
  auto next = [&] { return u32_to_unit_float(x = hash_u32(x + 1)); };
  for (int trial = 0; trial < 50; ++trial) {
    const size_t n = 1 + size_t(next() * 300);
    std::vector<float> f(n);
    for (float& v : f) v = next() < 0.3f ? 0.0f : next() * (next() < 0.1f ? 1000.0f : 1.0f);
    const Distribution1D d(f.data(), n);
    for (int i = 0; i < 2000; ++i) {
      const float u = i < 1000 ? next() : d.cdf[size_t(next() * n)];  // also exactly on segment starts
      if (!(u < 1.0f)) continue;
      const size_t lo = size_t(std::upper_bound(d.cdf.begin(), d.cdf.end(), u) - d.cdf.begin());
      const size_t expected = std::min(lo == 0 ? 0 : lo - 1, n - 1);
      float pdf;
      size_t offset;
      d.sample_continuous(u, &pdf, &offset);
      ASSERT_EQ(expected, offset) << "n " << n << " u " << u;
    }
  }
}

// sample_uniform_cone: unit directions within the cone, cos(theta) uniform in
// [cos_max, 1] (equal solid angle per band) and no preferred azimuth.
TEST(Sampling, UniformConeIsUniformInTheCone) {
  for (const float cos_max : {-1.0f, 0.0f, 0.9f}) {
    const int n = 64;
    double mean_z = 0.0, mean_x = 0.0, mean_y = 0.0;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const vec3 w = sample_uniform_cone(vec2((i + 0.5f) / n, (j + 0.5f) / n), cos_max);
        ASSERT_NEAR(glm::length(w), 1.0f, 1e-5f);
        ASSERT_GE(w.z, cos_max - 1e-6f);
        mean_z += w.z, mean_x += w.x, mean_y += w.y;
      }
    const double m = double(n) * n;
    EXPECT_NEAR(mean_z / m, 0.5 * (1.0 + cos_max), 1e-4) << cos_max;
    EXPECT_NEAR(mean_x / m, 0.0, 1e-4) << cos_max;
    EXPECT_NEAR(mean_y / m, 0.0, 1e-4) << cos_max;
  }
  EXPECT_FLOAT_EQ(uniform_cone_pdf(-1.0f), kUniformSpherePdf);
}
