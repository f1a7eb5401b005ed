// Per-(pixel, sample) random numbers: Owen-scrambled Sobol points with
// hash-based nested uniform scrambling (Burley 2020, "Practical Hash-based
// Owen Scrambling", JCGT 9(4)). Every value depends only on the pixel, the
// sample index, the seed and the dimension, never on threads or tile order.
#pragma once
#if defined(__x86_64__)
#include <emmintrin.h>
#endif

#include "math.h"
#include "simd.h"

namespace tessera {

inline uint32_t hash_u32(uint32_t x) {  // "lowbias32" (Wellons 2018)
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}
inline uint32_t hash_combine(uint32_t seed, uint32_t v) { return hash_u32(seed ^ (v + 0x9e3779b9U + (seed << 6) + (seed >> 2))); }

inline uint32_t reverse_bits(uint32_t x) {  // bytes swapped, then nibbles, pairs and bits
  x = __builtin_bswap32(x);
  x = ((x >> 4) & 0x0f0f0f0fU) | ((x & 0x0f0f0f0fU) << 4);
  x = ((x >> 2) & 0x33333333U) | ((x & 0x33333333U) << 2);
  return ((x >> 1) & 0x55555555U) | ((x & 0x55555555U) << 1);
}

// reverse_bits in four instructions on CPUs with GFNI (Intel from Ice Lake,
// AMD from Zen 4): gf2p8affineqb with the anti-diagonal bit matrix reverses
// the bits of each byte, then the bytes are swapped. In inline assembly, so
// that the module built for the x86-64 baseline carries it; the sampler runs
// it only where g_cpu_has_gfni (simd.h; its reversals were a third of its
// work, and the sampler 6-10% of a render).
inline uint32_t reverse_bits_gfni(uint32_t x) {
#if defined(__x86_64__)
  __m128i v = _mm_cvtsi32_si128(int(x));
  const __m128i flip = _mm_set1_epi64x(int64_t(0x8040201008040201ULL));
  __asm__("gf2p8affineqb $0, %1, %0" : "+x"(v) : "x"(flip));
  return __builtin_bswap32(uint32_t(_mm_cvtsi128_si32(v)));
#else
  return reverse_bits(x);
#endif
}

// Laine-Karras style permutation with Burley's improved constants.
inline uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cU;
  x ^= x * 0xb82f1e52U;
  x ^= x * 0xc7afe638U;
  x ^= x * 0x8d22f6e6U;
  return x;
}
inline uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
  return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

// The first two Sobol dimensions: van der Corput, and the dimension whose
// direction numbers are v_i = v_{i-1} ^ (v_{i-1} >> 1) (here bit by bit: the
// definition, which the table below is built from).
inline uint32_t sobol_dim0(uint32_t index) { return reverse_bits(index); }
constexpr uint32_t sobol_dim1(uint32_t index) {
  uint32_t x = 0, v = 0x80000000U;
  for (; index; index >>= 1, v ^= v >> 1)
    if (index & 1U) x ^= v;
  return x;
}
// Sobol dimensions 2 to 5 (Joe and Kuo's direction numbers,
// new-joe-kuo-6.21201, their dimensions 3 to 6: degree s, coefficients a,
// initial m), by definition: v_k = m_k 2^(32-k) for k <= s, then v_k =
// v_{k-s} ^ (v_{k-s} >> s) ^ the v_{k-j} whose bit of a is set (Bratley and
// Fox 1988); a point is the XOR of the v_k of its index's bits.
constexpr int kSobolJointDims = 4;  // dimensions 2 .. 5
constexpr uint32_t sobol_dim(int dim, uint32_t index) {
  constexpr int kS[kSobolJointDims] = {2, 3, 3, 4}, kA[kSobolJointDims] = {1, 1, 2, 1};
  constexpr uint32_t kM[kSobolJointDims][4] = {{1, 3}, {1, 3, 1}, {1, 1, 1}, {1, 1, 3, 3}};
  const int d = dim - 2, s = kS[d], a = kA[d];
  uint32_t v[33] = {};
  for (int k = 1; k <= 32; ++k) {
    if (k <= s) {
      v[k] = kM[d][k - 1] << (32 - k);
      continue;
    }
    v[k] = v[k - s] ^ (v[k - s] >> s);
    for (int j = 1; j < s; ++j)
      if ((a >> (s - 1 - j)) & 1) v[k] ^= v[k - j];
  }
  uint32_t x = 0;
  for (int k = 1; index; ++k, index >>= 1)
    if (index & 1U) x ^= v[k];
  return x;
}
constexpr uint32_t reverse_bits_serial(uint32_t x) {
  uint32_t r = 0;
  for (int i = 0; i < 32; ++i) r |= ((x >> i) & 1U) << (31 - i);
  return r;
}

