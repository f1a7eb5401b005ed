// Watertight ray/triangle intersection (Woop, Benthin, Wald 2013, "Watertight
// Ray/Triangle Intersection", JCGT 2(1)). Rays aimed at a shared edge or vertex
// hit at least one of the triangles meeting there; there are no cracks.
#pragma once
#include "math.h"

namespace tessera {

// Per-ray constants of the shear that maps the ray onto the +z axis,
// computed once per ray (and once per instance for transformed rays).
struct RayShear {
  int kx, ky, kz;
  float sx, sy, sz;

  // Branch-free (the same axes and values as max_dimension and a swap):
  // incoherent rays mispredicted every data-dependent branch here, and glm's
  // operator[] with a run-time index is a switch.
  explicit RayShear(const vec3& d) {
    const float dv[3] = {d.x, d.y, d.z};
    const float ax = std::abs(d.x), ay = std::abs(d.y), az = std::abs(d.z);
    // max_dimension's choice from its three comparisons, by table.
    static constexpr int8_t kMax[8] = {2, 2, 2, 0, 1, 2, 1, 0};
    const int idx = int(ax > ay) | int(ax > az) << 1 | int(ay > az) << 2;
    kz = kMax[idx];
    static constexpr int8_t kNext[3] = {1, 2, 0};
    kx = kNext[kz];
    ky = kNext[kx];
    const int swap = -int(dv[kz] < 0.0f);  // keep the winding order
    const int t = (kx ^ ky) & swap;
    kx ^= t, ky ^= t;
    sx = dv[kx] / dv[kz];
    sy = dv[ky] / dv[kz];
    sz = 1.0f / dv[kz];
  }
  // From its parts (the SIMD tests' fallback, which holds them broadcast).
  RayShear(int kx_, int ky_, int kz_, float sx_, float sy_, float sz_)
      : kx(kx_), ky(ky_), kz(kz_), sx(sx_), sy(sy_), sz(sz_) {}
};

struct TriangleHit {
  float t, u, v;  // distance and barycentrics of v1 and v2
};

// Conservative bound on the rounding error of the computed t (pbrt-v4,
// 6.8.5, from the sheared vertices and the edge functions). A float t above
// it is certainly positive. One not above it may be the very surface the ray
// leaves, or a real hit that float cannot certify: the bound's main term,
// the edge functions' error times the largest |z| of the triangle over det,
// is large on long thin triangles (modern_hall's 8.8 m x 6 mm ceiling strip,
// hit at t = 0.077: bound 0.11; the float t itself was within 4e-6), and
// those are recomputed in double by refine_triangle_t. A float t <= 0 stays a
// miss without that look: a real hit there is nearer than the float t's own
// rounding error (no ray of the interior benchmark that disagrees with Embree
// is one), and looking would put every ray's own triangle (float t just
// below 0) through the bound.
inline float triangle_t_error(float ax, float ay, float az, float bx, float by, float bz, float cx, float cy, float cz,
                              float max_z_raw, float sx, float sy, float u, float v, float w, float inv_det) {
  const float max_xt = std::max(std::abs(ax), std::max(std::abs(bx), std::abs(cx)));
  const float max_yt = std::max(std::abs(ay), std::max(std::abs(by), std::abs(cy)));
  const float max_zt = std::max(std::abs(az), std::max(std::abs(bz), std::abs(cz)));
  // x' = x - sx z uses the unscaled z: the error of x' does not grow with
  // 1/|d| (instance-space rays are not unit length; with pbrt's max_zt here,
  // every hit on a mesh scaled 1e4 by its transform was rejected).
  const float delta_x = gamma(5) * (max_xt + std::abs(sx) * max_z_raw);
  const float delta_y = gamma(5) * (max_yt + std::abs(sy) * max_z_raw);
  const float delta_z = gamma(3) * max_zt;
  const float delta_e = 2.0f * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
  const float max_e = std::max(std::abs(u), std::max(std::abs(v), std::abs(w)));
  return 3.0f * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * std::abs(inv_det);
}

// The ray's distance to the plane of (p0, p1, p2) in double, from the same
// sheared construction (triangle.cpp, with its error bounds): true, and t set
// to it rounded to float, when it is certainly positive and below tmax. The
// fallback of intersect_triangle and intersect_tri4 for a float t within its
// error bound; out of line, one compiled copy for every path (same bits).
bool refine_triangle_t(const vec3& p0, const vec3& p1, const vec3& p2, const vec3& o, const RayShear& s, float tmax,
                       float& t);

// Returns true and fills hit if the ray hits triangle (p0, p1, p2) at
// 0 < t < tmax. Edges count as inside (watertight, no gaps).
inline bool intersect_triangle(const vec3& p0, const vec3& p1, const vec3& p2, const vec3& o,
                               const RayShear& s, float tmax, TriangleHit& hit) {
  const vec3 a = p0 - o, b = p1 - o, c = p2 - o;
  const float ax = a[s.kx] - s.sx * a[s.kz], ay = a[s.ky] - s.sy * a[s.kz];
  const float bx = b[s.kx] - s.sx * b[s.kz], by = b[s.ky] - s.sy * b[s.kz];
  const float cx = c[s.kx] - s.sx * c[s.kz], cy = c[s.ky] - s.sy * c[s.kz];
  float u = cx * by - cy * bx;
  float v = ax * cy - ay * cx;
  float w = bx * ay - by * ax;
  // On an exact zero, redo the edge functions in double (paper, section 3.3).
  if (u == 0.0f || v == 0.0f || w == 0.0f) {
    u = float(double(cx) * double(by) - double(cy) * double(bx));
    v = float(double(ax) * double(cy) - double(ay) * double(cx));
    w = float(double(bx) * double(ay) - double(by) * double(ax));
  }
  if ((u < 0.0f || v < 0.0f || w < 0.0f) && (u > 0.0f || v > 0.0f || w > 0.0f)) return false;
  const float det = u + v + w;
  if (det == 0.0f) return false;
  const float az = s.sz * a[s.kz], bz = s.sz * b[s.kz], cz = s.sz * c[s.kz];
  const float t_scaled = u * az + v * bz + w * cz;
  // Compare against the range without dividing: the sign of det flips both sides.
  if (det < 0.0f ? (t_scaled >= 0.0f || t_scaled < tmax * det) : (t_scaled <= 0.0f || t_scaled > tmax * det))
    return false;
  const float inv_det = 1.0f / det;
  hit.t = t_scaled * inv_det;
  hit.u = v * inv_det;
  hit.v = w * inv_det;
  const float max_z_raw = std::max(std::abs(a[s.kz]), std::max(std::abs(b[s.kz]), std::abs(c[s.kz])));
  if (hit.t > triangle_t_error(ax, ay, az, bx, by, bz, cx, cy, cz, max_z_raw, s.sx, s.sy, u, v, w, inv_det))
    return hit.t < tmax;
  // Positive in float but within its error bound: decide in double (the edge
  // functions above still decide inside/outside; u and v stay theirs).
  return refine_triangle_t(p0, p1, p2, o, s, tmax, hit.t);
}

}  // namespace tessera
