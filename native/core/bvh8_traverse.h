// Closest-hit and any-hit traversal of the BVH8: one source for the AVX2 and
// the AVX-512 kernels (bvh8_avx2.cpp, bvh8_avx512.cpp), each of which
// includes it inside its own target region, after simd_tri4.h and
// wide_traverse.h, with an Isa struct for the few steps where the two
// instruction sets differ (the compare of the node test, the masked keys of
// the child sort, a sort step, the compressed push, the ray set-up's integer
// selects). Everything here has internal linkage.
//
// What the kernels do (the AVX2 one was the generic wide_intersect until
// the Zen 3 measurements in docs/BVH_BENCHMARK.md):
// - the node test is one multiply-add per plane (b inv - c, c = o inv rounded
//   outwards per ray; see intersect_node8x) instead of a subtract and a
//   multiply: one op less on the per-node dependency chain, still
//   conservative for any origin. Its distances can differ from the
//   subtract-then-multiply test's by an ulp, so children with (nearly) equal
//   entry distances may be visited in another order: the closest hit is the
//   same unless two hits lie within their t error of each other (coplanar
//   duplicates);
// - the root is tested before the loops, by the subtract-then-multiply form
//   (root_test);
// - closest hit orders two hit children by conditional moves and three or
//   more with a sorting network in one ymm (Embree's in-register sort)
//   instead of an insertion sort with a mispredicted branch per child:
//   32-bit keys, the entry distance's bits with the lane in the low three,
//   so distances within 8 ulps count as equal and go by lane; the sorted
//   keys pick the child references, and the pairs are the stack entries
//   (two 32-byte stores push them all). No zmm: the same network over 64-bit
//   keys in one zmm was 3-17% slower on a Xeon with AVX-512;
// - any hit pushes the hit children with one compress and store, and does
//   not prefetch them;
// - the triangle test's ray constants are made at the first leaf.
#pragma once
#include <immintrin.h>

#include <new>
#include <type_traits>

#include "bvh8.h"
#include "simd_tri4.h"
#include "wide_traverse.h"

namespace tessera {
namespace {

// The per-ray values of intersect_box's slab test (the 1e-30 clamp, 1 / d,
// widen_far, parallel_axis_delta, flip_sign), the three axes at once in one
// SSE register: the same operations lane by lane, so the same bits as the
// scalar functions. And the constants of the node test by multiply-add
// (intersect_node8x<true>).
template <typename Isa>
struct RaySetup {
  __m128 o4, d4;  // the ray, x, y, z in lanes 0-2
  __m128 inv, inv_far, o_near, o_far, c_near, c_far;
  int near_bits;
  bool fma;  // c_near and c_far finite on every axis

  RaySetup(const vec3& origin, const vec3& d) {
    o4 = _mm_setr_ps(origin.x, origin.y, origin.z, 0.0f);
    d4 = _mm_setr_ps(d.x, d.y, d.z, 1.0f);
    const __m128 sign = _mm_set1_ps(-0.0f);
    const __m128 abs_d = _mm_andnot_ps(sign, d4);
    const __m128 tiny = _mm_cmplt_ps(abs_d, _mm_set1_ps(1e-30f));
    const __m128 di = _mm_blendv_ps(d4, _mm_or_ps(_mm_and_ps(sign, d4), _mm_set1_ps(1e-30f)), tiny);
    inv = _mm_div_ps(_mm_set1_ps(1.0f), di);
    inv_far = Isa::widen_far(inv);
    // near_lo = !(inv >= 0); delta = |d| < 1e-30 ? |o| 1e-6 + 1e-20 : 0, its
    // sign flipped where near_lo.
    const __m128 near_neg = _mm_cmpnge_ps(inv, _mm_setzero_ps());
    near_bits = _mm_movemask_ps(near_neg);
    const __m128 delta = _mm_and_ps(tiny, _mm_add_ps(_mm_mul_ps(_mm_andnot_ps(sign, o4), _mm_set1_ps(1e-6f)), _mm_set1_ps(1e-20f)));
    const __m128 signed_delta = _mm_xor_ps(delta, _mm_and_ps(near_neg, sign));
    o_near = _mm_add_ps(o4, signed_delta);
    o_far = _mm_sub_ps(o4, signed_delta);
    // c_near: o_near inv rounded to float, then one ulp up (c_far: o_far
    // inv_far, one ulp down), so at least (at most) the exact product
    // whatever the rounding did (Isa::next_up). A short chain after the
    // division (most random rays visit two nodes: a rounding test in double
    // cost them 10%).
    c_near = Isa::next_up(_mm_mul_ps(o_near, inv));
    c_far = _mm_xor_ps(Isa::next_up(_mm_xor_ps(_mm_mul_ps(o_far, inv_far), sign)), sign);
    const __m128 inf = _mm_set1_ps(kInf);
    const __m128 finite = _mm_and_ps(_mm_cmplt_ps(_mm_andnot_ps(sign, c_near), inf), _mm_cmplt_ps(_mm_andnot_ps(sign, c_far), inf));
    fma = (_mm_movemask_ps(finite) & 7) == 7;
  }
};

// The node test's per-ray constants: RaySetup's values per axis, broadcast;
// c_near and c_far only with the node test by multiply-add (kFma below). A
// plain aggregate of registers, so that the compiler keeps no copy of it in
// memory besides its spills.
struct Ray8x {
  __m256 o_near[3], o_far[3], c_near[3], c_far[3], inv[3], inv_far[3];
  __m256 tmax8_far;  // tmax widened as the far planes
  __m128 tmax4;
  int near_lo[3];

