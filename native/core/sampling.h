// Warps from the unit square to the shapes the renderer samples, with their
// densities (pbrt-v4 appendix A.5 and chapter 4 of "Ray Tracing Gems").
#pragma once
#include <vector>
#include "math.h"

namespace tessera {

inline vec2 sample_uniform_disk_concentric(vec2 u) {
  vec2 o = 2.0f * u - vec2(1.0f);
  if (o.x == 0.0f && o.y == 0.0f) return vec2(0.0f);
  // theta = pi/4 (y / x), or pi/2 - pi/4 (x / y): (cos, sin) of the second
  // is (sin, cos) of pi/4 (x / y).
  if (std::abs(o.x) > std::abs(o.y)) return o.x * cos_sin_quarter(0.25f * kPi * (o.y / o.x));
  const vec2 cs = cos_sin_quarter(0.25f * kPi * (o.x / o.y));
  return o.y * vec2(cs.y, cs.x);
}

// Cosine-weighted hemisphere around +z (Malley's method); pdf = cos / pi.
inline vec3 sample_cosine_hemisphere(vec2 u) {
  vec2 d = sample_uniform_disk_concentric(u);
  float z = safe_sqrt(1.0f - d.x * d.x - d.y * d.y);
  return vec3(d.x, d.y, z);
}

inline vec3 sample_uniform_sphere(vec2 u) {
  float z = 1.0f - 2.0f * u.x;
  float r = safe_sqrt(1.0f - z * z);
  const vec2 cs = r * cos_sin_2pi(u.y);
  return vec3(cs.x, cs.y, z);
}
constexpr float kUniformSpherePdf = 1.0f / (4.0f * kPi);

// Uniform direction in the cone of directions within acos(cos_max) of +z
// (pbrt-v4 A.5.4); cos_max = -1 is the whole sphere. Its density is
// uniform_cone_pdf(cos_max).
inline vec3 sample_uniform_cone(vec2 u, float cos_max) {
  const float z = 1.0f - u.x * (1.0f - cos_max);
  const vec2 cs = safe_sqrt(1.0f - z * z) * cos_sin_2pi(u.y);
  return vec3(cs.x, cs.y, z);
}
inline float uniform_cone_pdf(float cos_max) { return 1.0f / (2.0f * kPi * (1.0f - cos_max)); }

// Uniform point on a triangle, as barycentrics (b1, b2) of the 2nd and 3rd
// vertex (Heitz 2019, "A low-distortion map between triangle and square").
inline vec2 sample_uniform_triangle(vec2 u) {
  float b0, b1;
  if (u.x < u.y) {
    b0 = u.x / 2;
    b1 = u.y - b0;
  } else {
    b1 = u.y / 2;
    b0 = u.x - b1;
  }
  return vec2(b1, 1.0f - b0 - b1);
}

// Solid angle of the spherical triangle with unit-vector corners a, b, c
// (Van Oosterom and Strackee 1983: tan(omega/2) = |a.(b x c)| / (1 + a.b +
// b.c + c.a)); accurate for small triangles, unlike the angle excess.
inline float spherical_triangle_area(const vec3& a, const vec3& b, const vec3& c) {
  const glm::dvec3 da(a), db(b), dc(c);
  const double num = std::abs(glm::dot(da, glm::cross(db, dc)));
  const double den = 1.0 + glm::dot(da, db) + glm::dot(db, dc) + glm::dot(dc, da);
  // num and den are exact enough in float now; the inline float atan2 is
  // the cheaper one (within 1.6e-7 relative: math.h).
  return 2.0f * atan2_poly(float(num), float(den));
}

// Direction uniformly distributed in solid angle over the spherical triangle
// a, b, c (unit vectors from the shading point to the corners): Arvo 1995,
// "Stratified sampling of spherical triangles", in the formulation of
// pbrt-v4 (A.5.5). u.x picks the sub-triangle (a, b, c') of area u.x * area,
// u.y the point along the arc from b to c'. The density is 1 / area, with
// the area given by spherical_triangle_area, which the caller passes in.
// Returns false for a degenerate triangle. near_plane: the point is close to
// the triangle's plane (the corners almost on one great circle), where the
// construction needs double precision: in float it lost 11% of the light
// 1e-5 of a quad light's size away; elsewhere float is as exact and faster.
bool sample_spherical_triangle(const vec3& a, const vec3& b, const vec3& c, float area, vec2 u, vec3* w,
                               bool near_plane = true);

// acos(c) for c in [-1, 1] (clamped), in float: Abramowitz and Stegun
// 4.4.45, acos x = sqrt(1 - x) (a0 + a1 x + ... + a7 x^7) on [0, 1] with
// |error| <= 2e-8, and pi - acos(-x) below 0: within 4e-7 of the exact
// value after float rounding (test LightSampling.AcosPolyIsAcos), where
// glibc's acosf is within 1.2e-7 but is a call the compiler cannot inline:
// the spherical rectangle's four angles through it took 4% of
// modern_hall.blend's render.
inline float acos_poly(float c) {
  const float x = std::min(std::abs(c), 1.0f);
  float p = -0.0012624911f;
  p = p * x + 0.0066700901f;
  p = p * x - 0.0170881256f;
  p = p * x + 0.0308918810f;
  p = p * x - 0.0501743046f;
  p = p * x + 0.0889789874f;
  p = p * x - 0.2145988016f;
  p = p * x + 1.5707963050f;
  const float a = std::sqrt(1.0f - x) * p;
  return c < 0.0f ? 3.14159265358979f - a : a;
}

// A rectangle seen from a point, for directions uniform in the solid angle
// it subtends (Urena, Fajardo and King 2013, "An area-preserving
// parametrization for spherical rectangles"; Cycles samples rectangular area
// lights this way). The rectangle is corner + [0,1] ex + [0,1] ey, ex and
// ey orthogonal. Real: float, or double where o is close to the
// rectangle's plane (SphericalRectangle chooses).
template <typename Real>
struct SphericalRectangleT {
  using V = glm::vec<3, Real>;
  // Sets it up from o; false when o lies in the rectangle's plane (or the
  // rectangle is degenerate), where there is no solid angle to sample.
  bool init(const vec3& o, const vec3& corner, const vec3& ex, const vec3& ey);
  float solid_angle() const { return float(S); }
  // The point of the rectangle in the direction given by u (density 1 / S
  // in solid angle from o), less o: without the rounding of adding o and
  // taking it off again (far from the world origin o is large).
  vec3 sample_offset(vec2 u) const;
  // The u that sample_offset takes to the point o + offset of the
  // rectangle (offset: any vector from o towards it): u.x the solid angle
  // of the sub-rectangle [x0, xu] over S, u.y where the height lies between
  // the column's ends. For the density of a warped u (SphericalRectangle).
  vec2 invert(const vec3& offset) const;

