// BVH8 traversal compiled for AVX2 (see bvh8.h). Every header is included
// before the target pragma, so inline functions from them keep the baseline
// target and the linker can never pick an AVX2 copy for baseline code; the
// code below the pragma has internal linkage except the two entry points.
// FMA is not enabled: no multiply-add is contracted, so the box and triangle
// arithmetic rounds exactly as in the SSE2 BVH4 and the scalar tests.
#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "bvh8.h"
#include "simd.h"
#include "triangle.h"

namespace tessera {
// Baseline code (outside the target region): the kernel choice.
bool g_bvh8_avx512 = cpu_has_avx512();
}  // namespace tessera

#pragma GCC push_options
#pragma GCC target("avx2")

#define TESSERA_TRI4_AVX 1  // TriRay4 may use AVX (simd_tri4.h)
#include "simd_tri4.h"
#include "wide_traverse.h"

namespace tessera {
namespace {

struct Ray8 {
  __m256 org_near[3], org_far[3], inv[3], inv_far[3];
  __m256 tmax8_far;  // tmax widened as the far planes
  __m128 tmax4;
  int near_lo[3];
  TriRay4 tri;

  Ray8(const vec3& origin, const vec3& d, float t_max) : tri(origin, d) {
    for (int i = 0; i < 3; ++i) {
      // The same per-axis values as Ray4 / TraversalRay, without branches on
      // the direction's signs (incoherent rays mispredict them).
      float di = std::abs(d[i]) < 1e-30f ? std::copysign(1e-30f, d[i]) : d[i];
      float inv_i = 1.0f / di;
      inv[i] = _mm256_set1_ps(inv_i);
      inv_far[i] = _mm256_set1_ps(widen_far(inv_i));
      near_lo[i] = int(!(inv_i >= 0.0f));
      // delta >= 0; near origin o + delta (inv >= 0) or o - delta, far the other.
      const float delta = parallel_axis_delta(origin[i], d[i]);
      const float signed_delta = flip_sign(delta, near_lo[i]);
      org_near[i] = _mm256_set1_ps(origin[i] + signed_delta);
      org_far[i] = _mm256_set1_ps(origin[i] - signed_delta);
    }
    set_tmax(t_max);
  }
  void set_tmax(float t) {
    tmax8_far = _mm256_set1_ps(widen_far(t));
    tmax4 = _mm_set1_ps(t);
  }
};

// Slab test against the eight child boxes: intersect_box's arithmetic on the
// near planes, at least as wide on the far planes, with a short dependency
// chain (a node visit is a chain of dependent loads and this arithmetic):
// - the far planes' widening is folded into their inverse direction and into
//   tmax (widen_far in aabb.h): |round((b - o) inv_far)| is at least intersect_box's
//   round(round((b - o) inv) (1 + 2 gamma(3))), as every rounding is
//   monotonic and costs at most one ulp, and inv_far is two ulps beyond
//   inv (1 + 2 gamma(3)); no multiply after the min;
// - max, min and compare run on the floats' bit patterns as signed integers
//   (1 cycle instead of 4): that order is float order on non-negative floats
//   and puts every negative float below +0. tnear, maxed with +0, is the
//   float max exactly (the near-first order and the pop cull are unchanged);
//   tfar is negative exactly when some far distance or tmax is negative, and
//   any negative tfar culls, as tnear >= +0. A far plane at exactly -0 now
//   culls (the float compare accepted +0 <= -0): that box holds no point at
//   t > 0 in that slab, and hits need t > 0.
inline int intersect_node8(const BVH8Node& n, const Ray8& r, __m256& tnear) {
  // The far plane of each axis by flipping bit 5 of its near plane's
  // address, as intersect_node8x (bvh8_avx512.cpp): three per-ray offsets.
  const uintptr_t box = reinterpret_cast<uintptr_t>(n.box);
  const uintptr_t px = box + uintptr_t(r.near_lo[0]) * 32, py = box + 64 + uintptr_t(r.near_lo[1]) * 32,
                  pz = box + 128 + uintptr_t(r.near_lo[2]) * 32;
  auto at = [](uintptr_t a) { return reinterpret_cast<const float*>(a); };
  const __m256 tnx = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(at(px)), r.org_near[0]), r.inv[0]);
  const __m256 tfx = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(at(px ^ 32)), r.org_far[0]), r.inv_far[0]);
  const __m256 tny = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(at(py)), r.org_near[1]), r.inv[1]);
  const __m256 tfy = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(at(py ^ 32)), r.org_far[1]), r.inv_far[1]);
  const __m256 tnz = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(at(pz)), r.org_near[2]), r.inv[2]);
  const __m256 tfz = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(at(pz ^ 32)), r.org_far[2]), r.inv_far[2]);
  const __m256i inx = _mm256_castps_si256(tnx), iny = _mm256_castps_si256(tny), inz = _mm256_castps_si256(tnz);
  const __m256i ifx = _mm256_castps_si256(tfx), ify = _mm256_castps_si256(tfy), ifz = _mm256_castps_si256(tfz);
  const __m256i near = _mm256_max_epi32(_mm256_max_epi32(inx, iny), _mm256_max_epi32(inz, _mm256_setzero_si256()));
  const __m256i far = _mm256_min_epi32(_mm256_min_epi32(ifx, ify), _mm256_min_epi32(ifz, _mm256_castps_si256(r.tmax8_far)));
  tnear = _mm256_castsi256_ps(near);
  return ~_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(near, far))) & 0xFF;
}

// BVH8 for wide_intersect / wide_occluded.
struct Bvh8Traits {
  static constexpr int kWidth = 8;
  static constexpr int kStackSize = 512;
  using Node = BVH8Node;
  using Ray = Ray8;
  static int test(const Node& n, const Ray& r, float* dist) {
    __m256 tn;
    const int mask = intersect_node8(n, r, tn);
    _mm256_store_ps(dist, tn);
    return mask;
  }
  static __m128 tri_tmax(const Ray& r) { return r.tmax4; }
  static void set_tmax(Ray& r, float t) { r.set_tmax(t); }
  static void prefetch(const char* base, uint32_t ref) {
    const char* p = base + size_t(ref) * kNodeUnit;
    _mm_prefetch(p, _MM_HINT_T0);
    _mm_prefetch(p + 64, _MM_HINT_T0);
    _mm_prefetch(p + 128, _MM_HINT_T0);
    _mm_prefetch(p + 192, _MM_HINT_T0);
  }
};

}  // namespace

#ifdef TESSERA_BVH_COUNTERS
WideCounters g_wide_counters;
#endif

template <bool kOrdered>
bool bvh8_intersect_avx2(const BVH8& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  if (g_bvh8_avx512) return bvh8_intersect_avx512<kOrdered>(bvh, o, d, tmax, hit);
  if (bvh.empty()) return false;
  WC(rays);
  Ray8 ray(o, d, tmax);
  return wide_intersect<Bvh8Traits, kOrdered>(bvh.base(), ray, tmax, hit);
}

template bool bvh8_intersect_avx2<true>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);
template bool bvh8_intersect_avx2<false>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);

bool bvh8_occluded_avx2(const BVH8& bvh, const vec3& o, const vec3& d, float tmax) {
  if (g_bvh8_avx512) return bvh8_occluded_avx512(bvh, o, d, tmax);
  if (bvh.empty()) return false;
  WC(rays);
  Ray8 ray(o, d, tmax);
  return wide_occluded<Bvh8Traits>(bvh.base(), ray);
}

}  // namespace tessera

#pragma GCC pop_options
