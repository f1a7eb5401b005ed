// Closest-hit and any-hit traversal of a wide BVH whose leaves are runs of
// Tri4 blocks, for a width given by a Traits struct:
//   Node, Ray                      node and per-ray constant types
//   kStackSize                     traversal stack entries
//   test(node, ray, dist) -> mask  slab test of the children, entry distances in dist
//   tri_tmax(ray) -> __m128        current tmax for the triangle test
//   set_tmax(ray, t)               shrink the ray after a hit
//   cull_t(ray) -> float           tmax widened as the far planes (widen_far)
//   prefetch(base, ref)            fetch a child node's cache lines
// The SSE2 BVH4 (bvh4.cpp) runs these loops; the BVH8 kernels have their own
// (bvh8_traverse.h) and share the stack entry and the node and leaf
// addressing below. Included after simd_tri4.h inside each file's target
// region, so each compiles for its own instruction set; everything here has
// internal linkage.
#pragma once
#include "bvh4.h"
#include "simd_tri4.h"

namespace tessera {
namespace {

struct WideStackEntry {
  uint32_t ref;
  float t;
};

template <typename Node>
inline const Node& wide_node(const char* base, uint32_t ref) {
  return *reinterpret_cast<const Node*>(base + size_t(ref) * kNodeUnit);
}
inline const Tri4* wide_leaf(const char* base, uint32_t ref) {
  return reinterpret_cast<const Tri4*>(base + size_t(bvh4_leaf_first(ref)) * kBlockUnit);
}

// Pops the top entry not farther than t_cull (the nearest hit so far,
// widened as the node tests' far planes) into ref, dropping the farther ones
// above it; false when the stack runs out.
inline bool pop_nearer(const WideStackEntry* stack, int& sp, float t_cull, uint32_t& ref) {
  while (sp > 0) {
    --sp;
    if (stack[sp].t <= t_cull) {
      ref = stack[sp].ref;
      return true;
    }
  }
  return false;
}

// The hit of a Tri4 test's nearest lane among `mask` (on equal distances
// the lower lane, the earlier triangle).
inline BVH4Hit nearest_hit(const Tri4& tri, int mask, __m128 t, __m128 u, __m128 v) {
  alignas(16) float ts[4], us[4], vs[4];
  _mm_store_ps(ts, t);
  _mm_store_ps(us, u);
  _mm_store_ps(vs, v);
  int best = __builtin_ctz(mask);
  for (int m = mask & (mask - 1); m; m &= m - 1) {
    const int lane = __builtin_ctz(m);
    if (ts[lane] < ts[best]) best = lane;
  }
  return {ts[best], us[best], vs[best], tri.prim[best], &tri, uint32_t(best)};
}

// base: the tree's arena (WideBVH::base()).
template <typename Traits, bool kOrdered>
bool wide_intersect(const char* base, typename Traits::Ray& ray, float& tmax, BVH4Hit& hit) {
  constexpr int kWidth = Traits::kWidth;
  WideStackEntry stack[Traits::kStackSize];
  int sp = 0;
  uint32_t ref = 0;
  bool found = false;
  float t_best = tmax;
  // Popped entries are skipped against t_best widened as the node test's far
  // planes (widen_far), so that a child is dropped only where the node test
  // with the current t_best would drop it.
  float t_cull = Traits::cull_t(ray);
  for (;;) {
    if (!bvh4_is_leaf(ref)) {
      const auto& n = wide_node<typename Traits::Node>(base, ref);
      WC(nodes);
      // The child references sit apart from the boxes (the BVH8's last
      // line): ask for them now, next to the box loads, instead of after the
      // test has picked a child, which serialises two misses per level.
      _mm_prefetch(reinterpret_cast<const char*>(n.child), _MM_HINT_T0);
      alignas(32) float dist[kWidth];
      int mask = Traits::test(n, ray, dist);
      WCN(hits_children, __builtin_popcount(mask));
      WCH(__builtin_popcount(mask));
      if (mask != 0) {
        const int first = __builtin_ctz(mask);
        mask &= mask - 1;
        if (mask == 0) {  // one child hit: descend without the stack
          ref = n.child[first];
          continue;
        }
        if (!kOrdered) {
          // Stored order: push the others in reverse, descend into the first.
          int lanes[kWidth], k = 0;
          for (int m = mask; m; m &= m - 1) lanes[k++] = __builtin_ctz(m);
          for (int j = k - 1; j >= 0; --j) stack[sp++] = {n.child[lanes[j]], dist[lanes[j]]};
          ref = n.child[first];
          continue;
        }
        // Nearest first: insertion sort of the hit children by distance
        // (prefetching their nodes), farthest pushed first.
        WideStackEntry e[kWidth];
        int k = 0;
        e[k++] = {n.child[first], dist[first]};
        if (!bvh4_is_leaf(n.child[first])) Traits::prefetch(base, n.child[first]);
        for (int m = mask; m; m &= m - 1) {
          const int c = __builtin_ctz(m);
          WideStackEntry x{n.child[c], dist[c]};
          if (!bvh4_is_leaf(x.ref)) Traits::prefetch(base, x.ref);
          int j = k++;
          while (j > 0 && e[j - 1].t > x.t) {
            e[j] = e[j - 1];
            --j;
          }
          e[j] = x;
        }
        for (int j = k - 1; j > 0; --j) stack[sp++] = e[j];
        ref = e[0].ref;
        continue;
      }
    } else {
      const Tri4* tris = wide_leaf(base, ref);
      WC(leaves);
      const uint32_t blocks = bvh4_leaf_blocks(ref);
      for (uint32_t b = 0; b < blocks; ++b) {
        WC(blocks);
        __m128 t, u, v;
        const int mask = intersect_tri4(tris[b], ray.tri, Traits::tri_tmax(ray), t, u, v);
        if (mask == 0) continue;
        hit = nearest_hit(tris[b], mask, t, u, v);
        t_best = hit.t;
        Traits::set_tmax(ray, t_best);
        t_cull = Traits::cull_t(ray);
        found = true;
      }
    }
    if (!pop_nearer(stack, sp, t_cull, ref)) {
      tmax = t_best;
      return found;
    }
  }
}

template <typename Traits>
bool wide_occluded(const char* base, typename Traits::Ray& ray) {
  uint32_t stack[Traits::kStackSize];
  int sp = 0;
  uint32_t ref = 0;
  for (;;) {
    if (!bvh4_is_leaf(ref)) {
      const auto& n = wide_node<typename Traits::Node>(base, ref);
      WC(nodes);
      _mm_prefetch(reinterpret_cast<const char*>(n.child), _MM_HINT_T0);
      alignas(32) float dist[Traits::kWidth];
      int mask = Traits::test(n, ray, dist);
      WCN(hits_children, __builtin_popcount(mask));
      WCH(__builtin_popcount(mask));
      if (mask != 0) {
        const int first = __builtin_ctz(mask);
        for (int m = mask & (mask - 1); m; m &= m - 1) {
          const uint32_t c = n.child[__builtin_ctz(m)];
          // Any-hit visits every pushed node unless it stops: fetch them now.
          if (!bvh4_is_leaf(c)) Traits::prefetch(base, c);
          stack[sp++] = c;
        }
        ref = n.child[first];
        continue;
      }
    } else {
      const Tri4* tris = wide_leaf(base, ref);
      WC(leaves);
      const uint32_t blocks = bvh4_leaf_blocks(ref);
      for (uint32_t b = 0; b < blocks; ++b) {
        WC(blocks);
        __m128 t, u, v;
        if (intersect_tri4(tris[b], ray.tri, Traits::tri_tmax(ray), t, u, v)) return true;
      }
    }
    if (sp == 0) return false;
    ref = stack[--sp];
  }
}

}  // namespace
}  // namespace tessera