  V x, y, z;               // local frame: x, y along the edges, z towards the rectangle's plane
  Real z0, x0, x1, y0, y1; // the rectangle in that frame (z0 <= 0)
  Real b0, b1, q, k, S;  // q = 1 - b0^2
};

// The construction in float where that is exact enough, else in double:
// where o is within 1% of its reach from the rectangle's plane, seen at
// grazing angles, the sample's 1 - cu^2 cancels (in float, a point 1e-5 from
// the plane of a 1 x 0.5 light and 0.02 beside it was sent twice its
// irradiance). The same rule as for spherical triangles. height: o's
// distance from the rectangle's plane; reach: o's distance from its middle
// plus half its diagonal (both of which the callers have at hand).
//
// With a receiver's normal (warp_by_cosine), the directions follow its
// |cos| as well: u is first drawn by the bilinear density whose corners
// are the |cos| towards the rectangle's corners (Hart et al. 2020,
// "Practical product sampling by fitting and composing warps"; pbrt-v4
// warps its spherical triangles and bilinear patches alike), so that a
// light beside a receiver sends fewer samples where it is seen at a grazing
// angle. The direction's density is then density / solid_angle().
class SphericalRectangle {
 public:
  bool init(const vec3& o, const vec3& corner, const vec3& ex, const vec3& ey, float height, float reach);
  float solid_angle() const { return near_plane_ ? d_.solid_angle() : f_.solid_angle(); }
  vec3 sample(vec2 u) const { return o_ + sample_offset(u); }
  vec3 sample_offset(vec2 u) const { return near_plane_ ? d_.sample_offset(u) : f_.sample_offset(u); }

  // Sets up the warp for a receiver with (unit) normal n, unless the
  // corners' bilinear fit misses the cosine: where the cosine at an edge's
  // middle, the centre or the point nearest the normal is over kWarpFit
  // times the fit there (a wall beside a ceiling panel, turned to it, sees
  // its largest cosine at the middle of the panel's near edge and next to
  // none at the corners), warped samples there would weigh more than
  // uniform ones, and the rectangle is sampled uniformly. Nor where the
  // warp would buy little for its cost: the rectangle under
  // kMinWarpSolidAngle, or its corners' cosines nearly even. Returns
  // whether it warps. (On modern_hall.blend, 120 px, 64 spp, two sets of 8
  // seeds: variance -2.6% / -2.1%, core time +1.6%; without the guard -2.7%
  // / -2.3%, with kWarpFit 2 -2.1% / -1.6%. Beside a light, tests
  // LightSampling.CosineWarped*: 0.11-0.35x the variance.)
  bool warp_by_cosine(const vec3& n);
  // sample_offset() after the warp; *density: the warp's density at u (1 unwarped).
  vec3 sample_offset(vec2 u, float* density) const;
  // The warp's density for the point o + offset of the rectangle (1 unwarped).
  float density(const vec3& offset) const;

