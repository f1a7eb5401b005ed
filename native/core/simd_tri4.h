// The four-triangle SIMD version of the watertight test in triangle.h (SSE,
// one triangle per lane, exactly the scalar float operations in the same
// order: bit-identical results). Included by the BVH4 traversal (baseline
// SSE2) and by the BVH8 traversal (compiled for AVX2, where the same
// intrinsics are VEX-encoded; no FMA is enabled there, so nothing is
// contracted and the rounding is the same). Everything here has internal
// linkage so that the two compilations never get merged by the linker.
#pragma once
#include <immintrin.h>

#include "bvh4.h"
#include "triangle.h"

namespace tessera {
#ifdef TESSERA_BVH_COUNTERS
struct WideCounters {
  unsigned long long rays, nodes, hits_children, leaves, blocks, sign_pass, t_pass;
  unsigned long long hit_hist[9];  // node visits by number of children hit
};
extern WideCounters g_wide_counters;
#define WC(x) (++g_wide_counters.x)
#define WCN(x, n) (g_wide_counters.x += (n))
#define WCH(n) (++g_wide_counters.hit_hist[n])
#else
#define WC(x) ((void)0)
#define WCN(x, n) ((void)0)
#define WCH(n) ((void)0)
#endif

namespace {

// Per-ray constants of the triangle test (shear to +z), broadcast.
struct TriRay4 {
  __m128 okx, oky, okz, sx, sy, sz;
  int kx, ky, kz;
  RayShear shear;
  vec3 o;

