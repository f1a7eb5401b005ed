#include "sampling.h"

#include <type_traits>

namespace tessera {

namespace {
template <typename Real>
bool sample_spherical_triangle_in(const vec3& a_, const vec3& b_, const vec3& c_, float area, vec2 u, vec3* w) {
  using dvec3 = glm::vec<3, Real>;
  if (!(area > 0.0f)) return false;
  // The corners are unit vectors in float; in double they are normalised
  // again, to double's precision.
  dvec3 a(a_), b(b_), c(c_);
  if constexpr (std::is_same_v<Real, double>) a = glm::normalize(a), b = glm::normalize(b), c = glm::normalize(c);
  // Normals of the great circles through a and b, and through c and a
  // (unnormalised: the angle between them needs only the product of their
  // lengths, one division).
  const dvec3 n_ab = glm::cross(a, b), n_ca = glm::cross(c, a);
  const Real l = glm::length(n_ab) * glm::length(n_ca);
  if (!(l > Real(0))) return false;
  const Real inv_l = Real(1) / l;
  // The interior angle alpha at a, between those circles, as its cosine and
  // sine (the sine from the cross product stays accurate for thin corners,
  // where acos of the dot product would not).
  const Real cos_alpha = std::clamp(-glm::dot(n_ab, n_ca) * inv_l, Real(-1), Real(1));
  const Real sin_alpha = glm::length(glm::cross(n_ab, n_ca)) * inv_l;
  if (!(sin_alpha > Real(0))) return false;
  // Sub-triangle (a, b, c') of area A' = u.x * area: Arvo's closed form for
  // the cosine of the arc from a to c' (pbrt-v4 A.5.5 with phi = A' + pi -
  // alpha, its sine and cosine expanded so that only A' needs a sincos).
  const Real a_sub = Real(u.x) * Real(area);
  const Real sin_a = std::sin(a_sub), cos_a = std::cos(a_sub);
  const Real sin_phi = cos_a * sin_alpha - sin_a * cos_alpha;
  const Real cos_phi = -cos_a * cos_alpha - sin_a * sin_alpha;
  const Real k1 = cos_phi + cos_alpha;
  const Real k2 = sin_phi - sin_alpha * glm::dot(a, b);
  Real cos_bp = (k2 + (k2 * cos_phi - k1 * sin_phi) * cos_alpha) / ((k2 * sin_phi + k1 * cos_phi) * sin_alpha);
  cos_bp = std::clamp(std::isfinite(cos_bp) ? cos_bp : Real(1), Real(-1), Real(1));
  const dvec3 c_perp = c - glm::dot(c, a) * a;
  if (!(glm::dot(c_perp, c_perp) > Real(0))) return false;
  const dvec3 cp = cos_bp * a + std::sqrt(std::max(Real(0), Real(1) - cos_bp * cos_bp)) * glm::normalize(c_perp);
  // Uniform in solid angle along the arc from b to c'.
  const Real cos_theta = Real(1) - u.y * (Real(1) - glm::dot(cp, b));
  const Real sin_theta = std::sqrt(std::max(Real(0), Real(1) - cos_theta * cos_theta));
  const dvec3 bp = cp - glm::dot(cp, b) * b;
  const dvec3 wd = glm::dot(bp, bp) > Real(0) ? cos_theta * b + sin_theta * glm::normalize(bp) : b;
  *w = vec3(wd);
  return is_finite(*w);
}

}  // namespace

bool sample_spherical_triangle(const vec3& a, const vec3& b, const vec3& c, float area, vec2 u, vec3* w,
                               bool near_plane) {
  return near_plane ? sample_spherical_triangle_in<double>(a, b, c, area, u, w)
                    : sample_spherical_triangle_in<float>(a, b, c, area, u, w);
}

namespace {
// An angle from its cosine: acos_poly in float, std::acos in double.
template <typename Real>
Real angle_of(Real c) {
  if constexpr (std::is_same_v<Real, float>) {
    return acos_poly(c);
  } else {
    return std::acos(std::clamp(c, Real(-1), Real(1)));
  }
}
}  // namespace

template <typename Real>
bool SphericalRectangleT<Real>::init(const vec3& o, const vec3& corner, const vec3& ex_, const vec3& ey_) {
  const V ex(ex_), ey(ey_);
  const Real exl = glm::length(ex), eyl = glm::length(ey);
  if (!(exl > 0 && eyl > 0)) return false;
  x = ex / exl, y = ey / eyl, z = glm::cross(x, y);
  const V d = V(corner) - V(o);
  z0 = glm::dot(d, z);
  if (z0 > 0) z = -z, z0 = -z0;  // the frame's z points away from the rectangle
  if (!(z0 < 0)) return false;
  x0 = glm::dot(d, x), y0 = glm::dot(d, y);
  x1 = x0 + exl, y1 = y0 + eyl;
  // Normals of the planes through o and each edge, n0 (0, z0, -y0) / l0,
  // n1 (-z0, 0, x1) / l1, n2 (0, -z0, y1) / l2, n3 (z0, 0, -x0) / l3 (the
  // paper's closed forms of the cross products of neighbouring corners); the
  // interior angles of the spherical quad are the angles between
  // neighbouring ones, g_i = acos(-n_i . n_i+1).
  const Real z2 = z0 * z0;
  const Real l0 = std::sqrt(z2 + y0 * y0), l1 = std::sqrt(z2 + x1 * x1);
  const Real l2 = std::sqrt(z2 + y1 * y1), l3 = std::sqrt(z2 + x0 * x0);
  const Real g0 = angle_of(x1 * y0 / (l0 * l1)), g1 = angle_of(-x1 * y1 / (l1 * l2));
  const Real g2 = angle_of(x0 * y1 / (l2 * l3)), g3 = angle_of(-x0 * y0 / (l3 * l0));
  b0 = -y0 / l0, b1 = y1 / l2;
  q = z2 / (l0 * l0);  // 1 - b0^2, without its cancellation
  k = Real(2) * Real(M_PI) - g2 - g3;
  S = g0 + g1 - k;  // the angle excess: the solid angle
  return S > 0 && std::isfinite(S) && std::isfinite(float(S));
}

template <typename Real>
vec3 SphericalRectangleT<Real>::sample_offset(vec2 u) const {
  // u.x: the sub-rectangle [x0, xu] of solid angle u.x S, solved for xu. The
  // paper's fu = (cos au b0 - b1) / sin au, cu = sign(fu) / sqrt(fu^2 + b0^2),
  // xu = -cu z0 / sqrt(1 - cu^2) folded into one square root and one
  // division, with 1 - b0^2 = (z0 / l0)^2 = q (init): xu = -z0 sign(m) sin au /
  // sqrt(m^2 - q sin^2 au), m = cos au b0 - b1. The same cancellation where
  // |cu| is near 1 as 1 - cu^2 had, on a chain of two long operations
  // instead of five.
  const Real au = Real(u.x) * S + k;
  const Real sin_au = std::sin(au), cos_au = std::cos(au);
  const Real m = cos_au * b0 - b1;
  Real xu = -(z0 * sin_au) * std::copysign(Real(1), m) / std::sqrt(std::max(Real(0), m * m - q * sin_au * sin_au));
  xu = std::clamp(std::isfinite(xu) ? xu : x1, x0, x1);
  // u.y: uniform in the height h (cosine to the y axis) along that column,
  // yv = hv dd / sqrt(1 - hv^2) with dd^2 = xu^2 + z0^2.
  const Real dd2 = xu * xu + z0 * z0;
  const Real h0 = y0 / std::sqrt(dd2 + y0 * y0), h1 = y1 / std::sqrt(dd2 + y1 * y1);
  const Real hv = h0 + Real(u.y) * (h1 - h0), hv2 = hv * hv;
  const Real yv = hv2 < Real(1) - Real(1e-6) ? hv * std::sqrt(dd2 / (Real(1) - hv2)) : y1;
  return vec3(xu * x + std::clamp(yv, y0, y1) * y + z0 * z);
}

template <typename Real>
vec2 SphericalRectangleT<Real>::invert(const vec3& offset_) const {
  // The point in the rectangle's plane z = z0 along the offset.
  const V w(offset_);
  const Real wz = glm::dot(w, z);
  if (!(wz < 0)) return vec2(0.5f);
  const Real s = z0 / wz;
  const Real xu = std::clamp(s * glm::dot(w, x), x0, x1), yv = std::clamp(s * glm::dot(w, y), y0, y1);
  // The sub-rectangle [x0, xu] x [y0, y1]: init's angle excess with x1
  // replaced by xu (g2, g3 and so k do not depend on x1).
  const Real z2 = z0 * z0;
  const Real l0 = std::sqrt(z2 + y0 * y0), lu = std::sqrt(z2 + xu * xu), l2 = std::sqrt(z2 + y1 * y1);
  const Real s_u = angle_of(xu * y0 / (l0 * lu)) + angle_of(-xu * y1 / (lu * l2)) - k;
  // The height's place between the column's ends (sample_offset's hv).
  const Real dd2 = xu * xu + z2;
  const Real h0 = y0 / std::sqrt(dd2 + y0 * y0), h1 = y1 / std::sqrt(dd2 + y1 * y1);
  const Real hv = yv / std::sqrt(dd2 + yv * yv);
  const Real v = h1 > h0 ? (hv - h0) / (h1 - h0) : Real(0.5);
  return vec2(float(std::clamp(s_u / S, Real(0), Real(1))), float(std::clamp(v, Real(0), Real(1))));
}

template struct SphericalRectangleT<float>;
template struct SphericalRectangleT<double>;

bool SphericalRectangle::init(const vec3& o, const vec3& corner, const vec3& ex, const vec3& ey, float height,
                              float reach) {
  o_ = o;
  near_plane_ = std::abs(height) < 0.01f * reach;
  warped_ = false;
  return near_plane_ ? d_.init(o, corner, ex, ey) : f_.init(o, corner, ex, ey);
}

namespace {
// The corner weights of the cosine warp (u order (0,0), (1,0), (0,1),
// (1,1)), and whether their bilinear fit holds (SphericalRectangle::
// warp_by_cosine). The fit is checked where the cosine peaks: at the
// middles of the edges, the centre, and the point of the rectangle nearest
// the receiver's normal (where the normal meets its plane, clamped to it;
// with no such point, the edge it leans towards). Against the fit there
// taken bilinear in the plane's coordinates, close enough to u's for a
// bound on a ratio.
template <typename Real>
bool cosine_warp_weights(const SphericalRectangleT<Real>& r, const vec3& n_, float w[4]) {
  // In the rectangle's orthonormal frame the point (xu, yv) is the offset
  // (xu, yv, z0): its cosine to n is |xu nx + yv ny + z0 nz| / sqrt(xu^2 +
  // yv^2 + z0^2), a few multiplications a point.
  const glm::vec<3, Real> n(n_);
  const float nx = float(glm::dot(n, r.x)), ny = float(glm::dot(n, r.y)), nz = float(glm::dot(n, r.z));
  const float x0 = float(r.x0), x1 = float(r.x1), y0 = float(r.y0), y1 = float(r.y1), z0 = float(r.z0);
  const float xm = 0.5f * (x0 + x1), ym = 0.5f * (y0 + y1);
  // The normal's point (nz < 0: n meets the plane z = z0 at t = z0 / nz).
  const float t = nz < 0.0f ? z0 / nz : 1e30f;
  const float xf = std::clamp(t * nx, x0, x1), yf = std::clamp(t * ny, y0, y1);
  // The four corners (u order), the middles of the edges, the centre, the normal's point.
  constexpr int kPoints = 10;
  const float px[kPoints] = {x0, x1, x0, x1, xm, xm, x0, x1, xm, xf};
  const float py[kPoints] = {y0, y0, y1, y1, y0, y1, ym, ym, ym, yf};
  const auto cosine = [&](int i) {
    return std::abs(px[i] * nx + py[i] * ny + z0 * nz) / std::sqrt(px[i] * px[i] + py[i] * py[i] + z0 * z0);
  };
  for (int i = 0; i < 4; ++i) w[i] = std::max(cosine(i), SphericalRectangle::kMinWarpCosine);
  // Nearly even corners: a warp nearly uniform, not worth its cost.
  if (std::max(std::max(w[0], w[1]), std::max(w[2], w[3])) <
      SphericalRectangle::kEvenCorners * std::min(std::min(w[0], w[1]), std::min(w[2], w[3])))
    return false;
  const float inv_dx = 1.0f / (x1 - x0), inv_dy = 1.0f / (y1 - y0);
  bool fits = true;
  for (int i = 4; i < kPoints; ++i) {
    const float fx = (px[i] - x0) * inv_dx, fy = (py[i] - y0) * inv_dy;
    const float fit = (1.0f - fy) * ((1.0f - fx) * w[0] + fx * w[1]) + fy * ((1.0f - fx) * w[2] + fx * w[3]);
    fits = fits && cosine(i) <= SphericalRectangle::kWarpFit * fit;
  }
  return fits;
}
}  // namespace

bool SphericalRectangle::warp_by_cosine(const vec3& n) {
  warped_ = solid_angle() >= kMinWarpSolidAngle &&
            (near_plane_ ? cosine_warp_weights(d_, n, w_) : cosine_warp_weights(f_, n, w_));
  return warped_;
}

vec3 SphericalRectangle::sample_offset(vec2 u, float* density) const {
  if (!warped_) {
    *density = 1.0f;
    return sample_offset(u);
  }
  const vec2 uw = sample_bilinear(u, w_);
  *density = bilinear_pdf(uw, w_);
  return sample_offset(uw);
}

float SphericalRectangle::density(const vec3& offset) const {
  if (!warped_) return 1.0f;
  return bilinear_pdf(near_plane_ ? d_.invert(offset) : f_.invert(offset), w_);
}

AliasTable::AliasTable(const std::vector<float>& weights) {
  const size_t n = weights.size();
  if (n == 0) return;
  double total = 0.0;
  for (float w : weights) total += std::max(0.0f, w);
  bins_.resize(n);
  if (!(total > 0.0)) {
    for (size_t i = 0; i < n; ++i) bins_[i] = {1.0f, 1.0f / n, uint32_t(i)};
    return;
  }
  std::vector<double> scaled(n);
  std::vector<uint32_t> small, large;
  for (size_t i = 0; i < n; ++i) {
    bins_[i].p = float(std::max(0.0f, weights[i]) / total);
    scaled[i] = std::max(0.0f, weights[i]) / total * n;
    (scaled[i] < 1.0 ? small : large).push_back(uint32_t(i));
  }
  while (!small.empty() && !large.empty()) {
    uint32_t s = small.back(), l = large.back();
    small.pop_back();
    bins_[s].q = float(scaled[s]);
    bins_[s].alias = l;
    scaled[l] -= 1.0 - scaled[s];
    if (scaled[l] < 1.0) {
      large.pop_back();
      small.push_back(l);
    }
  }
  for (uint32_t i : large) bins_[i].q = 1.0f, bins_[i].alias = i;
  for (uint32_t i : small) bins_[i].q = 1.0f, bins_[i].alias = i;
}

Distribution1D::Distribution1D(const float* f, size_t n) : func(f, f + n), cdf(n + 1), guide(n) {
  cdf[0] = 0.0f;
  for (size_t i = 0; i < n; ++i) cdf[i + 1] = cdf[i] + std::max(0.0f, func[i]) / n;
  integral = cdf[n];
  if (integral <= 0.0f) {
    for (size_t i = 0; i <= n; ++i) cdf[i] = float(i) / n;
  } else {
    for (size_t i = 0; i <= n; ++i) cdf[i] /= integral;
  }
  cdf[n] = 1.0f;
  // The last segment whose start is <= k / n.
  for (size_t k = 0, i = 0; k < n; ++k) {
    const float u = float(k) / float(n);
    while (i + 1 < n && cdf[i + 1] <= u) ++i;
    guide[k] = uint32_t(i);
  }
}

float Distribution1D::sample_continuous(float u, float* pdf, size_t* offset) const {
  const size_t n = func.size();
  // The segment o with cdf[o] <= u < cdf[o + 1] (the last one for u >= 1),
  // skipping empty segments as the binary search upper_bound did.
  size_t o = guide[std::min(size_t(u * float(n)), n - 1)];
  while (o > 0 && cdf[o] > u) --o;  // u * n rounded up into the next bucket
  while (o + 1 < n && cdf[o + 1] <= u) ++o;
  *offset = o;
  float du = u - cdf[o];
  float width = cdf[o + 1] - cdf[o];
  if (width > 0.0f) du /= width;
  *pdf = integral > 0.0f ? std::max(0.0f, func[o]) / integral : 1.0f;
  return (o + du) / size();
}

}  // namespace tessera