  // kFma: with c_near and c_far (the node test by multiply-add). Made after
  // the branch on setup.fma, so that no node test waits for that check.
  template <typename Isa, bool kFma>
  Ray8x(const RaySetup<Isa>& s, std::bool_constant<kFma>, float t_max) {
    auto lane = [](__m128 x, int i) {
      return _mm256_permutevar8x32_ps(_mm256_castps128_ps256(x), _mm256_set1_epi32(i));
    };
    for (int i = 0; i < 3; ++i) {
      inv[i] = lane(s.inv, i);
      inv_far[i] = lane(s.inv_far, i);
      o_near[i] = lane(s.o_near, i);
      o_far[i] = lane(s.o_far, i);
      if (kFma) c_near[i] = lane(s.c_near, i), c_far[i] = lane(s.c_far, i);
      near_lo[i] = (s.near_bits >> i) & 1;
    }
    set_tmax(t_max);
  }
  void set_tmax(float t) {
    tmax8_far = _mm256_set1_ps(widen_far(t));
    tmax4 = _mm_set1_ps(t);
  }
  float cull_t() const { return _mm256_cvtss_f32(tmax8_far); }  // widen_far(tmax), made by set_tmax
};

// The triangle test's constants (shear), made at the first leaf: most
// primary and random rays never reach one (they miss the mesh or pass
// between its boxes), and the shear costs a division. Keeps its own copy of
// the ray, not a reference to the RaySetup: that would keep every value of
// the set-up in memory (eight stores per ray that nothing reads back).
template <typename Isa>
class LazyTriRay4 {
 public:
  explicit LazyTriRay4(const RaySetup<Isa>& s) : o4_(s.o4), d4_(s.d4) {}
  const TriRay4& get() {
    if (__builtin_expect(!ready_, 0)) {
      new (storage_) TriRay4(o4_, d4_);
      ready_ = true;
    }
    return *std::launder(reinterpret_cast<const TriRay4*>(storage_));
  }

