// BVH8 traversal compiled for AVX-512 (F, VL, DQ, BW) and FMA, chosen at run
// time over the AVX2 one (bvh8_avx2.cpp) when the CPU has it: same tree, same
// triangle test. What it changes:
// - the node test is one multiply-add per plane (b inv - c, c = o inv rounded
//   outwards per ray; see intersect_node8x) instead of a subtract and a
//   multiply: one op less on the per-node dependency chain, still
//   conservative for any origin. Its distances can differ from the AVX2
//   test's by an ulp, so children with (nearly) equal entry distances may be
//   visited in another order: the closest hit is the same unless two hits lie
//   within their t error of each other (coplanar duplicates);
// - the node test's compare lands in a mask register (no movemask) and the
//   entry distances stay in a register;
// - closest hit orders three or more hit children with a sorting network in
//   one ymm (Embree's in-register sort) instead of an insertion sort with a
//   mispredicted branch per child: 32-bit keys, the entry distance's bits
//   with the lane in the low three, so distances within 8 ulps count as
//   equal and go by lane; the sorted keys pick the child references, and the
//   pairs are the stack entries (two 32-byte stores push them all). No zmm:
//   the same network over 64-bit keys in one zmm was 3-17% slower on a
//   Xeon with AVX-512 (docs/BVH_BENCHMARK.md), and 512-bit instructions lower
//   the clock of the whole core on many Intel CPUs;
// - any hit pushes the hit children with one compress (vpcompressd) and store,
//   and does not prefetch them.
// Headers come before the target pragma (see bvh8_avx2.cpp). AVX-512F makes
// GCC contract a * b + c into FMA (even across intrinsics), which would
// change the triangle test's rounding: fp-contract is off for everything
// below; the node test's multiply-adds are explicit.
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

// Ray8's values (bvh8_avx2.cpp: the 1e-30 clamp, 1 / d, widen_far,
// parallel_axis_delta, flip_sign), the three axes at once in one SSE
// register: the same operations lane by lane, so the same bits. And the
// constants of the node test by multiply-add (intersect_node8x<true>).
struct RaySetup {
  __m128 inv, inv_far, o_near, o_far, c_near, c_far;
  int near_bits;
  bool fma;  // c_near and c_far finite on every axis

  RaySetup(const vec3& origin, const vec3& d) {
    const __m128 o4 = _mm_setr_ps(origin.x, origin.y, origin.z, 0.0f);
    const __m128 d4 = _mm_setr_ps(d.x, d.y, d.z, 1.0f);
    const __m128 sign = _mm_set1_ps(-0.0f);
    const __m128 abs_d = _mm_andnot_ps(sign, d4);
    const __m128 tiny = _mm_cmplt_ps(abs_d, _mm_set1_ps(1e-30f));
    const __m128 di = _mm_blendv_ps(d4, _mm_or_ps(_mm_and_ps(sign, d4), _mm_set1_ps(1e-30f)), tiny);
    inv = _mm_div_ps(_mm_set1_ps(1.0f), di);
    // widen_far: x (1 + 2 gamma(3)), then two ulps out unless zero, inf or
    // NaN; a magnitude within two ulps of inf becomes inf.
    const __m128i w = _mm_castps_si128(_mm_mul_ps(inv, _mm_set1_ps(1.0f + 2.0f * gamma(3))));
    const __m128i mag = _mm_and_si128(w, _mm_set1_epi32(0x7FFFFFFF));
    const __mmask8 keep = _mm_cmpeq_epi32_mask(mag, _mm_setzero_si128()) | _mm_cmpgt_epi32_mask(mag, _mm_set1_epi32(0x7F7FFFFF));
    const __mmask8 to_inf = _mm_cmpgt_epi32_mask(mag, _mm_set1_epi32(0x7F7FFFFD)) & ~keep;
    __m128i wf = _mm_mask_add_epi32(w, __mmask8(~keep), w, _mm_set1_epi32(2));
    wf = _mm_mask_or_epi32(wf, to_inf, _mm_and_si128(w, _mm_castps_si128(sign)), _mm_set1_epi32(0x7F800000));
    inv_far = _mm_castsi128_ps(wf);
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
    // whatever the rounding did: on the bit patterns, +1 for a float >= +0
    // and -1 for a negative one (down: the same on the negated value); + 0
    // first turns -0 into +0. A short chain after the division (most random
    // rays visit two nodes: a rounding test in double cost them 10%).
    // A result below the smallest normal float goes to it (positive) or to
    // +0 (negative), still an upper bound: a subnormal constant would make
    // every node test's multiply-add a microcode assist (~100 cycles), and
    // o inv rounds to 0 wherever an origin coordinate is 0 (a camera on an
    // axis, a ray leaving a floor at z = 0): next_up(0) is subnormal.
    auto next_up = [](__m128 x) {
      const __m128i b = _mm_castps_si128(_mm_add_ps(x, _mm_setzero_ps()));
      __m128i r = _mm_add_epi32(b, _mm_or_si128(_mm_srai_epi32(b, 31), _mm_set1_epi32(1)));
      const __m128i min_normal = _mm_set1_epi32(0x00800000);
      const __mmask8 tiny = _mm_cmplt_epi32_mask(_mm_and_si128(r, _mm_set1_epi32(0x7FFFFFFF)), min_normal);
      const __mmask8 positive = _mm_cmpgt_epi32_mask(r, _mm_setzero_si128());
      r = _mm_mask_mov_epi32(r, tiny, _mm_setzero_si128());
      return _mm_castsi128_ps(_mm_mask_mov_epi32(r, __mmask8(tiny & positive), min_normal));
    };
    c_near = next_up(_mm_mul_ps(o_near, inv));
    c_far = _mm_xor_ps(next_up(_mm_xor_ps(_mm_mul_ps(o_far, inv_far), sign)), sign);
    const __m128 inf = _mm_set1_ps(kInf);
    const __mmask8 finite = _mm_cmp_ps_mask(_mm_andnot_ps(sign, c_near), inf, _CMP_LT_OQ) &
                            _mm_cmp_ps_mask(_mm_andnot_ps(sign, c_far), inf, _CMP_LT_OQ);
    fma = (finite & 7) == 7;
  }
};

