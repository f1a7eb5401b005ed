// Unit vectors in 32 bits by the octahedral map (Meyer et al. 2010, "On
// floating-point normal vectors"; Cigolle et al. 2014, "A Survey of Efficient
// Representations for Independent Unit Vectors", JCGT 3(2)): the vector over
// its L1 norm, the lower half folded over the upper, 16 bits per coordinate.
// Encoding picks the best of the four grid points around the projection
// (their "precise" oct32), judged in double: at most 0.0025 degrees (4e-5
// rad) off over 200k random directions (test
// Numerics.OctahedralNormalsRoundTrip), in a third of the memory of three
// floats per corner normal. Codes run 0..65534 per axis so that 32767 is
// exactly 0 and axis-aligned normals come back exact.
#pragma once
#include <cstdint>
#include "math.h"

namespace tessera {

// The zero vector: a corner normal that is zero or not finite in the input
// (interpolation then leans on the other corners, as with the floats).
constexpr uint32_t kOctZero = 0xFFFFFFFFu;

namespace oct_detail {
constexpr int kCenter = 32767;
inline float sign_not_zero(float x) { return x >= 0.0f ? 1.0f : -1.0f; }
// The unnormalised point of the octahedron for a code (|x| + |y| + |z| = 1).
inline vec3 unfold(uint32_t code) {
  const float k = 1.0f / float(kCenter);
  float x = float(int(code & 0xFFFFu) - kCenter) * k;
  float y = float(int(code >> 16) - kCenter) * k;
  const float z = 1.0f - std::abs(x) - std::abs(y);
  // Lower half: fold back across the diagonals, branch-free (t = 0 above).
  const float t = std::max(-z, 0.0f);
  x += x >= 0.0f ? -t : t;
  y += y >= 0.0f ? -t : t;
  return vec3(x, y, z);
}
}  // namespace oct_detail

inline vec3 oct_decode(uint32_t code) {
  if (code == kOctZero) return vec3(0.0f);
  return glm::normalize(oct_detail::unfold(code));
}

inline uint32_t oct_encode(const vec3& n) {
  using namespace oct_detail;
  const float l1 = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
  if (!(l1 > 0.0f) || !std::isfinite(l1)) return kOctZero;
  float px = n.x / l1, py = n.y / l1;
  if (n.z < 0.0f) {
    const float ox = px;
    px = (1.0f - std::abs(py)) * sign_not_zero(px);
    py = (1.0f - std::abs(ox)) * sign_not_zero(py);
  }
  const double len = std::sqrt(double(n.x) * n.x + double(n.y) * n.y + double(n.z) * n.z);
  const double ux = n.x / len, uy = n.y / len, uz = n.z / len;
  const float fx = (std::clamp(px, -1.0f, 1.0f) + 1.0f) * float(kCenter);
  const float fy = (std::clamp(py, -1.0f, 1.0f) + 1.0f) * float(kCenter);
  // The candidate whose decoded vector (as oct_decode makes it, in float)
  // is nearest, by the chord in double: a float dot near 1 cannot tell them apart.
  uint32_t best = 0;
  double best_d2 = 10.0;
  for (int i = 0; i < 4; ++i) {
    const int qx = std::clamp(int(i & 1 ? std::ceil(fx) : std::floor(fx)), 0, 2 * kCenter);
    const int qy = std::clamp(int(i & 2 ? std::ceil(fy) : std::floor(fy)), 0, 2 * kCenter);
    const uint32_t code = uint32_t(qx) | uint32_t(qy) << 16;
    const vec3 d = glm::normalize(unfold(code));
    const double d2 = (d.x - ux) * (d.x - ux) + (d.y - uy) * (d.y - uy) + (d.z - uz) * (d.z - uz);
    if (d2 < best_d2) best_d2 = d2, best = code;
  }
  return best;
}

}  // namespace tessera
