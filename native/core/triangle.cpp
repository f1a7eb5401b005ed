// The double-precision t of the watertight triangle test (see triangle.h).
// Out of line and in this one file on purpose: the scalar test and every SIMD
// kernel (SSE2, AVX2, AVX-512 compilations) call this same compiled code, so a
// refined t is bit for bit the same on every path.
#include "triangle.h"

namespace tessera {

namespace {
// Relative error of n chained double operations (Higham's gamma_n for
// u = 2^-53), as gamma(n) in math.h is for float.
constexpr double kDoubleEps = std::numeric_limits<double>::epsilon() * 0.5;
constexpr double gamma_d(int n) { return (n * kDoubleEps) / (1 - n * kDoubleEps); }
}  // namespace

// The plane distance t = N / D, N = sum e_i z_i, D = sum e_i (the sheared
// construction of intersect_triangle, Woop et al. eq. 4-6), all in double
// from the float inputs. The float sx, sy, sz are taken as exact: they define
// the ray o + t d' that the float test traces too (d'_kz = 1/sz, d'_kx = sx/sz,
// d'_ky = sy/sz), and t is its parameter. Error bounds (Higham's model,
// |fl(a op b) - a op b| <= u |a op b|; hats are computed values):
//   a = p - o:            one rounding.
//   x' = a_x - sx a_z:    |x'^ - x'| <= gamma(4) (|a_x| + |sx a_z|) =: dx per vertex,
//                         and so for y'; z' = sz a_z: |z'^ - z'| <= gamma(3) |z'^|.
//   e = x'_1 y'_2 - y'_1 x'_2 (exact sheared coordinates) against its value from
//   the rounded ones: |e^ - e| <= 2 (gamma(2) Mx My + Mx dy + My dx + dx dy) =: de,
//   Mx, My the largest |x'^|, |y'^| (pbrt-v4 6.8.5 keeps the first three terms).
//   D = e0 + e1 + e2:     |D^ - D| <= gamma(2) * 3E + 3 de, E = max |e^_i|.
//   N = sum e_i z_i:      |N^ - N| <= gamma(3) * 3E Z + 3 (de Z + (E + de) dz),
//                         Z = max |z'^_i|, dz = gamma(3) Z.
// N^ and D^ beyond their bounds fix the signs of the exact N and D, so t > 0 is
// certain when they agree. The bounds are computed in double too, with a
// rounding error far below the 1e-3 relative margin they are given.
bool refine_triangle_t(const vec3& p0, const vec3& p1, const vec3& p2, const vec3& o, const RayShear& s, float tmax,
                       float& t) {
  const vec3* p[3] = {&p0, &p1, &p2};
  const double sx = s.sx, sy = s.sy, sz = s.sz;
  double x[3], y[3], z[3];
  double mx = 0.0, my = 0.0, mz = 0.0, dx = 0.0, dy = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double ax = double((*p[i])[s.kx]) - double(o[s.kx]);
    const double ay = double((*p[i])[s.ky]) - double(o[s.ky]);
    const double az = double((*p[i])[s.kz]) - double(o[s.kz]);
    x[i] = ax - sx * az;
    y[i] = ay - sy * az;
    z[i] = sz * az;
    mx = std::max(mx, std::abs(x[i]));
    my = std::max(my, std::abs(y[i]));
    mz = std::max(mz, std::abs(z[i]));
    dx = std::max(dx, gamma_d(4) * (std::abs(ax) + std::abs(sx * az)));
    dy = std::max(dy, gamma_d(4) * (std::abs(ay) + std::abs(sy * az)));
  }
  // Edge functions of the three vertex pairs (u, v, w of intersect_triangle).
  const double e0 = x[2] * y[1] - y[2] * x[1];
  const double e1 = x[0] * y[2] - y[0] * x[2];
  const double e2 = x[1] * y[0] - y[1] * x[0];
  const double d = e0 + e1 + e2;
  const double n = e0 * z[0] + e1 * z[1] + e2 * z[2];
  const double me = std::max(std::abs(e0), std::max(std::abs(e1), std::abs(e2)));
  const double de = 2.0 * (gamma_d(2) * mx * my + mx * dy + my * dx + dx * dy);
  const double dz = gamma_d(3) * mz;
  const double margin = 1.001;
  const double err_d = margin * (gamma_d(2) * 3.0 * me + 3.0 * de);
  const double err_n = margin * (gamma_d(3) * 3.0 * me * mz + 3.0 * (de * mz + (me + de) * dz));
  // Both signs certain and equal: the exact t = N / D is positive.
  if (!(std::abs(d) > err_d && std::abs(n) > err_n && (n > 0.0) == (d > 0.0))) return false;
  const float tf = float(n / d);
  if (!(tf > 0.0f && tf < tmax)) return false;  // rounded to float: still > 0, and in range
  t = tf;
  return true;
}

}  // namespace tessera
