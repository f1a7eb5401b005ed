#include "background.h"

namespace tessera {

// Blender's equirectangular mapping (Cycles direction_to_equirectangular):
// u = -atan2(y, x) / 2pi + 1/2, v = atan2(z, hypot(x, y)) / pi + 1/2.
vec2 Background::direction_to_uv(const vec3& world_dir) const {
  vec3 d = rotation_ * world_dir;
  float u = -std::atan2(d.y, d.x) / (2.0f * kPi) + 0.5f;
  float v = std::atan2(d.z, std::hypot(d.x, d.y)) / kPi + 0.5f;
  return vec2(u, v);
}

vec3 Background::uv_to_direction(vec2 uv) const {
  float phi = kPi * (1.0f - 2.0f * uv.x);
  float theta = kPi * (1.0f - uv.y);  // polar angle from +z
  vec3 d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
  return glm::transpose(rotation_) * d;
}

// Bilinear lookup, wrapping in u and clamping in v (Blender's Linear interpolation).
vec3 Background::lookup(vec2 uv) const {
  float x = uv.x * width_ - 0.5f, y = uv.y * height_ - 0.5f;
  float fx = std::floor(x), fy = std::floor(y);
  float tx = x - fx, ty = y - fy;
  auto px = [&](int ix, int iy) {
    ix = ((ix % width_) + width_) % width_;
    iy = std::clamp(iy, 0, height_ - 1);
    return pixels_[size_t(iy) * width_ + ix];
  };
  int ix = int(fx), iy = int(fy);
  return (1 - ty) * ((1 - tx) * px(ix, iy) + tx * px(ix + 1, iy)) + ty * ((1 - tx) * px(ix, iy + 1) + tx * px(ix + 1, iy + 1));
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
  std::vector<float> row_weights(height);
  std::vector<float> f(width);
  conditional_.clear();
  conditional_.reserve(height);
  for (int y = 0; y < height; ++y) {
    float sin_theta = std::sin(kPi * (y + 0.5f) / height);
    for (int x = 0; x < width; ++x) {
      vec3 c = pixels_[size_t(y) * width + x];
      f[x] = is_finite(c) ? std::max(0.0f, luminance(c)) * sin_theta : 0.0f;
    }
    conditional_.emplace_back(f.data(), width);
    row_weights[y] = conditional_.back().integral;
  }
  marginal_ = Distribution1D(row_weights.data(), height);
}

vec3 Background::Le(const vec3& dir) const {
  if (!has_image_) return color_;
  return strength_ * lookup(direction_to_uv(dir));
}

bool Background::sample(vec2 u, vec3* wi, float* pdf) const {
  if (!has_image_) {
    *wi = sample_uniform_sphere(u);
    *pdf = kUniformSpherePdf;
    return true;
  }
  float pdf_v, pdf_u;
  size_t row, col;
  float v = marginal_.sample_continuous(u.y, &pdf_v, &row);
  float uu = conditional_[row].sample_continuous(u.x, &pdf_u, &col);
  float sin_theta = std::sin(kPi * (1.0f - v));
  if (sin_theta <= 0.0f || pdf_u * pdf_v <= 0.0f) return false;
  *wi = uv_to_direction(vec2(uu, v));
  *pdf = pdf_u * pdf_v / (2.0f * kPi * kPi * sin_theta);
  return true;
}

float Background::pdf(const vec3& wi) const {
  if (!has_image_) return kUniformSpherePdf;
  vec2 uv = direction_to_uv(wi);
  float sin_theta = std::sin(kPi * (1.0f - uv.y));
  if (sin_theta <= 0.0f || marginal_.integral <= 0.0f) return 0.0f;
  int col = std::clamp(int(uv.x * width_), 0, width_ - 1);
  int row = std::clamp(int(uv.y * height_), 0, height_ - 1);
  float p = conditional_[row].func[col] / marginal_.integral;
  return p / (2.0f * kPi * kPi * sin_theta);
}

float Background::average_luminance() const {
  if (!has_image_) return luminance(color_);
  // The marginal integral is the sin-weighted mean; sin averages to 2/pi.
  return luminance(strength_) * marginal_.integral / (2.0f / kPi);
}

}  // namespace tessera
