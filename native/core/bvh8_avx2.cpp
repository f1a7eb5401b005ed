// BVH8 traversal compiled for AVX2 and FMA (see bvh8.h): the loops of
// bvh8_traverse.h with the AVX2 forms of their few instruction-set-specific
// steps (below). Every header is included before the target pragma, so
// inline functions from them keep the baseline target and the linker can
// never pick an AVX2 copy for baseline code; the code below the pragma has
// internal linkage except the entry points. FMA makes GCC contract a * b + c
// (even across intrinsics), which would change the triangle test's
// rounding: fp-contract is off for everything below, so the triangle
// arithmetic rounds exactly as in the SSE2 BVH4 and the scalar tests; the
// node test's multiply-adds are explicit.
#include <immintrin.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <new>
#include <type_traits>

#include "bvh8.h"
#include "simd.h"
#include "triangle.h"

namespace tessera {
// Baseline code (outside the target region): the kernel choice.
bool g_bvh8_avx512 = cpu_has_avx512();
}  // namespace tessera

#pragma GCC push_options
#pragma GCC target("avx2,fma")
#pragma GCC optimize("fp-contract=off")
// Vector arguments of the internal lambdas: nothing here crosses an ABI boundary.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"

#define TESSERA_TRI4_AVX 1  // TriRay4 may use AVX (simd_tri4.h)
#include "simd_tri4.h"
#include "wide_traverse.h"

namespace tessera {
namespace {

// For each 8-bit lane mask, the indices of its set lanes in order, one byte
// each (the rest 0): AVX2 has no compress, so push_compressed permutes by these.
constexpr std::array<uint64_t, 256> compress_table() {
  std::array<uint64_t, 256> t{};
  for (int m = 0; m < 256; ++m) {
    int k = 0;
    for (int i = 0; i < 8; ++i)
      if (m >> i & 1) t[m] |= uint64_t(i) << (8 * k++);
  }
  return t;
}
alignas(64) constexpr std::array<uint64_t, 256> kCompressLanes = compress_table();

// The steps of bvh8_traverse.h in AVX2: masks as vectors (all ones on a
// lane, or none), blends by immediates or by those vectors.
struct Avx2 {
  static constexpr bool kTernaryLogic = false;