 private:
  __m128 o4_, d4_;
  bool ready_ = false;
  alignas(16) unsigned char storage_[sizeof(TriRay4)];
};

// Slab test against the eight child boxes: intersect_box's arithmetic on the
// near planes, at least as wide on the far planes, with a short dependency
// chain (a node visit is a chain of dependent loads and this arithmetic):
// - the far planes' widening is folded into their inverse direction and into
//   tmax (widen_far in aabb.h): |round((b - o) inv_far)| is at least
//   intersect_box's round(round((b - o) inv) (1 + 2 gamma(3))), as every
//   rounding is monotonic and costs at most one ulp, and inv_far is two ulps
//   beyond inv (1 + 2 gamma(3)); no multiply after the min;
// - max, min and compare run on the floats' bit patterns as signed integers
//   (1 cycle instead of 4): that order is float order on non-negative floats
//   and puts every negative float below +0. tnear, maxed with +0, is the
//   float max exactly (the near-first order and the pop cull are unchanged);
//   tfar is negative exactly when some far distance or tmax is negative, and
//   any negative tfar culls, as tnear >= +0. A far plane at exactly -0
//   culls: that box holds no point at t > 0 in that slab, and hits need t > 0.
// kFma: each plane distance by one multiply-add, b inv - c, with c = o inv
// rounded up on the near planes and o inv_far rounded down on the far ones
// (Ray8x; Embree's node test made one-sided): b inv - c is at most the exact
// (b - o) inv on the near planes and at least (b - o) inv_far on the far
// ones, and one rounding follows instead of two, so both stay on the
// conservative side of the bounds above wherever the origin is (the
// rounding of c moves a plane outwards by an ulp of o inv). Only with c
// finite on every axis: a c of inf would give inf - inf on the unused
// lanes' infinite planes.
template <typename Isa, bool kFma>
inline typename Isa::NodeHits intersect_node8x(const BVH8Node& n, const Ray8x& r) {
  const int nx = r.near_lo[0], ny = r.near_lo[1], nz = r.near_lo[2];
  auto plane = [](const float* b, __m256 o, __m256 inv) {
    return kFma ? _mm256_fmsub_ps(_mm256_load_ps(b), inv, o) : _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(b), o), inv);
  };
  const __m256* on = kFma ? r.c_near : r.o_near;
  const __m256* of = kFma ? r.c_far : r.o_far;
  // Axis a's near plane is box[2 a + near_lo[a]], its far plane the other
  // one: the same address with bit 5 flipped (a node is 64-byte aligned, an
  // axis's two planes share one 64-byte line). Three per-ray offsets instead
  // of six: with six, the node loop had no registers left for them and
  // reloaded each from the stack at every node.
  const uintptr_t box = reinterpret_cast<uintptr_t>(n.box);
  const uintptr_t px = box + uintptr_t(nx) * 32, py = box + 64 + uintptr_t(ny) * 32, pz = box + 128 + uintptr_t(nz) * 32;
  auto at = [](uintptr_t a) { return reinterpret_cast<const float*>(a); };
  const __m256 tnx = plane(at(px), on[0], r.inv[0]);
  const __m256 tfx = plane(at(px ^ 32), of[0], r.inv_far[0]);
  const __m256 tny = plane(at(py), on[1], r.inv[1]);
  const __m256 tfy = plane(at(py ^ 32), of[1], r.inv_far[1]);
  const __m256 tnz = plane(at(pz), on[2], r.inv[2]);
  const __m256 tfz = plane(at(pz ^ 32), of[2], r.inv_far[2]);
  const __m256i inx = _mm256_castps_si256(tnx), iny = _mm256_castps_si256(tny), inz = _mm256_castps_si256(tnz);
  const __m256i ifx = _mm256_castps_si256(tfx), ify = _mm256_castps_si256(tfy), ifz = _mm256_castps_si256(tfz);
  const __m256i near = _mm256_max_epi32(_mm256_max_epi32(inx, iny), _mm256_max_epi32(inz, _mm256_setzero_si256()));
  const __m256i far = _mm256_min_epi32(_mm256_min_epi32(ifx, ify), _mm256_min_epi32(ifz, _mm256_castps_si256(r.tmax8_far)));
  return Isa::node_hits(near, far);
}

// The root's test, before the traversal loops (ref 0 is always a node): by
// the subtract-then-multiply form, from the origins, which needs no c, so
// the chain that makes c (o inv after the division, then its rounding) runs
// beside the root's loads and test instead of before them. Every ray tests
// the root, and a random ray few nodes more (modern_hall: 2.1): with every
// node by multiply-add, random rays there were 4% slower than with none,
// primary rays (6.2 nodes) 3% faster; with the root apart, random rays are
// as fast as with none and primary rays keep the gain (AMD Zen 5,
// docs/BVH_BENCHMARK.md). Outside the loop the origins' registers are free
// once it is done: tested inside it (ref == 0 ? this : multiply-add), the
// loop held both forms' constants and spilled the far planes' tmax, reloaded
// at every node.
template <typename Isa>
inline typename Isa::NodeHits root_test(const BVH8Node& root, const Ray8x& r) {
  WC(nodes);
  _mm_prefetch(reinterpret_cast<const char*>(root.child), _MM_HINT_T0);
  return intersect_node8x<Isa, false>(root, r);
}

