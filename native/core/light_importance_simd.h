// ImportanceBounds::importance for several light BVH children at once: the
// scalar function's operations, in the same order, one SIMD lane per child,
// written once over a vector type. light_bvh.cpp instantiates it for SSE2
// (two passes of four lanes, every x86-64 CPU), light_bvh_avx2.cpp inside
// its AVX2 target region (one pass of eight). Internal linkage only, so the
// two instruction sets never mix in one symbol.
#pragma once
#include "light_bvh.h"

namespace tessera {
namespace {

// Ops: T (the vector), load / store (aligned), set1, add, sub, mul, div,
// sqrt, max, and_, andnot (~a & b), or_, cmpgt, cmplt (all-ones lanes),
// bits (a lane mask loaded from uint32_t[]).
template <typename Ops>
struct ImportanceLanes {
  using T = typename Ops::T;
  static T blend(T mask, T a, T b) { return Ops::or_(Ops::and_(mask, a), Ops::andnot(mask, b)); }
  static T sqrt0(T x) { return Ops::sqrt(Ops::max(x, Ops::set1(0.0f))); }  // safe_sqrt
  // cos(max(0, a - b)) and sin(max(0, a - b)), as cos_sub_clamped / sin_sub_clamped.
  static T cos_sub(T sin_a, T cos_a, T sin_b, T cos_b) {
    return blend(Ops::cmpgt(cos_a, cos_b), Ops::set1(1.0f), Ops::add(Ops::mul(cos_a, cos_b), Ops::mul(sin_a, sin_b)));
  }
  static T sin_sub(T sin_a, T cos_a, T sin_b, T cos_b) {
    return Ops::andnot(Ops::cmpgt(cos_a, cos_b), Ops::sub(Ops::mul(sin_a, cos_b), Ops::mul(cos_a, sin_b)));
  }

  // Lanes [k, k + width of T) of b into out[k...].
  static void eval(const ImportanceBounds8& b, int k, const vec3& p, const vec3& n, float* out) {
    const T zero = Ops::set1(0.0f), one = Ops::set1(1.0f);
    const T tx = Ops::sub(Ops::set1(p.x), Ops::load(b.cx + k));
    const T ty = Ops::sub(Ops::set1(p.y), Ops::load(b.cy + k));
    const T tz = Ops::sub(Ops::set1(p.z), Ops::load(b.cz + k));
    const T dist2 = Ops::add(Ops::add(Ops::mul(tx, tx), Ops::mul(ty, ty)), Ops::mul(tz, tz));
    const T d2 = Ops::max(dist2, Ops::load(b.min_dist2 + k));
    const T away = Ops::cmpgt(dist2, zero);
    const T inv_len = Ops::and_(away, Ops::div(one, Ops::sqrt(dist2)));
    const T wi_x = Ops::mul(tx, inv_len), wi_y = Ops::mul(ty, inv_len);
    const T wi_z = blend(away, Ops::mul(tz, inv_len), one);
    T cos_w = Ops::add(Ops::add(Ops::mul(Ops::load(b.wx + k), wi_x), Ops::mul(Ops::load(b.wy + k), wi_y)),
                       Ops::mul(Ops::load(b.wz + k), wi_z));
    const T abs_mask = Ops::abs_mask();
    cos_w = blend(Ops::bits(b.two_sided + k), Ops::and_(cos_w, abs_mask), cos_w);
    const T sin_w = sqrt0(Ops::sub(one, Ops::mul(cos_w, cos_w)));
    const T r2 = Ops::load(b.radius2 + k);
    const T inside = Ops::cmplt(dist2, r2);
    const T sin2_b = Ops::andnot(inside, Ops::mul(r2, Ops::mul(inv_len, inv_len)));
    const T cos_b = blend(inside, Ops::set1(-1.0f), sqrt0(Ops::sub(one, sin2_b)));
    const T sin_b = Ops::sqrt(sin2_b);
    const T co = Ops::load(b.cos_o + k), so = Ops::load(b.sin_o + k);
    const T cos_x = cos_sub(sin_w, cos_w, so, co), sin_x = sin_sub(sin_w, cos_w, so, co);
    const T cos_p = cos_sub(sin_x, cos_x, sin_b, cos_b);
    const T ph = Ops::load(b.phi + k);
    const T lit = Ops::and_(Ops::cmpgt(cos_p, Ops::load(b.cos_e + k)), Ops::cmpgt(ph, zero));
    T imp = Ops::div(Ops::mul(ph, cos_p), d2);
    if (n != vec3(0.0f)) {
      const T dn = Ops::add(Ops::add(Ops::mul(wi_x, Ops::set1(n.x)), Ops::mul(wi_y, Ops::set1(n.y))),
                            Ops::mul(wi_z, Ops::set1(n.z)));
      const T cos_i = Ops::and_(dn, abs_mask);
      const T sin_i = sqrt0(Ops::sub(one, Ops::mul(cos_i, cos_i)));
      imp = Ops::mul(imp, cos_sub(sin_i, cos_i, sin_b, cos_b));
    }
    // max(imp, 0) also turns a NaN (a light of zero size exactly at p) into 0.
    Ops::store(out + k, Ops::and_(lit, Ops::max(imp, zero)));
  }
};

}  // namespace
}  // namespace tessera
