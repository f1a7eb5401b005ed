// The four-triangle SIMD version of the watertight test in triangle.h (SSE,
// one triangle per lane, exactly the scalar float operations in the same
// order: bit-identical results). Included by the BVH4 traversal (baseline
// SSE2) and by the BVH8 traversals (compiled for AVX2 and for AVX-512, where
// the same intrinsics are VEX-encoded; both enable FMA with fp-contract off,
// so nothing is contracted and the rounding is the same). Everything here has internal
// linkage so that the two compilations never get merged by the linker. The
// BVH8 kernels define TESSERA_TRI4_AVX first: TriRay4 is then made from
// their per-ray vectors with AVX permutes (GCC's target pragma does not
// define __AVX__).
#pragma once
#include <immintrin.h>

#include "bvh4.h"
#include "triangle.h"

namespace tessera {
#ifdef TESSERA_BVH_COUNTERS
struct WideCounters {
  unsigned long long rays, nodes, hits_children, leaves, blocks, sign_pass, t_pass, zero_path;
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
  int axes;  // kx | ky << 2 | kz << 4: one register for the cold fallback, not three

#ifdef TESSERA_TRI4_AVX
  // From the BVH8 kernels' per-ray vectors (x, y, z in lanes 0-2): RayShear's
  // axes and values (the same divisions, so the same bits) without its
  // table loads and run-time-indexed stack arrays. kz, the largest |d| (the
  // highest axis on ties, as RayShear's table), by a lane max and compare;
  // the coordinates by lane permutes. This runs when a ray reaches its first
  // leaf, and every leaf test waits for it.
  TriRay4(__m128 o4, __m128 d4) {
    const __m128 abs_d = _mm_andnot_ps(_mm_set1_ps(-0.0f), d4);
    const __m128 m = _mm_max_ps(_mm_max_ps(abs_d, _mm_permute_ps(abs_d, 0x55)), _mm_permute_ps(abs_d, 0xAA));
    const int is_max = _mm_movemask_ps(_mm_cmpeq_ps(abs_d, _mm_permute_ps(m, 0x00))) & 7;
    kz = is_max ? 31 - __builtin_clz(unsigned(is_max)) : 2;  // none: a NaN direction
    kx = kz + 1 - 3 * (kz == 2);
    ky = kz + 2 - 3 * (kz != 0);
    const __m128i kz4 = _mm_set1_epi32(kz);
    const __m128 dz = _mm_permutevar_ps(d4, kz4);
    const int swap = -int(_mm_cvtss_f32(dz) < 0.0f);  // keep the winding order
    const int t = (kx ^ ky) & swap;
    kx ^= t, ky ^= t;
    // (d[kx], d[ky], 1, 1) / d[kz]: sx, sy, sz.
    const __m128 num = _mm_blend_ps(_mm_permutevar_ps(d4, _mm_setr_epi32(kx, ky, 0, 0)), _mm_set1_ps(1.0f), 0xC);
    const __m128 q = _mm_div_ps(num, dz);
    sx = _mm_permute_ps(q, 0x00);
    sy = _mm_permute_ps(q, 0x55);
    sz = _mm_permute_ps(q, 0xAA);
    okx = _mm_permutevar_ps(o4, _mm_set1_epi32(kx));
    oky = _mm_permutevar_ps(o4, _mm_set1_epi32(ky));
    okz = _mm_permutevar_ps(o4, kz4);
    axes = kx | ky << 2 | kz << 4;
  }
#else
  TriRay4(const vec3& origin, const vec3& d) {
    const RayShear shear(d);
    kx = shear.kx, ky = shear.ky, kz = shear.kz;
    const float ov[3] = {origin.x, origin.y, origin.z};  // no switch on the run-time index
    okx = _mm_set1_ps(ov[kx]);
    oky = _mm_set1_ps(ov[ky]);
    okz = _mm_set1_ps(ov[kz]);
    sx = _mm_set1_ps(shear.sx);
    sy = _mm_set1_ps(shear.sy);
    sz = _mm_set1_ps(shear.sz);
    axes = kx | ky << 2 | kz << 4;
  }
#endif
};

// An edge function is exactly zero in some lane (`zero`): those lanes redo
// all three in double, as the scalar test does (products of floats are exact
// in double, one rounding for the difference, one back to float: the same
// operations as intersect_triangle's, so the same bits); the other lanes keep
// theirs. Two doubles per SSE2 register, so it compiles for every width.
// Out of line and cold: it only runs where some edge function is exactly
// zero, which zero-area triangles (two equal vertices: modern_hall has 2,429
// of 31,247) do for every ray. It used to redo all four lanes with the scalar
// test (11% of modern_hall's diffuse-ray time).
__attribute__((noinline, cold)) void redo_zero_edges(__m128 ax, __m128 ay, __m128 bx, __m128 by, __m128 cx, __m128 cy,
                                                     __m128 zero, __m128& u, __m128& v, __m128& w) {
  auto lo = [](__m128 x) { return _mm_cvtps_pd(x); };
  auto hi = [](__m128 x) { return _mm_cvtps_pd(_mm_movehl_ps(x, x)); };
  auto edge = [](__m128d p, __m128d q, __m128d r, __m128d s) { return _mm_sub_pd(_mm_mul_pd(p, q), _mm_mul_pd(r, s)); };
  auto join = [](__m128d l, __m128d h) { return _mm_movelh_ps(_mm_cvtpd_ps(l), _mm_cvtpd_ps(h)); };
  const __m128 ud = join(edge(lo(cx), lo(by), lo(cy), lo(bx)), edge(hi(cx), hi(by), hi(cy), hi(bx)));
  const __m128 vd = join(edge(lo(ax), lo(cy), lo(ay), lo(cx)), edge(hi(ax), hi(cy), hi(ay), hi(cx)));
  const __m128 wd = join(edge(lo(bx), lo(ay), lo(by), lo(ax)), edge(hi(bx), hi(ay), hi(by), hi(ax)));
  u = _mm_or_ps(_mm_and_ps(zero, ud), _mm_andnot_ps(zero, u));
  v = _mm_or_ps(_mm_and_ps(zero, vd), _mm_andnot_ps(zero, v));
  w = _mm_or_ps(_mm_and_ps(zero, wd), _mm_andnot_ps(zero, w));
}

// The lanes that passed the range test (`passed`) but whose t is not above
// the error bound (not `certain`) have a positive float t within the bound:
// refine_triangle_t decides each, exactly as intersect_triangle does (same
// function, same inputs: the lane's vertices, the ray's origin and shear,
// rebuilt here from the broadcast per-ray constants, which are the same
// floats). Returns the lanes it accepts and writes their t into t. Takes the
// constants the loop already holds, not the TriRay4: its address would keep
// the whole struct in memory on the hot path (+7% instructions per ray, BVH8
// AVX2 on the bunny), and the axes packed in one int (as three ints they
// were spilled and reloaded for every block: +2.4%).
__attribute__((noinline, cold)) int refine_lanes(const Tri4& tri, int axes, __m128 okx, __m128 oky, __m128 okz,
                                                 __m128 sx, __m128 sy, __m128 sz, __m128 tmax, __m128 certain,
                                                 int passed, __m128& t) {
  const int lanes = passed & ~_mm_movemask_ps(certain);  // passed the range test, not above the bound
  const int kx = axes & 3, ky = axes >> 2 & 3, kz = axes >> 4;
  vec3 o;
  o[kx] = _mm_cvtss_f32(okx), o[ky] = _mm_cvtss_f32(oky), o[kz] = _mm_cvtss_f32(okz);
  const RayShear shear(kx, ky, kz, _mm_cvtss_f32(sx), _mm_cvtss_f32(sy), _mm_cvtss_f32(sz));
  alignas(16) float ts[4], tm[4];
  _mm_store_ps(ts, t);
  _mm_store_ps(tm, tmax);
  int hit = 0;
  for (int l = 0; l < 4; ++l) {
    if (!(lanes >> l & 1)) continue;
    vec3 p[3];
    for (int j = 0; j < 3; ++j) p[j] = vec3(tri.v[j][0][l], tri.v[j][1][l], tri.v[j][2][l]);
    if (refine_triangle_t(p[0], p[1], p[2], o, shear, tm[l], ts[l])) hit |= 1 << l;
  }
  t = _mm_load_ps(ts);
  return hit;
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
  const bool some_zero = __builtin_expect(_mm_movemask_ps(any_zero) != 0, 0);
  if (some_zero) {
    WC(zero_path);
    redo_zero_edges(ax, ay, bx, by, cx, cy, any_zero, u, v, w);
  }
  const __m128 det = _mm_add_ps(_mm_add_ps(u, v), w);
  // The lanes whose edge functions have not both signs, and det not zero.
  // With no edge function zero (unless redone above, where one may still
  // be), that is "all three sign bits equal", and det, their sum, is then
  // not zero either (a NaN lane may pass here; its t is NaN and fails
  // below): kAvx512 by three-input logic (a & b & c | ~a & ~b & ~c),
  // otherwise by (u ^ v) | (u ^ w) having no sign bit.
  int valid;
  if (__builtin_expect(some_zero, 0)) {
    const __m128 neg = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)), _mm_cmplt_ps(w, zero));
    const __m128 pos = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u, zero), _mm_cmpgt_ps(v, zero)), _mm_cmpgt_ps(w, zero));
    valid = ~_mm_movemask_ps(_mm_and_ps(neg, pos)) & _mm_movemask_ps(_mm_cmpneq_ps(det, zero));
  } else if constexpr (kAvx512) {
    valid = _mm_movemask_ps(_mm_castsi128_ps(
        _mm_ternarylogic_epi32(_mm_castps_si128(u), _mm_castps_si128(v), _mm_castps_si128(w), 0x81)));
  } else {
    valid = ~_mm_movemask_ps(_mm_or_ps(_mm_xor_ps(u, v), _mm_xor_ps(u, w))) & 0xF;
  }
  if (valid == 0) return 0;
  WC(sign_pass);
  const __m128 az = _mm_mul_ps(r.sz, az0), bz = _mm_mul_ps(r.sz, bz0), cz = _mm_mul_ps(r.sz, cz0);
  const __m128 t_scaled = _mm_add_ps(_mm_add_ps(_mm_mul_ps(u, az), _mm_mul_ps(v, bz)), _mm_mul_ps(w, cz));
  // 0 < t_scaled / det < tmax without dividing: with det's sign moved onto
  // both sides (exact), 0 < t_scaled' <= tmax det', the scalar test's two
  // branches in one.
  const __m128 det_sign = _mm_and_ps(det, _mm_set1_ps(-0.0f));
  const __m128 ts = _mm_xor_ps(t_scaled, det_sign);
  const __m128 tmd = _mm_xor_ps(_mm_mul_ps(tmax, det), det_sign);
  const int passed = valid & ~_mm_movemask_ps(_mm_or_ps(_mm_cmple_ps(ts, zero), _mm_cmpgt_ps(ts, tmd)));
  if (passed == 0) return 0;
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
  const __m128 certain = _mm_cmpgt_ps(t, delta_t);
  t_out = t;
  u_out = _mm_mul_ps(v, inv_det);
  v_out = _mm_mul_ps(w, inv_det);
  int mask = passed & _mm_movemask_ps(_mm_and_ps(certain, _mm_cmplt_ps(t, tmax)));
  // Lanes positive in float but within the error bound go to the scalar
  // test's double fallback (rare: long thin triangles near the origin). One
  // compare on the hot path: a lane that passed the range test is dropped
  // here by the bound or, rarely, by t rounding up to tmax; the cold path
  // sorts out which.
  if (__builtin_expect(mask != passed, 0))
    mask |= refine_lanes(tri, r.axes, r.okx, r.oky, r.okz, r.sx, r.sy, r.sz, tmax, certain, passed, t_out);
  return mask;
}

}  // namespace
}  // namespace tessera