  TriRay4(const vec3& origin, const vec3& d) : shear(d), o(origin) {
    kx = shear.kx, ky = shear.ky, kz = shear.kz;
    const float ov[3] = {origin.x, origin.y, origin.z};  // no switch on the run-time index
    okx = _mm_set1_ps(ov[kx]);
    oky = _mm_set1_ps(ov[ky]);
    okz = _mm_set1_ps(ov[kz]);
    sx = _mm_set1_ps(shear.sx);
    sy = _mm_set1_ps(shear.sy);
    sz = _mm_set1_ps(shear.sz);
  }
};

// An edge function is exactly zero in some lane: the scalar test redoes
// every lane (in double where it needs to). Out of line and cold, so the
// fast path inlines into the traversal loops without it.
__attribute__((noinline, cold)) int intersect_tri4_exact_zero(const Tri4& tri, const TriRay4& r, __m128 tmax, __m128& t_out,
                                                             __m128& u_out, __m128& v_out) {
  alignas(16) float ts[4], us[4], vs[4];
  alignas(16) float tm[4];
  _mm_store_ps(tm, tmax);
  int mask = 0;
  for (int lane = 0; lane < 4; ++lane) {
    const vec3 p0(tri.v[0][0][lane], tri.v[0][1][lane], tri.v[0][2][lane]);
    const vec3 p1(tri.v[1][0][lane], tri.v[1][1][lane], tri.v[1][2][lane]);
    const vec3 p2(tri.v[2][0][lane], tri.v[2][1][lane], tri.v[2][2][lane]);
    TriangleHit h;
    if (intersect_triangle(p0, p1, p2, r.o, r.shear, tm[lane], h)) {
      mask |= 1 << lane;
      ts[lane] = h.t, us[lane] = h.u, vs[lane] = h.v;
    } else {
      ts[lane] = kInf, us[lane] = vs[lane] = 0.0f;
    }
  }
  t_out = _mm_load_ps(ts), u_out = _mm_load_ps(us), v_out = _mm_load_ps(vs);
  return mask;
}

// Watertight test of one ray against four triangles (see triangle.h for the
// scalar version; the lanes repeat its operations exactly). Returns the mask
// of lanes hit within (0, tmax) and their t, u, v. kAvx512: only for code
// compiled for AVX-512VL (bvh8_avx512.cpp), the zero and sign tests by
// three-input logic (vpternlogd), same result.
template <bool kAvx512 = false>
__attribute__((always_inline)) inline int intersect_tri4(const Tri4& tri, const TriRay4& r, __m128 tmax, __m128& t_out, __m128& u_out, __m128& v_out) {
  const int kx = r.kx, ky = r.ky, kz = r.kz;
  const __m128 ax0 = _mm_sub_ps(_mm_load_ps(tri.v[0][kx]), r.okx);
  const __m128 ay0 = _mm_sub_ps(_mm_load_ps(tri.v[0][ky]), r.oky);
  const __m128 az0 = _mm_sub_ps(_mm_load_ps(tri.v[0][kz]), r.okz);
  const __m128 bx0 = _mm_sub_ps(_mm_load_ps(tri.v[1][kx]), r.okx);
  const __m128 by0 = _mm_sub_ps(_mm_load_ps(tri.v[1][ky]), r.oky);
  const __m128 bz0 = _mm_sub_ps(_mm_load_ps(tri.v[1][kz]), r.okz);
  const __m128 cx0 = _mm_sub_ps(_mm_load_ps(tri.v[2][kx]), r.okx);
  const __m128 cy0 = _mm_sub_ps(_mm_load_ps(tri.v[2][ky]), r.oky);
  const __m128 cz0 = _mm_sub_ps(_mm_load_ps(tri.v[2][kz]), r.okz);
  const __m128 ax = _mm_sub_ps(ax0, _mm_mul_ps(r.sx, az0)), ay = _mm_sub_ps(ay0, _mm_mul_ps(r.sy, az0));
  const __m128 bx = _mm_sub_ps(bx0, _mm_mul_ps(r.sx, bz0)), by = _mm_sub_ps(by0, _mm_mul_ps(r.sy, bz0));
  const __m128 cx = _mm_sub_ps(cx0, _mm_mul_ps(r.sx, cz0)), cy = _mm_sub_ps(cy0, _mm_mul_ps(r.sy, cz0));
  __m128 u = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
  __m128 v = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
  __m128 w = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
  const __m128 zero = _mm_setzero_ps();
  __m128 any_zero;
  if constexpr (kAvx512) {
    any_zero = _mm_castsi128_ps(_mm_ternarylogic_epi32(_mm_castps_si128(_mm_cmpeq_ps(u, zero)),
        _mm_castps_si128(_mm_cmpeq_ps(v, zero)), _mm_castps_si128(_mm_cmpeq_ps(w, zero)), 0xFE));  // a | b | c
  } else {
    any_zero = _mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)), _mm_cmpeq_ps(w, zero));
  }
  if (__builtin_expect(_mm_movemask_ps(any_zero) != 0, 0)) return intersect_tri4_exact_zero(tri, r, tmax, t_out, u_out, v_out);
  const __m128 det = _mm_add_ps(_mm_add_ps(u, v), w);
  __m128 valid;
  if constexpr (kAvx512) {
    // No edge function is zero here, so "not both signs" is "all three sign
    // bits equal" (a & b & c | ~a & ~b & ~c), and then det, their sum, is not
    // zero either. (A NaN lane may pass here; its t is NaN and fails below.)
    valid = _mm_castsi128_ps(_mm_ternarylogic_epi32(_mm_castps_si128(u), _mm_castps_si128(v), _mm_castps_si128(w), 0x81));
  } else {
    const __m128 neg = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)), _mm_cmplt_ps(w, zero));
    const __m128 pos = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u, zero), _mm_cmpgt_ps(v, zero)), _mm_cmpgt_ps(w, zero));
    valid = _mm_andnot_ps(_mm_and_ps(neg, pos), _mm_castsi128_ps(_mm_set1_epi32(-1)));
    valid = _mm_and_ps(valid, _mm_cmpneq_ps(det, zero));
  }
  if (_mm_movemask_ps(valid) == 0) return 0;
  WC(sign_pass);
  const __m128 az = _mm_mul_ps(r.sz, az0), bz = _mm_mul_ps(r.sz, bz0), cz = _mm_mul_ps(r.sz, cz0);
  const __m128 t_scaled = _mm_add_ps(_mm_add_ps(_mm_mul_ps(u, az), _mm_mul_ps(v, bz)), _mm_mul_ps(w, cz));
  const __m128 tmd = _mm_mul_ps(tmax, det);
  const __m128 det_neg = _mm_cmplt_ps(det, zero);
  const __m128 fail_neg = _mm_or_ps(_mm_cmpge_ps(t_scaled, zero), _mm_cmplt_ps(t_scaled, tmd));
  const __m128 fail_pos = _mm_or_ps(_mm_cmple_ps(t_scaled, zero), _mm_cmpgt_ps(t_scaled, tmd));
  const __m128 fail = _mm_or_ps(_mm_and_ps(det_neg, fail_neg), _mm_andnot_ps(det_neg, fail_pos));
  valid = _mm_andnot_ps(fail, valid);
  if (_mm_movemask_ps(valid) == 0) return 0;
  WC(t_pass);
  const __m128 inv_det = _mm_div_ps(_mm_set1_ps(1.0f), det);
  const __m128 t = _mm_mul_ps(t_scaled, inv_det);
  // The conservative t error bound of triangle_t_error, lane by lane.
  const __m128 sign = _mm_set1_ps(-0.0f);
  auto abs4 = [&](__m128 x) { return _mm_andnot_ps(sign, x); };
  auto g = [](int n) { return _mm_set1_ps(gamma(n)); };
  const __m128 max_xt = _mm_max_ps(abs4(ax), _mm_max_ps(abs4(bx), abs4(cx)));
  const __m128 max_yt = _mm_max_ps(abs4(ay), _mm_max_ps(abs4(by), abs4(cy)));
  const __m128 max_zt = _mm_max_ps(abs4(az), _mm_max_ps(abs4(bz), abs4(cz)));
  const __m128 max_z_raw = _mm_max_ps(abs4(az0), _mm_max_ps(abs4(bz0), abs4(cz0)));
  const __m128 delta_x = _mm_mul_ps(g(5), _mm_add_ps(max_xt, _mm_mul_ps(abs4(r.sx), max_z_raw)));
  const __m128 delta_y = _mm_mul_ps(g(5), _mm_add_ps(max_yt, _mm_mul_ps(abs4(r.sy), max_z_raw)));
  const __m128 delta_z = _mm_mul_ps(g(3), max_zt);
  const __m128 delta_e = _mm_mul_ps(_mm_set1_ps(2.0f),
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_mul_ps(g(2), max_xt), max_yt), _mm_mul_ps(delta_y, max_xt)),
                 _mm_mul_ps(delta_x, max_yt)));
  const __m128 max_e = _mm_max_ps(abs4(u), _mm_max_ps(abs4(v), abs4(w)));
  const __m128 delta_t = _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(3.0f),
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_mul_ps(g(3), max_e), max_zt), _mm_mul_ps(delta_e, max_zt)),
                 _mm_mul_ps(delta_z, max_e))), abs4(inv_det));
  valid = _mm_and_ps(valid, _mm_and_ps(_mm_cmpgt_ps(t, delta_t), _mm_cmplt_ps(t, tmax)));
  t_out = t;
  u_out = _mm_mul_ps(v, inv_det);
  v_out = _mm_mul_ps(w, inv_det);
  return _mm_movemask_ps(valid);
}

}  // namespace
}  // namespace tessera