  // The node test's missed lanes (tnear > tfar: all ones) and entry distances.
  struct NodeHits {
    __m256i near, miss;
  };
  static NodeHits node_hits(__m256i near, __m256i far) { return {near, _mm256_cmpgt_epi32(near, far)}; }
  static unsigned mask(const NodeHits& h) { return ~unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(h.miss))) & 0xFF; }
  // v on the hit lanes, 0 elsewhere.
  static __m256i hit_keys(const NodeHits& h, __m256i v) { return _mm256_andnot_si256(h.miss, v); }
  // key on the hit lanes, all ones elsewhere.
  static __m256i miss_ones(const NodeHits& h, __m256i key) { return _mm256_or_si256(key, h.miss); }
  // One step of the bitonic network: the larger of (v, partner) on the
  // lanes in kTakeMax, the smaller elsewhere.
  template <int kTakeMax>
  static __m256i bitonic_step(__m256i v, __m256i partner) {
    return _mm256_blend_epi32(_mm256_min_epu32(v, partner), _mm256_max_epu32(v, partner), kTakeMax);
  }
  // The lanes of refs in `lanes`, in lane order, stored from dst (eight
  // entries written).
  static void push_compressed(uint32_t* dst, __m256i refs, unsigned lanes) {
    alignas(32) uint32_t r[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(r), refs);
    for (; lanes; lanes &= lanes - 1) *dst++ = r[__builtin_ctz(lanes)];
  }
  // widen_far (aabb.h) lane by lane: x (1 + 2 gamma(3)), then two ulps out
  // unless zero, inf or NaN; a magnitude within two ulps of inf becomes inf.
  static __m128 widen_far(__m128 x) {
    const __m128 sign = _mm_set1_ps(-0.0f);
    const __m128 w = _mm_mul_ps(x, _mm_set1_ps(1.0f + 2.0f * gamma(3)));
    const __m128i mag = _mm_castps_si128(_mm_andnot_ps(sign, w));
    const __m128i keep = _mm_or_si128(_mm_cmpeq_epi32(mag, _mm_setzero_si128()), _mm_cmpgt_epi32(mag, bits(kMaxFloat)));
    const __m128i to_inf = _mm_andnot_si128(keep, _mm_cmpgt_epi32(mag, bits(kMaxFloatMinus2)));
    const __m128i wf = _mm_add_epi32(_mm_castps_si128(w), _mm_andnot_si128(keep, bits(kTwo)));
    const __m128 inf = _mm_or_ps(_mm_and_ps(w, sign), _mm_set1_ps(kInf));
    return _mm_blendv_ps(_mm_castsi128_ps(wf), inf, _mm_castsi128_ps(to_inf));
  }
  // The next float up, on the bit patterns: +1 for a float >= +0 and -1 for
  // a negative one; + 0 first turns -0 into +0. A result below the smallest
  // normal float goes to it (positive) or to +0 (negative), still an upper
  // bound: a subnormal constant would make every node test's multiply-add a
  // microcode assist (~100 cycles), and o inv rounds to 0 wherever an origin
  // coordinate is 0 (a camera on an axis, a ray leaving a floor at z = 0).
  static __m128 next_up(__m128 x) {
    const __m128i b = _mm_castps_si128(_mm_add_ps(x, _mm_setzero_ps()));
    const __m128i r = _mm_add_epi32(b, _mm_or_si128(_mm_srai_epi32(b, 31), bits(kOne)));
    const __m128i min_normal = bits(kMinNormal);
    const __m128i tiny = _mm_cmpgt_epi32(min_normal, _mm_castps_si128(_mm_andnot_ps(_mm_set1_ps(-0.0f), _mm_castsi128_ps(r))));
    const __m128i positive = _mm_cmpgt_epi32(r, _mm_setzero_si128());
    return _mm_castsi128_ps(_mm_or_si128(_mm_andnot_si128(tiny, r), _mm_and_si128(_mm_and_si128(tiny, positive), min_normal)));
  }

 private:
  // Integer constants, loaded from memory (one load each, often folded into
  // the instruction that uses it). Written as immediates, or as floats with
  // their bits, GCC builds them in general registers and moves them over:
  // three instructions each, 18 of a ray's set-up. The empty asm hides the
  // table's contents from the optimiser, so that it keeps the loads; it is
  // not volatile, so all uses share one address.
  enum : int { kMaxFloat, kMaxFloatMinus2, kTwo, kOne, kMinNormal };
  alignas(16) static constexpr uint32_t kBits[5][4] = {{0x7F7FFFFF, 0x7F7FFFFF, 0x7F7FFFFF, 0x7F7FFFFF},
                                                      {0x7F7FFFFD, 0x7F7FFFFD, 0x7F7FFFFD, 0x7F7FFFFD},
                                                      {2, 2, 2, 2},
                                                      {1, 1, 1, 1},
                                                      {0x00800000, 0x00800000, 0x00800000, 0x00800000}};
  static __m128i bits(int which) {
    const uint32_t(*table)[4] = kBits;
    asm("" : "+r"(table));
    return _mm_load_si128(reinterpret_cast<const __m128i*>(table[which]));
  }
};

}  // namespace
}  // namespace tessera

#include "bvh8_traverse.h"

namespace tessera {

#ifdef TESSERA_BVH_COUNTERS
WideCounters g_wide_counters;
#endif

template <bool kOrdered>
bool bvh8_intersect_avx2(const BVH8& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  if (g_bvh8_avx512) return bvh8_intersect_avx512<kOrdered>(bvh, o, d, tmax, hit);
  return bvh8_intersect<Avx2, kOrdered>(bvh, o, d, tmax, hit);
}

template bool bvh8_intersect_avx2<true>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);
template bool bvh8_intersect_avx2<false>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);

bool bvh8_occluded_avx2(const BVH8& bvh, const vec3& o, const vec3& d, float tmax) {
  if (g_bvh8_avx512) return bvh8_occluded_avx512(bvh, o, d, tmax);
  return bvh8_occluded<Avx2>(bvh, o, d, tmax);
}

}  // namespace tessera

#pragma GCC diagnostic pop
#pragma GCC pop_options
