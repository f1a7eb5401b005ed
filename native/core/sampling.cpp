#include "sampling.h"

namespace tessera {

bool sample_spherical_triangle(const vec3& a_, const vec3& b_, const vec3& c_, float area, vec2 u, vec3* w) {
  using dvec3 = glm::dvec3;
  // In double: for a point almost in the triangle's plane the corners are
  // almost on one great circle, and in float the construction falls apart
  // (light lost next to a quad light 1e-5 of its size away).
  if (!(area > 0.0f)) return false;
  const dvec3 a = glm::normalize(dvec3(a_)), b = glm::normalize(dvec3(b_)), c = glm::normalize(dvec3(c_));
  // Normals of the great circles through a and b, and through c and a.
  dvec3 n_ab = glm::cross(a, b), n_ca = glm::cross(c, a);
  const double l_ab = glm::length(n_ab), l_ca = glm::length(n_ca);
  if (!(l_ab > 0.0 && l_ca > 0.0)) return false;
  n_ab /= l_ab, n_ca /= l_ca;
  // The interior angle alpha at a, between those circles, as its cosine and
  // sine (the sine from the cross product stays accurate for thin corners,
  // where acos of the dot product would not).
  const double cos_alpha = std::clamp(-glm::dot(n_ab, n_ca), -1.0, 1.0);
  const double sin_alpha = glm::length(glm::cross(n_ab, n_ca));
  if (!(sin_alpha > 0.0)) return false;
  // Sub-triangle (a, b, c') of area A' = u.x * area: Arvo's closed form for
  // the cosine of the arc from a to c' (pbrt-v4 A.5.5 with phi = A' + pi -
  // alpha, its sine and cosine expanded so that only A' needs a sincos).
  const double a_sub = double(u.x) * double(area);
  const double sin_a = std::sin(a_sub), cos_a = std::cos(a_sub);
  const double sin_phi = cos_a * sin_alpha - sin_a * cos_alpha;
  const double cos_phi = -cos_a * cos_alpha - sin_a * sin_alpha;
  const double k1 = cos_phi + cos_alpha;
  const double k2 = sin_phi - sin_alpha * glm::dot(a, b);
  double cos_bp = (k2 + (k2 * cos_phi - k1 * sin_phi) * cos_alpha) / ((k2 * sin_phi + k1 * cos_phi) * sin_alpha);
  cos_bp = std::clamp(std::isfinite(cos_bp) ? cos_bp : 1.0, -1.0, 1.0);
  const dvec3 c_perp = c - glm::dot(c, a) * a;
  if (!(glm::dot(c_perp, c_perp) > 0.0)) return false;
  const dvec3 cp = cos_bp * a + std::sqrt(std::max(0.0, 1.0 - cos_bp * cos_bp)) * glm::normalize(c_perp);
  // Uniform in solid angle along the arc from b to c'.
  const double cos_theta = 1.0 - u.y * (1.0 - glm::dot(cp, b));
  const double sin_theta = std::sqrt(std::max(0.0, 1.0 - cos_theta * cos_theta));
  const dvec3 bp = cp - glm::dot(cp, b) * b;
  const dvec3 wd = glm::dot(bp, bp) > 0.0 ? cos_theta * b + sin_theta * glm::normalize(bp) : b;
  *w = vec3(wd);
  return is_finite(*w);
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