// An interior node reached from its parent: its child references
// line asked for next to the box loads (instead of after the test has
// picked a child, which serialises two misses per level), then its test.
template <typename Isa, bool kFma>
inline typename Isa::NodeHits visit_node(const char* base, uint32_t ref, const Ray8x& ray, const BVH8Node*& np) {
  np = &wide_node<BVH8Node>(base, ref);
  WC(nodes);
  _mm_prefetch(reinterpret_cast<const char*>(np->child), _MM_HINT_T0);
  return intersect_node8x<Isa, kFma>(*np, ray);
}

// Lanes that keep the larger of the pair in bitonic step (k, j) of a
// descending sort (Batcher's bitonic network, lane i paired with i ^ j).
constexpr int bitonic_max_lanes(int k, int j) {
  int m = 0;
  for (int i = 0; i < 8; ++i)
    if (((i & j) == 0) == ((i & k) == 0)) m |= 1 << i;
  return m;
}

// Eight unsigned 32-bit keys sorted descending, in registers (six steps).
template <typename Isa>
inline __m256i sort8_desc(__m256i v) {
  auto swap1 = [](__m256i x) { return _mm256_shuffle_epi32(x, 0xB1); };      // i ^ 1
  auto swap2 = [](__m256i x) { return _mm256_shuffle_epi32(x, 0x4E); };      // i ^ 2
  auto swap4 = [](__m256i x) { return _mm256_permute4x64_epi64(x, 0x4E); };  // i ^ 4
  v = Isa::template bitonic_step<bitonic_max_lanes(2, 1)>(v, swap1(v));
  v = Isa::template bitonic_step<bitonic_max_lanes(4, 2)>(v, swap2(v));
  v = Isa::template bitonic_step<bitonic_max_lanes(4, 1)>(v, swap1(v));
  v = Isa::template bitonic_step<bitonic_max_lanes(8, 4)>(v, swap4(v));
  v = Isa::template bitonic_step<bitonic_max_lanes(8, 2)>(v, swap2(v));
  v = Isa::template bitonic_step<bitonic_max_lanes(8, 1)>(v, swap1(v));
  return v;
}

constexpr int kBvh8StackSize = 512;

inline void prefetch_node(const char* base, uint32_t ref) {
  const char* p = base + size_t(ref) * kNodeUnit;
  _mm_prefetch(p, _MM_HINT_T0);
  _mm_prefetch(p + 64, _MM_HINT_T0);
  _mm_prefetch(p + 128, _MM_HINT_T0);
  _mm_prefetch(p + 192, _MM_HINT_T0);
}

// Prefetches child node `c`, or (a leaf) the current node `self` again, which
// is in L1: a conditional move instead of a mispredicted branch per child.
inline void prefetch_interior(const char* base, uint32_t self, uint32_t c) {
  prefetch_node(base, bvh4_is_leaf(c) ? self : c);
}

// The leaf loop of wide_intersect (wide_traverse.h).
template <typename Isa>
__attribute__((always_inline)) inline bool leaf_intersect(const char* base, uint32_t ref, Ray8x& ray, LazyTriRay4<Isa>& lazy_tri,
                                                          float& t_best, BVH4Hit& hit) {
  const Tri4* tris = wide_leaf(base, ref);
  WC(leaves);
  const uint32_t blocks = bvh4_leaf_blocks(ref);
  const TriRay4& tri = lazy_tri.get();
  bool found = false;
  for (uint32_t b = 0; b < blocks; ++b) {
    WC(blocks);
    __m128 t, u, v;
    const int mask = intersect_tri4<Isa::kTernaryLogic>(tris[b], tri, ray.tmax4, t, u, v);
    if (mask == 0) continue;
    hit = nearest_hit(tris[b], mask, t, u, v);
    t_best = hit.t;
    ray.set_tmax(t_best);
    found = true;
  }
  return found;
}