// reverse_bits(sobol_dim1(reverse_bits(w))) by one table entry per byte of w
// (4 KiB, built at compile time): sobol_dim1 is linear over GF(2) in the
// index bits and bit reversal is a permutation of bits, so both commute with
// XOR, and w's byte k holds index byte 3 - k with its bits reversed. The
// sampler draws the shuffled index bit-reversed (w) and scrambles the point
// bit-reversed, so this takes both reversals of the y coordinate off its
// dependency chain (and the bit-serial loop's 32 steps).
struct SobolDim1ReversedTable {
  uint32_t byte[4][256];
  constexpr SobolDim1ReversedTable() : byte{} {
    for (int k = 0; k < 4; ++k)
      for (uint32_t b = 0; b < 256; ++b) byte[k][b] = reverse_bits_serial(sobol_dim1(reverse_bits_serial(b) >> (8 * k)));
  }
};
inline constexpr SobolDim1ReversedTable kSobolDim1Reversed{};
inline uint32_t sobol_dim1_reversed(uint32_t w) {
  return kSobolDim1Reversed.byte[0][w & 255U] ^ kSobolDim1Reversed.byte[1][(w >> 8) & 255U] ^
         kSobolDim1Reversed.byte[2][(w >> 16) & 255U] ^ kSobolDim1Reversed.byte[3][w >> 24];
}

// The same for Sobol dimensions 2 to 5 (Sampler::get_2d_joint), by
// nibbles: eight lookups in 512 bytes a dimension, where byte tables would
// take 16 KiB of the L1 cache beside the 4 KiB of dimension 1's.
struct SobolJointReversedTable {
  uint32_t nibble[kSobolJointDims][8][16];
  constexpr SobolJointReversedTable() : nibble{} {
    for (int d = 0; d < kSobolJointDims; ++d)
      for (int k = 0; k < 8; ++k)
        for (uint32_t b = 0; b < 16; ++b)
          nibble[d][k][b] = reverse_bits_serial(sobol_dim(d + 2, reverse_bits_serial(b << (4 * k))));
  }
};
inline constexpr SobolJointReversedTable kSobolJointReversed{};
// reverse_bits(sobol_dim(dim, reverse_bits(w))), dim in 2 .. 5.
inline uint32_t sobol_dim_reversed(int dim, uint32_t w) {
  const auto& t = kSobolJointReversed.nibble[dim - 2];
  uint32_t x = 0;
  for (int k = 0; k < 8; ++k) x ^= t[k][(w >> (4 * k)) & 15U];
  return x;
}

// The top 24 bits, exactly: rounding all 32 to a float could carry a value
// across a stratum's edge (or to 1), breaking the points' stratification.
inline float u32_to_unit_float(uint32_t x) { return float(x >> 8) * 0x1p-24f; }

// The scrambling seeds of one pixel's stream: per dimension pair, the seed s
// of the index shuffle and the seeds of its two coordinates' scrambles,
// hash_combine(s, 1) and hash_combine(s, 2). They depend on the pixel, the
// seed and the dimension, not on the sample, so all the samples a pixel
// takes in a pass share them: each is hashed once, on its first use, for
// the first kCached dimensions (a path of 8 bounces draws 4 a bounce), and
// later samples read them (three hashes of the ~125 operations a 2D point
// takes). A deeper dimension is hashed at each use.
struct StreamSeeds {
  static constexpr uint32_t kCached = 40;
  uint32_t pixel_seed;
  uint32_t cached = 0;  // dimensions 0 .. cached - 1 are in seed[]
  uint32_t seed[kCached][3];

  StreamSeeds(uint32_t px, uint32_t py, uint32_t seed_)
      : pixel_seed(hash_combine(hash_combine(hash_u32(seed_), px), py)) {}

  static void hash(uint32_t pixel_seed, uint32_t dimension, uint32_t out[3]) {
    out[0] = hash_combine(pixel_seed, dimension);
    out[1] = hash_combine(out[0], 1);
    out[2] = hash_combine(out[0], 2);
  }
  // The seeds of `dimension`, in `scratch` when it is not cached. Dimensions
  // are drawn in order from 0, so the cached ones are a prefix.
  const uint32_t* of(uint32_t dimension, uint32_t scratch[3]) {
    if (dimension < cached) return seed[dimension];
    uint32_t* out = dimension == cached && cached < kCached ? seed[cached++] : scratch;
    hash(pixel_seed, dimension, out);
    return out;
  }
};