  static constexpr float kMinWarpCosine = 0.01f;  // a corner's least weight (pbrt-v4's)
  static constexpr float kWarpFit = 3.0f;
  static constexpr float kMinWarpSolidAngle = 0.1f;  // sr
  static constexpr float kEvenCorners = 1.25f;  // no warp when the corners' largest is below this x their least

 private:
  vec3 o_;
  bool near_plane_ = false;
  bool warped_ = false;
  float w_[4];  // the bilinear warp's corner weights, u (0,0), (1,0), (0,1), (1,1)
  SphericalRectangleT<float> f_;
  SphericalRectangleT<double> d_;
};

// A density on [0,1] linear from a at 0 to b at 1 (a, b >= 0, not both 0):
// p(x) = 2 ((1 - x) a + x b) / (a + b). Its inverse CDF, the root of
// (b - a) x^2 + 2 a x = u (a + b) in [0,1] written without the cancellation
// of (sqrt(...) - a) / (b - a): x = u (a + b) / (a + sqrt((1 - u) a^2 + u b^2)).
inline float sample_linear(float u, float a, float b) {
  const float den = a + std::sqrt((1.0f - u) * a * a + u * b * b);
  return den > 0.0f ? std::min(u * (a + b) / den, 0x1.fffffep-1f) : u;
}

// A density on [0,1]^2 bilinear in the corner values w[0] at (0,0), w[1] at
// (1,0), w[2] at (0,1), w[3] at (1,1): 4 bilerp(w, p) / sum(w). Sampled as
// y by its marginal (linear from w0 + w1 to w2 + w3), then x given y (linear
// from lerp(w0, w2, y) to lerp(w1, w3, y)).
inline vec2 sample_bilinear(vec2 u, const float w[4]) {
  const float y = sample_linear(u.y, w[0] + w[1], w[2] + w[3]);
  return vec2(sample_linear(u.x, w[0] + y * (w[2] - w[0]), w[1] + y * (w[3] - w[1])), y);
}
inline float bilinear_pdf(vec2 p, const float w[4]) {
  const float sum = w[0] + w[1] + w[2] + w[3];
  if (!(sum > 0.0f)) return 1.0f;
  return 4.0f * ((1.0f - p.x) * (1.0f - p.y) * w[0] + p.x * (1.0f - p.y) * w[1] + (1.0f - p.x) * p.y * w[2] +
                 p.x * p.y * w[3]) / sum;
}

inline float power_heuristic(float f_pdf, float g_pdf) {
  float f = f_pdf * f_pdf, g = g_pdf * g_pdf;
  if (std::isinf(f)) return 1.0f;
  return f + g > 0.0f ? f / (f + g) : 0.0f;
}

// Discrete distribution by the alias method (Walker 1977; Vose 1991):
// O(1) sampling from one uniform number.
class AliasTable {
 public:
  AliasTable() = default;
  explicit AliasTable(const std::vector<float>& weights);
  bool empty() const { return bins_.empty(); }
  size_t size() const { return bins_.size(); }
  // Returns an index; pmf receives its probability and u_remapped, if
  // given, a number uniform in [0,1) again given that index (what is left of
  // u's bits after the choice), for a next discrete choice.
  uint32_t sample(float u, float* pmf, float* u_remapped = nullptr) const {
    float x = u * bins_.size();
    uint32_t i = std::min(uint32_t(x), uint32_t(bins_.size() - 1));
    float frac = x - i;
    const bool keep = frac < bins_[i].q;
    uint32_t k = keep ? i : bins_[i].alias;
    *pmf = bins_[k].p;
    if (u_remapped) {
      const float q = bins_[i].q;
      *u_remapped = std::min(keep ? frac / q : (frac - q) / (1.0f - q), 0x1.fffffep-1f);
    }
    return k;
  }
  float pmf(uint32_t i) const { return bins_[i].p; }

 private:
  struct Bin {
    float q;         // probability of keeping i
    float p;         // normalized weight of i
    uint32_t alias;  // taken otherwise
  };
  std::vector<Bin> bins_;
};

// Piecewise-constant 1D distribution with a CDF, sampled continuously
// (pbrt-v4 A.4.2). Used for the environment map and the pixel filter.
struct Distribution1D {
  std::vector<float> func, cdf;
  // guide[k]: the segment holding u = k / n, where the search for u in
  // [k/n, (k+1)/n) starts (a guide table, Chen and Asau 1974): O(1) expected
  // steps instead of a binary search over the whole CDF.
  std::vector<uint32_t> guide;
  float integral = 0.0f;
  Distribution1D() = default;
  explicit Distribution1D(const float* f, size_t n);
  size_t size() const { return func.size(); }
  // Continuous sample in [0,1); pdf is the density w.r.t. that domain; offset the segment.
  float sample_continuous(float u, float* pdf, size_t* offset) const;
};

}  // namespace tessera