template <typename Isa, bool kOrdered, bool kFma>
bool intersect8x(const char* base, Ray8x& ray, LazyTriRay4<Isa>& tri, float& tmax, BVH4Hit& hit) {
  // Eight entries of slack: pushes store all eight sorted entries.
  alignas(64) WideStackEntry stack[kBvh8StackSize + 8];
  static_assert(sizeof(WideStackEntry) == 8, "stack entries are one 64-bit lane: {ref, t} little-endian");
  int sp = 0;
  uint32_t ref = 0;
  bool found = false;
  float t_best = tmax;
  // Popped entries are skipped against t_best widened as the node test's far
  // planes (widen_far), so that a child is dropped only where the node test
  // with the current t_best would drop it.
  float t_cull = ray.cull_t();
  const __m256i lane_ids = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  // The root first, by the subtract-then-multiply form (from the origins,
  // no c), outside the loop (see root_test).
  const BVH8Node* np = &wide_node<BVH8Node>(base, 0);
  typename Isa::NodeHits hits = root_test<Isa>(*np, ray);
  goto tested;
  for (;;) {
    if (!bvh4_is_leaf(ref)) {
      hits = visit_node<Isa, kFma>(base, ref, ray, np);
    tested:
      const BVH8Node& n = *np;
      const unsigned mask = Isa::mask(hits);
      WCN(hits_children, __builtin_popcount(mask));
      WCH(__builtin_popcount(mask));
      if (mask != 0) {
        const unsigned rest = mask & (mask - 1);
        if (rest == 0) {  // one child hit: descend without the stack
          ref = n.child[__builtin_ctz(mask)];
          continue;
        }
        if (!kOrdered) {
          for (unsigned m = mask; m; m &= m - 1) {
            const uint32_t c = n.child[__builtin_ctz(m)];
            if (!bvh4_is_leaf(c)) prefetch_node(base, c);
          }
          // Stored order: push the others in reverse, descend into the first.
          alignas(32) float dist[8];
          _mm256_store_si256(reinterpret_cast<__m256i*>(dist), hits.near);
          int lanes[8], k = 0;
          for (unsigned m = rest; m; m &= m - 1) lanes[k++] = __builtin_ctz(m);
          for (int j = k - 1; j >= 0; --j) stack[sp++] = {n.child[lanes[j]], dist[lanes[j]]};
          ref = n.child[__builtin_ctz(mask)];
          continue;
        }
        if ((rest & (rest - 1)) == 0) {
          // Two children hit: the nearer (the lower lane on a tie) first, by
          // conditional moves instead of a branch.
          alignas(32) uint32_t dist[8];
          _mm256_store_si256(reinterpret_cast<__m256i*>(dist), hits.near);
          const int a = __builtin_ctz(mask), b = __builtin_ctz(rest);
          const uint32_t ra = n.child[a], rb = n.child[b], da = dist[a], db = dist[b];
          prefetch_interior(base, ref, ra);
          prefetch_interior(base, ref, rb);
          const bool swap = db < da;
          stack[sp].ref = swap ? ra : rb;
          reinterpret_cast<uint32_t*>(stack)[2 * sp + 1] = swap ? da : db;
          ++sp;
          ref = swap ? rb : ra;
          continue;
        }
        for (unsigned m = mask; m; m &= m - 1) prefetch_interior(base, ref, n.child[__builtin_ctz(m)]);
        // Keys (tnear bits & ~7) | lane on hit lanes, 0 elsewhere (sorted
        // last); descending, the nearest hit child is key h - 1.
        const __m256i low3 = _mm256_set1_epi32(7);
        const __m256i key = Isa::hit_keys(hits, _mm256_or_si256(_mm256_andnot_si256(low3, hits.near), lane_ids));
        // The next node, the hit child of the smallest key, by a min
        // reduction (the other lanes' keys all ones): the six-step sort
        // stays off the path to the next node's loads (only the stack
        // stores need it).
        __m256i m = Isa::miss_ones(hits, key);
        m = _mm256_min_epu32(m, _mm256_permute4x64_epi64(m, 0x4E));
        m = _mm256_min_epu32(m, _mm256_shuffle_epi32(m, 0x4E));
        m = _mm256_min_epu32(m, _mm256_shuffle_epi32(m, 0xB1));
        const uint32_t next = n.child[uint32_t(_mm256_cvtsi256_si32(m)) & 7];
        const __m256i sorted = sort8_desc<Isa>(key);
        // Entries {child of the key's lane, the key's distance bits}: at most
        // the entry distance, so the pop's cull stays conservative.
        const __m256i refs = _mm256_permutevar8x32_epi32(_mm256_load_si256(reinterpret_cast<const __m256i*>(n.child)), sorted);
        const __m256i t = _mm256_andnot_si256(low3, sorted);
        const __m256i lo = _mm256_unpacklo_epi32(refs, t), hi = _mm256_unpackhi_epi32(refs, t);  // entries 0 1 4 5, 2 3 6 7
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(stack + sp), _mm256_permute2x128_si256(lo, hi, 0x20));
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(stack + sp + 4), _mm256_permute2x128_si256(lo, hi, 0x31));
        ref = next;
        sp += __builtin_popcount(mask) - 1;
        continue;
      }
    } else if (leaf_intersect<Isa>(base, ref, ray, tri, t_best, hit)) {
      found = true;
      t_cull = ray.cull_t();
    }
    if (!pop_nearer(stack, sp, t_cull, ref)) {
      tmax = t_best;
      return found;
    }
  }
}

