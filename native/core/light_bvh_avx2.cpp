// The light BVH's eight-lane importance in one AVX2 pass (see
// light_importance_simd.h), called only after cpu_simd_level() said AVX2.
// Headers come before the target pragma, as in bvh8_avx2.cpp, so no inline
// function they define is compiled for AVX2 here; FMA stays off (the target
// is avx2 alone), so every lane rounds as the scalar function does.
#include <immintrin.h>

#include "light_bvh.h"

#pragma GCC push_options
#pragma GCC target("avx2")

#include "light_importance_simd.h"

namespace tessera {
namespace {
struct Avx2Ops {
  using T = __m256;
  static T load(const float* x) { return _mm256_load_ps(x); }
  static T bits(const uint32_t* x) { return _mm256_castsi256_ps(_mm256_load_si256(reinterpret_cast<const __m256i*>(x))); }
  static void store(float* x, T v) { _mm256_storeu_ps(x, v); }
  static T set1(float x) { return _mm256_set1_ps(x); }
  static T abs_mask() { return _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff)); }
  static T add(T a, T b) { return _mm256_add_ps(a, b); }
  static T sub(T a, T b) { return _mm256_sub_ps(a, b); }
  static T mul(T a, T b) { return _mm256_mul_ps(a, b); }
  static T div(T a, T b) { return _mm256_div_ps(a, b); }
  static T sqrt(T a) { return _mm256_sqrt_ps(a); }
  static T max(T a, T b) { return _mm256_max_ps(a, b); }
  static T min(T a, T b) { return _mm256_min_ps(a, b); }
  static T and_(T a, T b) { return _mm256_and_ps(a, b); }
  static T andnot(T a, T b) { return _mm256_andnot_ps(a, b); }
  static T or_(T a, T b) { return _mm256_or_ps(a, b); }
  static T cmpgt(T a, T b) { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); }
  static T cmplt(T a, T b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
};
}  // namespace

void ImportanceBounds8::importance_avx2(const vec3& p, const vec3& n, float out[8]) const {
  ImportanceLanes<Avx2Ops>::eval(*this, 0, p, n, out);
}

}  // namespace tessera

#pragma GCC pop_options
