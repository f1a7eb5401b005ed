#include "sampling.h"

namespace tessera {

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

Distribution1D::Distribution1D(const float* f, size_t n) : func(f, f + n), cdf(n + 1) {
  cdf[0] = 0.0f;
  for (size_t i = 0; i < n; ++i) cdf[i + 1] = cdf[i] + std::max(0.0f, func[i]) / n;
  integral = cdf[n];
  if (integral <= 0.0f) {
    for (size_t i = 0; i <= n; ++i) cdf[i] = float(i) / n;
  } else {
    for (size_t i = 0; i <= n; ++i) cdf[i] /= integral;
  }
}

float Distribution1D::sample_continuous(float u, float* pdf, size_t* offset) const {
  size_t lo = std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin();
  size_t o = std::min(lo == 0 ? 0 : lo - 1, func.size() - 1);
  *offset = o;
  float du = u - cdf[o];
  float width = cdf[o + 1] - cdf[o];
  if (width > 0.0f) du /= width;
  *pdf = integral > 0.0f ? std::max(0.0f, func[o]) / integral : 1.0f;
  return (o + du) / size();
}

}  // namespace tessera