template <typename Isa, bool kFma>
bool occluded8x(const char* base, Ray8x& ray, LazyTriRay4<Isa>& lazy_tri) {
  alignas(32) uint32_t stack[kBvh8StackSize + 8];
  int sp = 0;
  uint32_t ref = 0;
  const BVH8Node* np = &wide_node<BVH8Node>(base, 0);
  typename Isa::NodeHits hits = root_test<Isa>(*np, ray);
  goto tested;
  for (;;) {
    if (!bvh4_is_leaf(ref)) {
      hits = visit_node<Isa, kFma>(base, ref, ray, np);
    tested:
      const BVH8Node& n = *np;
      const unsigned mask = Isa::mask(hits);
      WCN(hits_children, __builtin_popcount(mask));
      WCH(__builtin_popcount(mask));
      if (mask != 0) {
        const unsigned rest = mask & (mask - 1);
        if (rest) {
          // Push the other hit children in lane order (the last on top), as
          // wide_occluded does, with one compress and store.
          Isa::push_compressed(stack + sp, _mm256_load_si256(reinterpret_cast<const __m256i*>(n.child)), rest);
          sp += __builtin_popcount(rest);
          // No prefetch of the pushed nodes: their four lines each cost more
          // than they saved (AMD Zen 5: shadow rays 2-10% faster without;
          // docs/BVH_BENCHMARK.md), unlike closest hit's random rays.
        }
        ref = n.child[__builtin_ctz(mask)];
        continue;
      }
    } else {
      const Tri4* tris = wide_leaf(base, ref);
      WC(leaves);
      const uint32_t blocks = bvh4_leaf_blocks(ref);
      const TriRay4& tri = lazy_tri.get();
      for (uint32_t b = 0; b < blocks; ++b) {
        WC(blocks);
        __m128 t, u, v;
        if (intersect_tri4<Isa::kTernaryLogic>(tris[b], tri, ray.tmax4, t, u, v)) return true;
      }
    }
    if (sp == 0) return false;
    ref = stack[--sp];
  }
}

// The entry points' bodies: the multiply-add node test unless some c is
// not finite (an origin coordinate beyond ~1e38 times the direction's).
template <typename Isa, bool kOrdered>
bool bvh8_intersect(const BVH8& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  if (bvh.empty()) return false;
  WC(rays);
  const RaySetup<Isa> s(o, d);
  LazyTriRay4<Isa> tri(s);
  if (__builtin_expect(s.fma, 1)) {
    Ray8x ray(s, std::true_type{}, tmax);
    return intersect8x<Isa, kOrdered, true>(bvh.base(), ray, tri, tmax, hit);
  }
  Ray8x ray(s, std::false_type{}, tmax);
  return intersect8x<Isa, kOrdered, false>(bvh.base(), ray, tri, tmax, hit);
}

template <typename Isa>
bool bvh8_occluded(const BVH8& bvh, const vec3& o, const vec3& d, float tmax) {
  if (bvh.empty()) return false;
  WC(rays);
  const RaySetup<Isa> s(o, d);
  LazyTriRay4<Isa> tri(s);
  if (__builtin_expect(s.fma, 1)) {
    Ray8x ray(s, std::true_type{}, tmax);
    return occluded8x<Isa, true>(bvh.base(), ray, tri);
  }
  Ray8x ray(s, std::false_type{}, tmax);
  return occluded8x<Isa, false>(bvh.base(), ray, tri);
}

}  // namespace
}  // namespace tessera