// Stream for one (pixel, sample): dimension pairs are drawn in order, each
// pair decorrelated from the others by its own scrambling seed.
// Each dimension pair: the sample index shuffled, index =
// nested_uniform_scramble(sample, s), then the Sobol point at that index,
// each coordinate scrambled, nested_uniform_scramble(sobol_dimK(index), s_K).
// Computed with the reversals that cancel left out: the shuffle's inner
// reversal of `sample` once per stream, x's two around sobol_dim0, and y's
// through sobol_dim1_reversed (test Sampler.StreamEqualsTheNestedScrambleDefinition).
// The seeds come from the pixel's StreamSeeds when the sampler has one
// (the same numbers: test Sampler.SharedSeedsGiveTheSameStream).
struct Sampler {
  uint32_t pixel_seed;
  uint32_t sample_reversed;  // reverse_bits(sample index)
  uint32_t dimension = 0;
  StreamSeeds* seeds = nullptr;
  uint32_t first_w = 0;  // the first pair's shuffled index, bit-reversed (get_2d_joint)
  bool has_first = false;
  int joint_dim = 2;  // the next Sobol dimension get_2d_joint draws

  Sampler(uint32_t px, uint32_t py, uint32_t sample_index, uint32_t seed)
      : pixel_seed(hash_combine(hash_combine(hash_u32(seed), px), py)), sample_reversed(reverse_bits(sample_index)) {}
  // Sample `sample_index` of the pixel whose stream `shared` is.
  Sampler(StreamSeeds& shared, uint32_t sample_index)
      : pixel_seed(shared.pixel_seed), sample_reversed(reverse_bits(sample_index)), seeds(&shared) {}

  // The bit reversals by GFNI where the CPU has it: the same numbers (test
  // Sampler.GfniDrawsArePortableDraws), one branch a draw.
  vec2 get_2d() { return g_cpu_has_gfni ? get_2d_with<true>() : get_2d_with<false>(); }
  float get_1d() { return g_cpu_has_gfni ? get_1d_with<true>() : get_1d_with<false>(); }
  // The next pair, not from a shuffle of its own but as the next two Sobol
  // dimensions of the first pair's shuffled index (2 and 3 at the first
  // call, 4 and 5 at the second; each coordinate scrambled by its own
  // seed), while there are any, else get_2d(): the first pair (the pixel
  // position) and these are the first dimensions of one scrambled Sobol
  // sequence, stratified together. The integrator draws the first two
  // bounces' directions so: with independent shuffles, which part of the
  // pixel a sample lands in said nothing about where its path went next.
  // Per-pixel variance at 64 samples over 8 seeds, two seed sets: McGuire's
  // Cornell box -5 to -7%, cbox_mitsuba -7%, veach_mis -10%, modern_hall
  // -0.5% (docs/convergence/NOTES.md; a third bounce's direction from
  // dimensions 6 and 7 did worse on the Cornell box). Only after get_2d drew
  // the first pair.
  vec2 get_2d_joint() {
    if (!has_first || joint_dim + 1 >= 2 + kSobolJointDims) return get_2d();
    return g_cpu_has_gfni ? get_2d_joint_with<true>() : get_2d_joint_with<false>();
  }

  template <bool kGfni>
  vec2 get_2d_joint_with() {
    uint32_t scratch[3];
    const uint32_t* s = dimension_seeds(scratch);
    const uint32_t x = reverse<kGfni>(laine_karras_permutation(sobol_dim_reversed(joint_dim, first_w), s[1]));
    const uint32_t y = reverse<kGfni>(laine_karras_permutation(sobol_dim_reversed(joint_dim + 1, first_w), s[2]));
    joint_dim += 2;
    return vec2(u32_to_unit_float(x), u32_to_unit_float(y));
  }

  template <bool kGfni>
  vec2 get_2d_with() {
    uint32_t scratch[3];
    const bool first = dimension == 0;
    const uint32_t* s = dimension_seeds(scratch);
    const uint32_t w = laine_karras_permutation(sample_reversed, s[0]);  // the shuffled index, bit-reversed
    if (first) first_w = w, has_first = true;
    const uint32_t x = reverse<kGfni>(laine_karras_permutation(reverse<kGfni>(w), s[1]));
    const uint32_t y = reverse<kGfni>(laine_karras_permutation(sobol_dim1_reversed(w), s[2]));
    return vec2(u32_to_unit_float(x), u32_to_unit_float(y));
  }
  template <bool kGfni>
  float get_1d_with() {
    uint32_t scratch[3];
    const uint32_t* s = dimension_seeds(scratch);
    const uint32_t w = laine_karras_permutation(sample_reversed, s[0]);
    return u32_to_unit_float(reverse<kGfni>(laine_karras_permutation(reverse<kGfni>(w), s[1])));
  }

 private:
  template <bool kGfni>
  static uint32_t reverse(uint32_t x) { return kGfni ? reverse_bits_gfni(x) : reverse_bits(x); }

  const uint32_t* dimension_seeds(uint32_t scratch[3]) {
    const uint32_t d = dimension++;
    if (seeds) return seeds->of(d, scratch);
    StreamSeeds::hash(pixel_seed, d, scratch);
    return scratch;
  }
};

}  // namespace tessera
