// BVH traversal for single rays: closest hit with early-out against the
// current nearest distance and front-to-back child order, or any hit for
// shadow rays. Leaves call a primitive test given by the caller, so the same
// loop serves the triangle BLAS and the instance TLAS.
#pragma once
#include "bvh.h"

namespace tessera {

struct TraversalRay {
  vec3 o, d, inv_d;
  vec3 o_lo, o_hi;  // origins for the lo / hi planes of the slab test (see aabb.h)
  float tmax;
  explicit TraversalRay(const vec3& origin, const vec3& dir, float t_max) : o(origin), d(dir), tmax(t_max) {
    // A zero component would give 0 * inf = NaN in the slab test; a tiny
    // value of the same sign gives the same answer without it.
    for (int i = 0; i < 3; ++i) {
      float di = std::abs(d[i]) < 1e-30f ? std::copysign(1e-30f, d[i]) : d[i];
      inv_d[i] = 1.0f / di;
      const float delta = parallel_axis_delta(o[i], d[i]);
      o_lo[i] = o[i] + delta;
      o_hi[i] = o[i] - delta;
    }
  }
};

// intersect_leaf(first, count, ray) tests primitives [first, first+count),
// shrinks ray.tmax on a hit and returns true if it hit anything.
// With any_hit, traversal stops at the first hit.
template <bool kAnyHit, bool kOrdered = true, typename LeafFn>
inline bool traverse(const BVHNode* nodes, TraversalRay& ray, LeafFn&& intersect_leaf) {
  struct Entry { uint32_t node; float t; };
  Entry stack[64];
  int sp = 0;
  uint32_t index = 0;
  bool hit = false;
  if (intersect_box(nodes[0].lo, nodes[0].hi, ray.o_lo, ray.o_hi, ray.inv_d, ray.tmax) == kInf) return false;
  for (;;) {
    const BVHNode& node = nodes[index];
    if (node.is_leaf()) {
      if (intersect_leaf(node.first, node.count, ray)) {
        hit = true;
        if (kAnyHit) return true;
      }
    } else {
      uint32_t a = node.first, b = node.first + 1;
      float ta = intersect_box(nodes[a].lo, nodes[a].hi, ray.o_lo, ray.o_hi, ray.inv_d, ray.tmax);
      float tb = intersect_box(nodes[b].lo, nodes[b].hi, ray.o_lo, ray.o_hi, ray.inv_d, ray.tmax);
      if (kOrdered && tb < ta) {
        std::swap(ta, tb);
        std::swap(a, b);
      }
      if (ta != kInf) {
        if (tb != kInf && sp < 64) stack[sp++] = {b, tb};
        index = a;
        continue;
      }
      if (tb != kInf) {
        index = b;
        continue;
      }
    }
    // Pop, skipping nodes whose entry lies beyond the nearest hit so far
    // (nearest-hit early-out), against tmax widened as intersect_box's far
    // distance: a node is skipped only where intersect_box would miss it.
    for (;;) {
      if (sp == 0) return hit;
      --sp;
      if (stack[sp].t <= ray.tmax * (1.0f + 2.0f * gamma(3))) break;
    }
    index = stack[sp].node;
  }
}

}  // namespace tessera
