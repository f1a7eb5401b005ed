#include "background.h"

namespace tessera {

// Blender's equirectangular mapping (Cycles direction_to_equirectangular):
// u = -atan2(y, x) / 2pi + 1/2, v = atan2(z, hypot(x, y)) / pi + 1/2.
// sin_theta: the direction's distance from the texture's pole axis, the
// sin of its polar angle (its length is 1).
vec2 Background::direction_to_uv(const vec3& world_dir, float* sin_theta) const {
  vec3 d = rotation_ * world_dir;
  *sin_theta = std::sqrt(d.x * d.x + d.y * d.y);
  float u = -atan2_poly(d.y, d.x) / (2.0f * kPi) + 0.5f;
  float v = atan2_poly(d.z, *sin_theta) / kPi + 0.5f;
  return vec2(u, v);
}

// The polar angle from +z is theta = pi (1 - v) and the azimuth phi = pi (1 -
// 2u): (cos phi, sin phi) = (-cos 2 pi u, sin 2 pi u), (cos theta, sin theta)
// = (-cos pi v, sin pi v), with pi v = 2 pi (v / 2).
vec3 Background::uv_to_direction(vec2 uv, float* sin_theta) const {
  const vec2 cs_u = cos_sin_2pi(uv.x), cs_v = cos_sin_2pi(0.5f * uv.y);
  *sin_theta = cs_v.y;
  vec3 d(-cs_v.y * cs_u.x, cs_v.y * cs_u.y, -cs_v.x);
  return glm::transpose(rotation_) * d;
}

// Bilinear lookup, wrapping in u and clamping in v (Blender's Linear
// interpolation). u is in [0,1], so a column wraps by one step at most.
vec3 Background::lookup(vec2 uv) const {
  const float x = uv.x * width_ - 0.5f, y = uv.y * height_ - 0.5f;
  const float fx = std::floor(x), fy = std::floor(y);
  const float tx = x - fx, ty = y - fy;
  int x0 = int(fx);
  x0 = x0 < 0 ? x0 + width_ : x0 >= width_ ? x0 - width_ : x0;
  if (!(x0 >= 0 && x0 < width_)) x0 = 0;  // NaN directions
  const int x1 = x0 + 1 == width_ ? 0 : x0 + 1;
  const int iy = int(fy);
  const vec3* r0 = &pixels_[size_t(std::clamp(iy, 0, height_ - 1)) * width_];
  const vec3* r1 = &pixels_[size_t(std::clamp(iy + 1, 0, height_ - 1)) * width_];
  return (1 - ty) * ((1 - tx) * r0[x0] + tx * r0[x1]) + ty * ((1 - tx) * r1[x0] + tx * r1[x1]);
}

void Background::set_image(std::vector<vec3> pixels, int width, int height, const glm::mat3& rotation,
                           const vec3& strength) {
  pixels_ = std::move(pixels);
  width_ = width;
  height_ = height;
  rotation_ = rotation;
  strength_ = strength;
  has_image_ = width > 0 && height > 0 && pixels_.size() == size_t(width) * height;
  if (!has_image_) return;
  // Texel weights: the mean of the bilinear reconstruction (lookup) over
  // each texel's cell, which is the separable filter [1/8, 3/4, 1/8] over
  // the texel and its neighbours (columns wrap, rows clamp), times sin(theta)
  // for the sphere's area. Weights from the texels alone gave zero density
  // next to a small bright sun that the bilinear lookup spreads into its
  // neighbours: its light there was found only by BSDF sampling.
  std::vector<float> lum(size_t(width) * height), across(size_t(width) * height);
  for (size_t i = 0; i < lum.size(); ++i) lum[i] = is_finite(pixels_[i]) ? std::max(0.0f, luminance(pixels_[i])) : 0.0f;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const float* row = &lum[size_t(y) * width];
      const int xl = x == 0 ? width - 1 : x - 1, xr = x + 1 == width ? 0 : x + 1;
      across[size_t(y) * width + x] = 0.125f * row[xl] + 0.75f * row[x] + 0.125f * row[xr];
    }
  std::vector<float> row_weights(height);
  std::vector<float> f(width);
  conditional_.clear();
  conditional_.reserve(height);
  for (int y = 0; y < height; ++y) {
    const float sin_theta = std::sin(kPi * (y + 0.5f) / height);
    const float* below = &across[size_t(std::max(y - 1, 0)) * width];
    const float* here = &across[size_t(y) * width];
    const float* above = &across[size_t(std::min(y + 1, height - 1)) * width];
    for (int x = 0; x < width; ++x) f[x] = (0.125f * below[x] + 0.75f * here[x] + 0.125f * above[x]) * sin_theta;
    conditional_.emplace_back(f.data(), width);
    row_weights[y] = conditional_.back().integral;
  }
  marginal_ = Distribution1D(row_weights.data(), height);
}

vec3 Background::Le(const vec3& dir, float* pdf) const {
  if (!has_image_) {
    if (pdf) *pdf = kUniformSpherePdf;
    return color_;
  }
  float sin_theta;
  const vec2 uv = direction_to_uv(dir, &sin_theta);
  if (pdf) *pdf = pdf_uv(uv, sin_theta);
  return strength_ * lookup(uv);
}

bool Background::sample(vec2 u, vec3* wi, float* pdf, vec3* le) const {
  if (!has_image_) {
    *wi = sample_uniform_sphere(u);
    *pdf = kUniformSpherePdf;
    if (le) *le = color_;
    return true;
  }
  float pdf_v, pdf_u;
  size_t row, col;
  float v = marginal_.sample_continuous(u.y, &pdf_v, &row);
  float uu = conditional_[row].sample_continuous(u.x, &pdf_u, &col);
  float sin_theta;
  *wi = uv_to_direction(vec2(uu, v), &sin_theta);
  if (sin_theta <= 0.0f || pdf_u * pdf_v <= 0.0f) return false;
  *pdf = pdf_u * pdf_v / (2.0f * kPi * kPi * sin_theta);
  if (le) *le = strength_ * lookup(vec2(uu, v));
  return true;
}

// The density of sample() at texture coordinates uv, per unit solid angle:
// the piecewise-constant density in (u, v) over the Jacobian 2 pi^2 sin(theta).
float Background::pdf_uv(vec2 uv, float sin_theta) const {
  if (sin_theta <= 0.0f || marginal_.integral <= 0.0f) return 0.0f;
  int col = std::clamp(int(uv.x * width_), 0, width_ - 1);
  int row = std::clamp(int(uv.y * height_), 0, height_ - 1);
  float p = conditional_[row].func[col] / marginal_.integral;
  return p / (2.0f * kPi * kPi * sin_theta);
}

float Background::pdf(const vec3& wi) const {
  if (!has_image_) return kUniformSpherePdf;
  float sin_theta;
  const vec2 uv = direction_to_uv(wi, &sin_theta);
  return pdf_uv(uv, sin_theta);
}

float Background::average_luminance() const {
  if (!has_image_) return luminance(color_);
  // The marginal integral is the sin-weighted mean; sin averages to 2/pi.
  return luminance(strength_) * marginal_.integral / (2.0f / kPi);
}

}  // namespace tessera
