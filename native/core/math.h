// Basic maths shared by the whole core: GLM vectors, rays, boxes and the
// floating-point error bounds used for robust ray origins (pbrt-v4, 6.8).
#pragma once
#include <glm/glm.hpp>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <cstring>

namespace tessera {

using glm::vec2;
using glm::vec3;
using glm::vec4;
using glm::mat4;
using glm::uvec3;

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 0.31830988618379067154f;
constexpr float kInf = std::numeric_limits<float>::infinity();

// gamma(n) bounds the relative error of n chained float operations
// (Higham; pbrt-v4 eq. 6.7).
constexpr float kMachineEps = std::numeric_limits<float>::epsilon() * 0.5f;
constexpr float gamma(int n) { return (n * kMachineEps) / (1 - n * kMachineEps); }

// |v| per component, by clearing sign bits. glm::abs is written
// x >= 0 ? x : -x, which g++ must keep as a compare and a branch (the two
// differ for -0): a misprediction wherever the signs vary, as they do from
// one shading point to the next.
inline vec3 abs(const vec3& v) { return vec3(std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)); }

inline float max_component(const vec3& v) { return std::max(v.x, std::max(v.y, v.z)); }
inline int max_dimension(const vec3& v) { return v.x > v.y ? (v.x > v.z ? 0 : 2) : (v.y > v.z ? 1 : 2); }
inline float average(const vec3& v) { return (v.x + v.y + v.z) / 3.0f; }
inline float luminance(const vec3& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }
inline bool is_finite(const vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
inline float safe_sqrt(float x) { return std::sqrt(std::max(0.0f, x)); }
inline float sqr(float x) { return x * x; }

// (cos x, sin x) for |x| <= pi/4 by the minimax polynomials of Cephes' sinf
// and cosf (within 1 ulp there), inline: the samplers need no library call.
inline vec2 cos_sin_quarter(float x) {
  const float z = x * x;
  const float s = x + x * z * ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f);
  const float c = 1.0f - 0.5f * z + z * z * ((2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f);
  return vec2(c, s);
}

// (cos 2 pi u, sin 2 pi u) for u in [0, 1]: the nearest quarter turn q (4u
// and 4u - q are exact in float) and the polynomials for the rest, within
// pi/4 (a hair beyond where 4u + 0.5 rounds up). Within 1.1e-7 of the exact
// values; std::cos / std::sin of the rounded float 2 pi u are within 4.2e-7.
inline vec2 cos_sin_2pi(float u) {
  const float t = 4.0f * u;
  const int q = int(t + 0.5f);
  const vec2 cs = cos_sin_quarter((t - float(q)) * (0.5f * kPi));
  switch (q & 3) {
    case 0: return cs;
    case 1: return vec2(-cs.y, cs.x);
    case 2: return -cs;
    default: return vec2(cs.y, -cs.x);
  }
}

// atan2(y, x) in float, inline (glibc's atanf and atan2f are calls the
// compiler cannot inline: 3.2% of bunny_glass.blend's render, whose world
// image maps every escaping ray's direction through two of them). The
// octant's ratio a = min / max of |x|, |y| in [0, 1], atan a = a P(a^2) with P
// of degree 8, fitted to the relative error of atan a / a on [0, 1] (Lawson's
// iteratively reweighted least squares towards the minimax fit): within
// 1.2e-7 absolute and 1.6e-7 relative of atan after float rounding (glibc's
// atanf: about 6e-8; test Numerics.Atan2PolyIsAtan2), relative so that the
// solid angle of a tiny triangle keeps its digits. Then pi/2 - r, pi - r
// and the sign of y place it in its octant; zeros and infinities as atan2's.
inline float atan2_poly(float y, float x) {
  if (std::isnan(x) || std::isnan(y)) return x + y;
  const float ax = std::fabs(x), ay = std::fabs(y);
  const float hi = std::max(ax, ay), lo = std::min(ax, ay);
  float r = 0.0f;
  if (hi > 0.0f) {
    const float a = lo == hi ? 1.0f : lo / hi;  // 1 for two infinities too
    const float t = a * a;
    float p = 0.002849911106750369f;
    p = p * t - 0.016068723052740097f;
    p = p * t + 0.04269168898463249f;
    p = p * t - 0.07504310458898544f;
    p = p * t + 0.10640943050384521f;
    p = p * t - 0.14203646779060364f;
    p = p * t + 0.1999261975288391f;
    p = p * t - 0.3333307206630707f;
    r = a * (p * t + 1.0f);
    if (ay > ax) r = 0.5f * kPi - r;
  }
  if (std::signbit(x)) r = kPi - r;
  return std::copysign(r, y);
}

struct Ray {
  vec3 o;
  vec3 d;
  float tmax = kInf;
};

// Orthonormal basis around a unit vector (Duff et al. 2017, "Building an
// orthonormal basis, revisited").
inline void make_basis(const vec3& n, vec3& t, vec3& b) {
  float sign = std::copysign(1.0f, n.z);
  float a = -1.0f / (sign + n.z);
  float c = n.x * n.y * a;
  t = vec3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
  b = vec3(c, sign + n.y * n.y * a, -n.y);
}

struct Frame {
  vec3 t, b, n;
  explicit Frame(const vec3& normal) : n(normal) { make_basis(n, t, b); }
  vec3 to_local(const vec3& v) const { return vec3(glm::dot(v, t), glm::dot(v, b), glm::dot(v, n)); }
  vec3 to_world(const vec3& v) const { return t * v.x + b * v.y + n * v.z; }
};

// Next representable float towards +inf / -inf.
inline float next_float_up(float v) {
  if (std::isinf(v) && v > 0.f) return v;
  if (v == -0.f) v = 0.f;
  uint32_t ui;
  std::memcpy(&ui, &v, sizeof ui);
  ui = v >= 0 ? ui + 1 : ui - 1;
  std::memcpy(&v, &ui, sizeof ui);
  return v;
}
inline float next_float_down(float v) {
  if (std::isinf(v) && v < 0.f) return v;
  if (v == 0.f) v = -0.f;
  uint32_t ui;
  std::memcpy(&ui, &v, sizeof ui);
  ui = v > 0 ? ui - 1 : ui + 1;
  std::memcpy(&v, &ui, sizeof ui);
  return v;
}

// Moves a surface point p with absolute error bound p_error off the surface
// along the geometric normal n, to the side of w, far enough that a ray
// leaving it cannot re-hit the same surface (pbrt-v4, 6.8.6).
inline vec3 offset_ray_origin(const vec3& p, const vec3& p_error, const vec3& n, const vec3& w) {
  float d = glm::dot(abs(n), p_error);
  vec3 offset = d * n;
  if (glm::dot(w, n) < 0) offset = -offset;
  vec3 po = p + offset;
  for (int i = 0; i < 3; ++i) {
    if (offset[i] > 0) po[i] = next_float_up(po[i]);
    else if (offset[i] < 0) po[i] = next_float_down(po[i]);
  }
  return po;
}

}  // namespace tessera
