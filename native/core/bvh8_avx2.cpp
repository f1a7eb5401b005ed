// BVH8 traversal compiled for AVX2 (see bvh8.h). Every header is included
// before the target pragma, so inline functions from them keep the baseline
// target and the linker can never pick an AVX2 copy for baseline code; the
// code below the pragma has internal linkage except the two entry points.
// FMA is not enabled: no multiply-add is contracted, so the box and triangle
// arithmetic rounds exactly as in the SSE2 BVH4 and the scalar tests.
#include <immintrin.h>

#include <algorithm>
#include <cmath>

#include "bvh8.h"
#include "triangle.h"

#pragma GCC push_options
#pragma GCC target("avx2")

#include "simd_tri4.h"
#include "wide_traverse.h"

namespace tessera {
namespace {

struct Ray8 {
  __m256 org_near[3], org_far[3], inv[3];
  __m256 tmax8;
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
    tmax8 = _mm256_set1_ps(t);
    tmax4 = _mm_set1_ps(t);
  }
};

// Slab test against the eight child boxes: intersect_box's arithmetic per lane.
inline int intersect_node8(const BVH8Node& n, const Ray8& r, __m256& tnear) {
  const int nx = r.near_lo[0], ny = r.near_lo[1], nz = r.near_lo[2];
  const __m256 tnx = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.box[0 + nx]), r.org_near[0]), r.inv[0]);
  const __m256 tfx = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.box[1 - nx]), r.org_far[0]), r.inv[0]);
  const __m256 tny = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.box[2 + ny]), r.org_near[1]), r.inv[1]);
  const __m256 tfy = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.box[3 - ny]), r.org_far[1]), r.inv[1]);
  const __m256 tnz = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.box[4 + nz]), r.org_near[2]), r.inv[2]);
  const __m256 tfz = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.box[5 - nz]), r.org_far[2]), r.inv[2]);
  tnear = _mm256_max_ps(_mm256_max_ps(tnx, tny), _mm256_max_ps(tnz, _mm256_setzero_ps()));
  const __m256 tfar = _mm256_mul_ps(_mm256_min_ps(_mm256_min_ps(tfx, tfy), _mm256_min_ps(tfz, r.tmax8)),
                                    _mm256_set1_ps(1.0f + 2.0f * gamma(3)));
  return _mm256_movemask_ps(_mm256_cmp_ps(tnear, tfar, _CMP_LE_OQ));
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

template <bool kOrdered>
bool bvh8_intersect_avx2(const BVH8& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  if (bvh.empty()) return false;
  Ray8 ray(o, d, tmax);
  return wide_intersect<Bvh8Traits, kOrdered>(bvh.base(), ray, tmax, hit);
}

template bool bvh8_intersect_avx2<true>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);
template bool bvh8_intersect_avx2<false>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);

bool bvh8_occluded_avx2(const BVH8& bvh, const vec3& o, const vec3& d, float tmax) {
  if (bvh.empty()) return false;
  Ray8 ray(o, d, tmax);
  return wide_occluded<Bvh8Traits>(bvh.base(), ray);
}

}  // namespace tessera

#pragma GCC pop_options
