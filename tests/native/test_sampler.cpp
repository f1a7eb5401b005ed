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

// Sobol dimensions 2 and 3 are those of Joe and Kuo's table (their first
// points, in the usual 1-based numbering dimensions 3 and 4), and their
// reversed tables the definition's.
TEST(Sampler, SobolDims23AreJoeKuosAndTheirTablesTheDefinition) {
  // Points 0..7 of Joe-Kuo dimensions 3 and 4, times 8, worked by hand from
  // v = 1/2, 3/4, 3/8 (m = 1, 3, then m_3 = 2 m_2 ^ 4 m_1 ^ m_1 = 3) and
  // v = 1/2, 3/4, 1/8 (m = 1, 3, 1), each point the XOR of the v of its
  // index's bits.
  const uint32_t d2[8] = {0, 4, 6, 2, 3, 7, 5, 1}, d3[8] = {0, 4, 6, 2, 1, 5, 7, 3};
  for (uint32_t i = 0; i < 8; ++i) {
    EXPECT_EQ(sobol_dim23(2, i) >> 29, d2[i]) << "index " << i;
    EXPECT_EQ(sobol_dim23(3, i) >> 29, d3[i]) << "index " << i;
  }
  uint32_t w = 999;
  for (int i = 0; i < 100000; ++i) {
    w = hash_u32(w + uint32_t(i));
    ASSERT_EQ(sobol_dim23_reversed(2, w), reverse_bits(sobol_dim23(2, reverse_bits(w)))) << w;
    ASSERT_EQ(sobol_dim23_reversed(3, w), reverse_bits(sobol_dim23(3, reverse_bits(w)))) << w;
  }
}

// The joint pair is the definition: Sobol dimensions 2 and 3 of the first
// pair's shuffled index, each scrambled with its own pair's seeds, the
// pairs around it untouched; without a first pair drawn, an ordinary pair.
TEST(Sampler, JointPairIsTheFirstPairsNextSobolDimensions) {
  for (uint32_t sample : {0U, 1U, 5U, 63U, 1000U, 65537U}) {
    const uint32_t pixel_seed = hash_combine(hash_combine(hash_u32(42), 2), 3);
    const uint32_t s0 = hash_combine(pixel_seed, 0), s2 = hash_combine(pixel_seed, 2);
    const uint32_t index = nested_uniform_scramble(sample, s0);
    Sampler joint(2, 3, sample, 42), plain(2, 3, sample, 42);
    const vec2 a = joint.get_2d(), b = plain.get_2d();
    ASSERT_EQ(a, b);
    ASSERT_EQ(joint.get_2d(), plain.get_2d());
    const vec2 j = joint.get_2d_joint();
    plain.get_2d();
    EXPECT_EQ(j.x, u32_to_unit_float(nested_uniform_scramble(sobol_dim23(2, index), hash_combine(s2, 1))));
    EXPECT_EQ(j.y, u32_to_unit_float(nested_uniform_scramble(sobol_dim23(3, index), hash_combine(s2, 2))));
    for (int d = 0; d < 5; ++d) ASSERT_EQ(joint.get_2d(), plain.get_2d()) << "pair " << 3 + d;
    Sampler fresh(2, 3, sample, 42), ordinary(2, 3, sample, 42);
    EXPECT_EQ(fresh.get_2d_joint(), ordinary.get_2d());
  }
}

// The first pair and the joint pair are one scrambled 4D Sobol sequence: in
// 2^m samples of a pixel, every cell of a 2 x 2 x 2 x 2 grid over the four
// coordinates holds 2^m / 16 of them (Sobol's first four dimensions have
// t = 3: boxes of volume 2^(3 - m) hold 8 points each). With independent
// shuffles, as any two other pairs, the cells' counts scatter.
TEST(Sampler, FirstAndJointPairsAreStratifiedTogether) {
  for (int m : {5, 8}) {
    const uint32_t n = 1U << m;
    for (uint32_t pixel = 0; pixel < 4; ++pixel) {
      std::vector<int> joint_cells(16, 0), plain_cells(16, 0);
      for (uint32_t s = 0; s < n; ++s) {
        Sampler a(pixel, 9, s, 5), b(pixel, 9, s, 5);
        const vec2 p = a.get_2d(), q = b.get_2d();
        a.get_2d(), b.get_2d();
        const vec2 j = a.get_2d_joint(), k = b.get_2d();
        auto cell = [](vec2 u, vec2 v) { return int(u.x * 2) + 2 * int(u.y * 2) + 4 * int(v.x * 2) + 8 * int(v.y * 2); };
        ++joint_cells[cell(p, j)];
        ++plain_cells[cell(q, k)];
      }
      int spread = 0;
      for (int c = 0; c < 16; ++c) {
        ASSERT_EQ(joint_cells[c], int(n / 16)) << "m=" << m << " pixel " << pixel << " cell " << c;
        spread += std::abs(plain_cells[c] - int(n / 16));
      }
      if (m == 8) EXPECT_GT(spread, 0) << "independent pairs came out stratified together: the test sees nothing";
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
      } else if (d == 2) {
        ASSERT_EQ(a.get_2d_joint_with<true>(), b.get_2d_joint_with<false>()) << "sample " << sample;
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
