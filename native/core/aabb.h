// Axis-aligned bounding box and the slab test (Kay & Kajiya 1986; Williams
// et al. 2005 for the inverse-direction form).
#pragma once
#include <cstring>
#include "math.h"

namespace tessera {

struct AABB {
  vec3 lo{kInf};
  vec3 hi{-kInf};

  void grow(const vec3& p) { lo = glm::min(lo, p); hi = glm::max(hi, p); }
  void grow(const AABB& b) { lo = glm::min(lo, b.lo); hi = glm::max(hi, b.hi); }
  bool empty() const { return lo.x > hi.x; }
  vec3 extent() const { return hi - lo; }
  vec3 center() const { return 0.5f * (lo + hi); }
  float half_area() const {
    if (empty()) return 0.0f;
    vec3 e = extent();
    return e.x * e.y + e.y * e.z + e.z * e.x;
  }
  bool contains(const AABB& b) const {
    return b.empty() || (glm::all(glm::lessThanEqual(lo, b.lo)) && glm::all(glm::greaterThanEqual(hi, b.hi)));
  }
};

// Returns the entry distance of the ray into [lo, hi] or kInf on a miss.
// The exit distance is widened by 1 + 2 gamma(3) so that rounding never
// makes the test miss a box the ray grazes (pbrt-v4, 6.1.2; Ize 2013).
inline float intersect_box(const vec3& lo, const vec3& hi, const vec3& o, const vec3& inv_d, float tmax) {
  vec3 t0 = (lo - o) * inv_d;
  vec3 t1 = (hi - o) * inv_d;
  vec3 tn = glm::min(t0, t1), tf = glm::max(t0, t1);
  float tnear = std::max(std::max(tn.x, tn.y), std::max(tn.z, 0.0f));
  float tfar = std::min(std::min(tf.x, tf.y), std::min(tf.z, tmax)) * (1.0f + 2.0f * gamma(3));
  return tnear <= tfar ? tnear : kInf;
}

// The same test with separate origins for the lo and hi planes. A ray parallel
// to an axis (direction component below 1e-30, inverse clamped to +-1e30)
// whose origin lies exactly on a face would otherwise get 0 * 1e30 = 0 as the
// far distance of that slab and miss the box; the ray setup nudges the origin
// by a tiny delta, inwards for each plane (o_lo = o + delta, o_hi = o - delta),
// which only ever makes the test more conservative. Non-parallel axes have
// delta = 0 and the arithmetic above.
inline float intersect_box(const vec3& lo, const vec3& hi, const vec3& o_lo, const vec3& o_hi, const vec3& inv_d,
                           float tmax) {
  vec3 t0 = (lo - o_lo) * inv_d;
  vec3 t1 = (hi - o_hi) * inv_d;
  vec3 tn = glm::min(t0, t1), tf = glm::max(t0, t1);
  float tnear = std::max(std::max(tn.x, tn.y), std::max(tn.z, 0.0f));
  float tfar = std::min(std::min(tf.x, tf.y), std::min(tf.z, tmax)) * (1.0f + 2.0f * gamma(3));
  return tnear <= tfar ? tnear : kInf;
}

// Per-axis origin nudge for the two-origin slab test: 0 unless the direction
// component is (near) zero. delta * 1e30 >= 1e10, so the nudged slab spans at
// least t in [-1e10, 1e10].
// x with its sign flipped when flip is 1 (0 or 1; a bit operation, no branch).
inline float flip_sign(float x, int flip) {
  uint32_t bits;
  std::memcpy(&bits, &x, 4);
  bits ^= uint32_t(flip) << 31;
  std::memcpy(&x, &bits, 4);
  return x;
}

// x (1 + 2 gamma(3)), two ulps further from zero (zero, inf and NaN stay): an
// inverse direction (or tmax) that widens the far planes of the SIMD node
// tests by at least intersect_box's factor, without a multiply per node.
inline float widen_far(float x) {
  const float w = x * (1.0f + 2.0f * gamma(3));
  uint32_t bits;
  std::memcpy(&bits, &w, 4);
  const uint32_t mag = bits & 0x7FFFFFFFu;
  if (mag == 0 || mag >= 0x7F800000u) return w;
  bits = mag >= 0x7F7FFFFEu ? (bits & 0x80000000u) | 0x7F800000u : bits + 2;
  std::memcpy(&x, &bits, 4);
  return x;
}

inline float parallel_axis_delta(float o, float d) {
  return std::abs(d) < 1e-30f ? std::abs(o) * 1e-6f + 1e-20f : 0.0f;
}

}  // namespace tessera
