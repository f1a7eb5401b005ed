#include "bvh4.h"
#include "bvh8.h"
#include "simd_tri4.h"
#include "wide_traverse.h"

#include <algorithm>
#include <stdexcept>

namespace tessera {

namespace {

// Per-ray constants for the box and triangle tests.
struct Ray4 {
  __m128 org_near[3], org_far[3], inv[3];
  __m128 tmax;      // for the triangle test
  __m128 tmax_far;  // tmax widened as the far planes
  __m128 inv_far[3];
  int near_lo[3];  // box row holding the near plane per axis (0: lo, 1: hi)
  TriRay4 tri;

  Ray4(const vec3& origin, const vec3& d, float t_max) : tri(origin, d) {
    for (int i = 0; i < 3; ++i) {
      // Same guard as TraversalRay: avoid 0 * inf = NaN in the slab test.
      float di = std::abs(d[i]) < 1e-30f ? std::copysign(1e-30f, d[i]) : d[i];
      float inv_i = 1.0f / di;
      inv[i] = _mm_set1_ps(inv_i);
      inv_far[i] = _mm_set1_ps(widen_far(inv_i));
      near_lo[i] = int(!(inv_i >= 0.0f));
      // Separate origins for the lo / hi planes (see the two-origin intersect_box in aabb.h):
      // near o + delta (inv >= 0) or o - delta, far the other; no branch on the sign.
      const float delta = parallel_axis_delta(origin[i], d[i]);
      const float signed_delta = flip_sign(delta, near_lo[i]);
      org_near[i] = _mm_set1_ps(origin[i] + signed_delta);
      org_far[i] = _mm_set1_ps(origin[i] - signed_delta);
    }
    set_tmax(t_max);
  }
  void set_tmax(float t) {
    tmax = _mm_set1_ps(t);
    tmax_far = _mm_set1_ps(widen_far(t));
  }
  float cull_t() const { return _mm_cvtss_f32(tmax_far); }  // widen_far(tmax), made by set_tmax
};

// Slab test of the ray against the four child boxes: intersect_box's
// arithmetic on the near planes, at least as wide on the far planes (the
// widening folded into inv_far and tmax_far, as in the BVH8's test; see
// bvh8_avx2.cpp), the final compare on the bit patterns as signed integers
// (tnear >= +0, so a negative tfar culls; SSE2 has no integer max/min).
// Returns the hit mask, entry distances in tnear.
inline int intersect_node(const BVH4Node& n, const Ray4& r, __m128& tnear) {
  // The far plane of each axis by flipping bit 4 of its near plane's
  // address (a node is 64-byte aligned, an axis's two rows share 32 bytes),
  // as the BVH8's node tests: three per-ray offsets instead of six.
  const uintptr_t box = reinterpret_cast<uintptr_t>(n.box);
  const uintptr_t px = box + uintptr_t(r.near_lo[0]) * 16, py = box + 32 + uintptr_t(r.near_lo[1]) * 16,
                  pz = box + 64 + uintptr_t(r.near_lo[2]) * 16;
  auto at = [](uintptr_t a) { return reinterpret_cast<const float*>(a); };
  const __m128 tnx = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(at(px)), r.org_near[0]), r.inv[0]);
  const __m128 tfx = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(at(px ^ 16)), r.org_far[0]), r.inv_far[0]);
  const __m128 tny = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(at(py)), r.org_near[1]), r.inv[1]);
  const __m128 tfy = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(at(py ^ 16)), r.org_far[1]), r.inv_far[1]);
  const __m128 tnz = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(at(pz)), r.org_near[2]), r.inv[2]);
  const __m128 tfz = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(at(pz ^ 16)), r.org_far[2]), r.inv_far[2]);
  tnear = _mm_max_ps(_mm_max_ps(tnx, tny), _mm_max_ps(tnz, _mm_setzero_ps()));
  const __m128 tfar = _mm_min_ps(_mm_min_ps(tfx, tfy), _mm_min_ps(tfz, r.tmax_far));
  return ~_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(_mm_castps_si128(tnear), _mm_castps_si128(tfar)))) & 0xF;
}

// BVH4 for wide_intersect / wide_occluded.
struct Bvh4Traits {
  static constexpr int kWidth = 4;
  static constexpr int kStackSize = 256;
  using Node = BVH4Node;
  using Ray = Ray4;
  static int test(const Node& n, const Ray& r, float* dist) {
    __m128 tn;
    const int mask = intersect_node(n, r, tn);
    _mm_store_ps(dist, tn);
    return mask;
  }
  static __m128 tri_tmax(const Ray& r) { return r.tmax; }
  static void set_tmax(Ray& r, float t) { r.set_tmax(t); }
  static float cull_t(const Ray& r) { return r.cull_t(); }
  static void prefetch(const char* base, uint32_t ref) {
    const char* p = base + size_t(ref) * kNodeUnit;
    _mm_prefetch(p, _MM_HINT_T0);
    _mm_prefetch(p + 64, _MM_HINT_T0);
  }
};

}  // namespace

template <typename Tree>
static float wide_sah_cost(const Tree& bvh, const BuildOptions& options) {
  if (bvh.empty()) return 0.0f;
  const float root_area = bvh.bounds.half_area();
  if (root_area <= 0.0f) return 0.0f;
  double cost = options.traversal_cost;  // the root is always visited
  std::vector<uint32_t> stack{0u};
  while (!stack.empty()) {
    const auto& n = bvh.node(stack.back());
    stack.pop_back();
    for (uint32_t c = 0; c < n.num_children; ++c) {
      AABB b{vec3(n.box[0][c], n.box[2][c], n.box[4][c]), vec3(n.box[1][c], n.box[3][c], n.box[5][c])};
      const float a = b.half_area() / root_area;
      if (bvh4_is_leaf(n.child[c])) {
        cost += options.intersection_cost * bvh4_leaf_blocks(n.child[c]) * a;
      } else {
        cost += options.traversal_cost * a;
        stack.push_back(n.child[c]);
      }
    }
  }
  return float(cost);
}

template <typename Node>
int WideBVH<Node>::depth() const {
  if (empty()) return 0;
  int best = 0;
  std::vector<std::pair<uint32_t, int>> stack{{0u, 1}};
  while (!stack.empty()) {
    auto [i, d] = stack.back();
    stack.pop_back();
    best = std::max(best, d);
    for (uint32_t c = 0; c < node(i).num_children; ++c)
      if (!bvh4_is_leaf(node(i).child[c])) stack.push_back({node(i).child[c], d + 1});
  }
  return best;
}
template struct WideBVH<BVH4Node>;
template struct WideBVH<BVH8Node>;

float sah_cost(const BVH4& bvh, const BuildOptions& options) { return wide_sah_cost(bvh, options); }
float sah_cost(const BVH8& bvh, const BuildOptions& options) { return wide_sah_cost(bvh, options); }

template <bool kOrdered>
bool bvh4_intersect(const BVH4& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  if (bvh.empty()) return false;
  Ray4 ray(o, d, tmax);
  return wide_intersect<Bvh4Traits, kOrdered>(bvh.base(), ray, tmax, hit);
}

template bool bvh4_intersect<true>(const BVH4&, const vec3&, const vec3&, float&, BVH4Hit&);
template bool bvh4_intersect<false>(const BVH4&, const vec3&, const vec3&, float&, BVH4Hit&);

bool bvh4_occluded(const BVH4& bvh, const vec3& o, const vec3& d, float tmax) {
  if (bvh.empty()) return false;
  Ray4 ray(o, d, tmax);
  return wide_occluded<Bvh4Traits>(bvh.base(), ray);
}

}  // namespace tessera
