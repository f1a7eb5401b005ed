// BVH8 traversal compiled for AVX-512 (F, VL, DQ, BW) and FMA, chosen at run
// time over the AVX2 one (bvh8_avx2.cpp) when the CPU has it: the same loops
// (bvh8_traverse.h), same tree, same triangle test. What AVX-512 changes:
// - the node test's compare lands in a mask register (no movemask), and the
//   child sort's masked keys and steps are single masked instructions;
// - any hit pushes the hit children with one vpcompressd and store;
// - the triangle test's zero and sign tests by three-input logic
//   (vpternlogd, intersect_tri4<true>), same result.
// Headers come before the target pragma (see bvh8_avx2.cpp). FMA makes GCC
// contract a * b + c (even across intrinsics), which would change the
// triangle test's rounding: fp-contract is off for everything below; the
// node test's multiply-adds are explicit.
#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <new>
#include <type_traits>

#include "bvh8.h"
#include "triangle.h"

#pragma GCC push_options
#pragma GCC target("avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")
#pragma GCC optimize("fp-contract=off")
// GCC 12's AVX-512 intrinsics trip -Wmaybe-uninitialized (their
// _mm*_undefined sources); vector values never cross a non-inline call here.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wpsabi"

#define TESSERA_TRI4_AVX 1  // TriRay4 may use AVX (simd_tri4.h)
#include "simd_tri4.h"
#include "wide_traverse.h"

namespace tessera {
namespace {

// The steps of bvh8_traverse.h that AVX-512 does with mask registers.
struct Avx512 {
  static constexpr bool kTernaryLogic = true;

  // The node test's hit lanes (tnear <= tfar) and entry distances.
  struct NodeHits {
    __mmask8 hit;
    __m256i near;
  };
  static NodeHits node_hits(__m256i near, __m256i far) { return {_mm256_cmple_epi32_mask(near, far), near}; }
  static unsigned mask(const NodeHits& h) { return h.hit; }
  // v on the hit lanes, 0 elsewhere.
  static __m256i hit_keys(const NodeHits& h, __m256i v) { return _mm256_maskz_mov_epi32(h.hit, v); }
  // key on the hit lanes, all ones elsewhere.
  static __m256i miss_ones(const NodeHits& h, __m256i key) {
    return _mm256_mask_blend_epi32(h.hit, _mm256_set1_epi32(-1), key);
  }
  // One step of the bitonic network: the larger of (v, partner) on the
  // lanes in kTakeMax, the smaller elsewhere.
  template <int kTakeMax>
  static __m256i bitonic_step(__m256i v, __m256i partner) {
    return _mm256_mask_max_epu32(_mm256_min_epu32(v, partner), __mmask8(kTakeMax), v, partner);
  }
  // The lanes of refs in `lanes`, in lane order, stored from dst (eight
  // entries written).
  static void push_compressed(uint32_t* dst, __m256i refs, unsigned lanes) {
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(dst), _mm256_maskz_compress_epi32(__mmask8(lanes), refs));
  }
  // widen_far (aabb.h) lane by lane: x (1 + 2 gamma(3)), then two ulps out
  // unless zero, inf or NaN; a magnitude within two ulps of inf becomes inf.
  static __m128 widen_far(__m128 x) {
    const __m128i w = _mm_castps_si128(_mm_mul_ps(x, _mm_set1_ps(1.0f + 2.0f * gamma(3))));
    const __m128i mag = _mm_and_si128(w, _mm_set1_epi32(0x7FFFFFFF));
    const __mmask8 keep = _mm_cmpeq_epi32_mask(mag, _mm_setzero_si128()) | _mm_cmpgt_epi32_mask(mag, _mm_set1_epi32(0x7F7FFFFF));
    const __mmask8 to_inf = _mm_cmpgt_epi32_mask(mag, _mm_set1_epi32(0x7F7FFFFD)) & ~keep;
    __m128i wf = _mm_mask_add_epi32(w, __mmask8(~keep), w, _mm_set1_epi32(2));
    wf = _mm_mask_or_epi32(wf, to_inf, _mm_and_si128(w, _mm_set1_epi32(int(0x80000000u))), _mm_set1_epi32(0x7F800000));
    return _mm_castsi128_ps(wf);
  }
  // The next float up, on the bit patterns: +1 for a float >= +0 and -1 for
  // a negative one; + 0 first turns -0 into +0. A result below the smallest
  // normal float goes to it (positive) or to +0 (negative), still an upper
  // bound: a subnormal constant would make every node test's multiply-add a
  // microcode assist (~100 cycles), and o inv rounds to 0 wherever an origin
  // coordinate is 0 (a camera on an axis, a ray leaving a floor at z = 0).
  static __m128 next_up(__m128 x) {
    const __m128i b = _mm_castps_si128(_mm_add_ps(x, _mm_setzero_ps()));
    __m128i r = _mm_add_epi32(b, _mm_or_si128(_mm_srai_epi32(b, 31), _mm_set1_epi32(1)));
    const __m128i min_normal = _mm_set1_epi32(0x00800000);
    const __mmask8 tiny = _mm_cmplt_epi32_mask(_mm_and_si128(r, _mm_set1_epi32(0x7FFFFFFF)), min_normal);
    const __mmask8 positive = _mm_cmpgt_epi32_mask(r, _mm_setzero_si128());
    r = _mm_mask_mov_epi32(r, tiny, _mm_setzero_si128());
    return _mm_castsi128_ps(_mm_mask_mov_epi32(r, __mmask8(tiny & positive), min_normal));
  }
};

}  // namespace
}  // namespace tessera

#include "bvh8_traverse.h"

namespace tessera {

template <bool kOrdered>
bool bvh8_intersect_avx512(const BVH8& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  return bvh8_intersect<Avx512, kOrdered>(bvh, o, d, tmax, hit);
}

template bool bvh8_intersect_avx512<true>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);
template bool bvh8_intersect_avx512<false>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);

bool bvh8_occluded_avx512(const BVH8& bvh, const vec3& o, const vec3& d, float tmax) {
  return bvh8_occluded<Avx512>(bvh, o, d, tmax);
}

}  // namespace tessera

#pragma GCC diagnostic pop
#pragma GCC pop_options