struct Ray8x {
  // RaySetup's values per axis, broadcast; c_near and c_far only with the
  // node test by multiply-add (kFma below).
  __m256 o_near[3], o_far[3], c_near[3], c_far[3], inv[3], inv_far[3];
  __m256 tmax8_far;  // tmax widened as the far planes
  __m128 tmax4;
  int near_lo[3];
  // The triangle test's constants (shear), made at the first leaf: most
  // primary and random rays never reach one (they miss the mesh or pass
  // between its boxes), and the shear costs a division and table look-ups.
  vec3 org, dir;
  bool tri_ready = false;
  alignas(16) unsigned char tri_storage[sizeof(TriRay4)];

  const TriRay4& tri() {
    if (__builtin_expect(!tri_ready, 0)) {
      new (tri_storage) TriRay4(org, dir);
      tri_ready = true;
    }
    return *std::launder(reinterpret_cast<const TriRay4*>(tri_storage));
  }

  // kFma: with c_near and c_far (the node test by multiply-add). Made after
  // the branch on setup.fma, so that no node test waits for that check.
  template <bool kFma>
  Ray8x(const RaySetup& s, std::bool_constant<kFma>, const vec3& origin, const vec3& d, float t_max) : org(origin), dir(d) {
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
};

// intersect_node8 (bvh8_avx2.cpp) with the final compare into a mask
// register; tnear (as integers, >= +0 on hit lanes) in `near`.
// kFma: each plane distance by one multiply-add, b inv - c, with c = o inv
// rounded up on the near planes and o inv_far rounded down on the far ones
// (Ray8x; Embree's node test made one-sided): b inv - c is at most the exact
// (b - o) inv on the near planes and at least (b - o) inv_far on the far
// ones, and one rounding follows instead of two, so both stay on the
// conservative side of intersect_node8's bounds wherever the origin is (the
// rounding of c moves a plane outwards by an ulp of o inv). Only with c
// finite on every axis: a c of inf would give inf - inf on the unused
// lanes' infinite planes.
template <bool kFma>
inline __mmask8 intersect_node8x(const BVH8Node& n, const Ray8x& r, __m256i& near) {
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
  near = _mm256_max_epi32(_mm256_max_epi32(inx, iny), _mm256_max_epi32(inz, _mm256_setzero_si256()));
  const __m256i far = _mm256_min_epi32(_mm256_min_epi32(ifx, ify), _mm256_min_epi32(ifz, _mm256_castps_si256(r.tmax8_far)));
  return _mm256_cmple_epi32_mask(near, far);
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
inline unsigned root_test(const BVH8Node& root, const Ray8x& r, __m256i& near) {
  WC(nodes);
  _mm_prefetch(reinterpret_cast<const char*>(root.child), _MM_HINT_T0);
  return intersect_node8x<false>(root, r, near);
}

// Lanes that keep the larger of the pair in bitonic step (k, j) of a
// descending sort (Batcher's bitonic network, lane i paired with i ^ j).
constexpr __mmask8 bitonic_max_lanes(int k, int j) {
  int m = 0;
  for (int i = 0; i < 8; ++i)
    if (((i & j) == 0) == ((i & k) == 0)) m |= 1 << i;
  return __mmask8(m);
}

inline __m256i bitonic_step(__m256i v, __m256i partner, __mmask8 take_max) {
  return _mm256_mask_max_epu32(_mm256_min_epu32(v, partner), take_max, v, partner);
}

// Eight unsigned 32-bit keys sorted descending, in registers (six steps).
inline __m256i sort8_desc(__m256i v) {
  auto swap1 = [](__m256i x) { return _mm256_shuffle_epi32(x, 0xB1); };         // i ^ 1
  auto swap2 = [](__m256i x) { return _mm256_shuffle_epi32(x, 0x4E); };         // i ^ 2
  auto swap4 = [](__m256i x) { return _mm256_permute4x64_epi64(x, 0x4E); };     // i ^ 4
  v = bitonic_step(v, swap1(v), bitonic_max_lanes(2, 1));
  v = bitonic_step(v, swap2(v), bitonic_max_lanes(4, 2));
  v = bitonic_step(v, swap1(v), bitonic_max_lanes(4, 1));
  v = bitonic_step(v, swap4(v), bitonic_max_lanes(8, 4));
  v = bitonic_step(v, swap2(v), bitonic_max_lanes(8, 2));
  v = bitonic_step(v, swap1(v), bitonic_max_lanes(8, 1));
  return v;
}

constexpr int kStackSize = 512;

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
__attribute__((always_inline)) inline bool leaf_intersect(const char* base, uint32_t ref, Ray8x& ray, float& t_best, BVH4Hit& hit) {
  const Tri4* tris = wide_leaf(base, ref);
  WC(leaves);
  const uint32_t blocks = bvh4_leaf_blocks(ref);
  const TriRay4& tri = ray.tri();
  bool found = false;
  for (uint32_t b = 0; b < blocks; ++b) {
    WC(blocks);
    __m128 t, u, v;
    const int mask = intersect_tri4<true>(tris[b], tri, ray.tmax4, t, u, v);
    if (mask == 0) continue;
    alignas(16) float ts[4], us[4], vs[4];
    _mm_store_ps(ts, t);
    _mm_store_ps(us, u);
    _mm_store_ps(vs, v);
    // Nearest lane; on equal distances the lower lane (earlier triangle) wins.
    int best = -1;
    for (int m = mask; m; m &= m - 1) {
      const int lane = __builtin_ctz(m);
      if (best < 0 || ts[lane] < ts[best]) best = lane;
    }
    t_best = ts[best];
    hit = {ts[best], us[best], vs[best], tris[b].prim[best]};
    ray.set_tmax(t_best);
    found = true;
  }
  return found;
}

template <bool kOrdered, bool kFma>
bool intersect8x(const char* base, Ray8x& ray, float& tmax, BVH4Hit& hit) {
  // Eight entries of slack: pushes store all eight sorted entries.
  alignas(64) WideStackEntry stack[kStackSize + 8];
  static_assert(sizeof(WideStackEntry) == 8, "stack entries are one 64-bit lane: {ref, t} little-endian");
  int sp = 0;
  uint32_t ref = 0;
  bool found = false;
  float t_best = tmax;
  // Popped entries are skipped against t_best widened as the node test's far
  // planes (widen_far), so that a child is dropped only where the node test
  // with the current t_best would drop it.
  float t_cull = widen_far(tmax);
  const __m256i lane_ids = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  // The root first, by the subtract-then-multiply form (from the origins,
  // no c), outside the loop (see root_test).
  const BVH8Node* np = &wide_node<BVH8Node>(base, 0);
  __m256i tnear;
  unsigned mask = root_test(*np, ray, tnear);
  goto tested;
  for (;;) {
    if (!bvh4_is_leaf(ref)) {
      np = &wide_node<BVH8Node>(base, ref);
      WC(nodes);
      _mm_prefetch(reinterpret_cast<const char*>(np->child), _MM_HINT_T0);
      mask = intersect_node8x<kFma>(*np, ray, tnear);
    tested:
      const BVH8Node& n = *np;
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
          _mm256_store_si256(reinterpret_cast<__m256i*>(dist), tnear);
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
          _mm256_store_si256(reinterpret_cast<__m256i*>(dist), tnear);
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
        const __m256i key = _mm256_maskz_mov_epi32(__mmask8(mask), _mm256_or_si256(_mm256_andnot_si256(low3, tnear), lane_ids));
        // The next node, the hit child of the smallest key, by a min
        // reduction: the six-step sort stays off the path to the next node's
        // loads (only the stack stores need it).
        __m256i m = _mm256_mask_blend_epi32(__mmask8(mask), _mm256_set1_epi32(-1), key);
        m = _mm256_min_epu32(m, _mm256_permute4x64_epi64(m, 0x4E));
        m = _mm256_min_epu32(m, _mm256_shuffle_epi32(m, 0x4E));
        m = _mm256_min_epu32(m, _mm256_shuffle_epi32(m, 0xB1));
        const uint32_t next = n.child[uint32_t(_mm256_cvtsi256_si32(m)) & 7];
        const __m256i sorted = sort8_desc(key);
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
    } else if (leaf_intersect(base, ref, ray, t_best, hit)) {
      found = true;
      t_cull = widen_far(t_best);
    }
    // Pop, skipping entries farther than the nearest hit so far.
    for (;;) {
      if (sp == 0) {
        tmax = t_best;
        return found;
      }
      --sp;
      if (stack[sp].t <= t_cull) break;
    }
    ref = stack[sp].ref;
  }
}

template <bool kFma>
bool occluded8x(const char* base, Ray8x& ray) {
  alignas(32) uint32_t stack[kStackSize + 8];
  int sp = 0;
  uint32_t ref = 0;
  const BVH8Node* np = &wide_node<BVH8Node>(base, 0);
  __m256i tnear;
  unsigned mask = root_test(*np, ray, tnear);
  goto tested;
  for (;;) {
    if (!bvh4_is_leaf(ref)) {
      np = &wide_node<BVH8Node>(base, ref);
      WC(nodes);
      _mm_prefetch(reinterpret_cast<const char*>(np->child), _MM_HINT_T0);
      mask = intersect_node8x<kFma>(*np, ray, tnear);
    tested:
      const BVH8Node& n = *np;
      WCN(hits_children, __builtin_popcount(mask));
      WCH(__builtin_popcount(mask));
      if (mask != 0) {
        const unsigned rest = mask & (mask - 1);
        if (rest) {
          // Push the other hit children in lane order (the last on top), as
          // wide_occluded does, with one compress and store.
          const __m256i refs = _mm256_load_si256(reinterpret_cast<const __m256i*>(n.child));
          _mm256_storeu_si256(reinterpret_cast<__m256i*>(stack + sp), _mm256_maskz_compress_epi32(__mmask8(rest), refs));
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
      const TriRay4& tri = ray.tri();
      for (uint32_t b = 0; b < blocks; ++b) {
        WC(blocks);
        __m128 t, u, v;
        if (intersect_tri4<true>(tris[b], tri, ray.tmax4, t, u, v)) return true;
      }
    }
    if (sp == 0) return false;
    ref = stack[--sp];
  }
}

}  // namespace

template <bool kOrdered>
bool bvh8_intersect_avx512(const BVH8& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  if (bvh.empty()) return false;
  WC(rays);
  const RaySetup s(o, d);
  if (__builtin_expect(s.fma, 1)) {
    Ray8x ray(s, std::true_type{}, o, d, tmax);
    return intersect8x<kOrdered, true>(bvh.base(), ray, tmax, hit);
  }
  Ray8x ray(s, std::false_type{}, o, d, tmax);
  return intersect8x<kOrdered, false>(bvh.base(), ray, tmax, hit);
}

template bool bvh8_intersect_avx512<true>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);
template bool bvh8_intersect_avx512<false>(const BVH8&, const vec3&, const vec3&, float&, BVH4Hit&);

bool bvh8_occluded_avx512(const BVH8& bvh, const vec3& o, const vec3& d, float tmax) {
  if (bvh.empty()) return false;
  WC(rays);
  const RaySetup s(o, d);
  if (__builtin_expect(s.fma, 1)) {
    Ray8x ray(s, std::true_type{}, o, d, tmax);
    return occluded8x<true>(bvh.base(), ray);
  }
  Ray8x ray(s, std::false_type{}, o, d, tmax);
  return occluded8x<false>(bvh.base(), ray);
}

}  // namespace tessera

#pragma GCC diagnostic pop
#pragma GCC pop_options
