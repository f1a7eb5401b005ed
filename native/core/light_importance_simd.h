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
// sqrt, max, min, and_, andnot (~a & b), or_, cmpgt, cmplt (all-ones lanes),
// bits (a lane mask loaded from uint32_t[]).
template <typename Ops>
struct ImportanceLanes {
  using T = typename Ops::T;
  static T blend(T mask, T a, T b) { return Ops::or_(Ops::and_(mask, a), Ops::andnot(mask, b)); }
  static T sqrt0(T x) { return Ops::sqrt(Ops::max(x, Ops::set1(0.0f))); }  // safe_sqrt
  static T dot(T ax, T ay, T az, T bx, T by, T bz) {
    return Ops::add(Ops::add(Ops::mul(ax, bx), Ops::mul(ay, by)), Ops::mul(az, bz));
  }

  // Lanes [k, k + width of T) of b into out[k...].
  static void eval(const ImportanceBounds8& b, int k, const vec3& p, const vec3& n, float* out) {
    const T zero = Ops::set1(0.0f), one = Ops::set1(1.0f), abs_mask = Ops::abs_mask();
    const T tx = Ops::sub(Ops::set1(p.x), Ops::load(b.cx + k));
    const T ty = Ops::sub(Ops::set1(p.y), Ops::load(b.cy + k));
    const T tz = Ops::sub(Ops::set1(p.z), Ops::load(b.cz + k));
    const T dist2 = dot(tx, ty, tz, tx, ty, tz);
    const T inv_dist2 = Ops::div(one, dist2);
    const T inv_d2 = Ops::min(inv_dist2, Ops::load(b.inv_min_dist2 + k));
    T cw = dot(Ops::load(b.wx + k), Ops::load(b.wy + k), Ops::load(b.wz + k), tx, ty, tz);
    cw = blend(Ops::bits(b.two_sided + k), Ops::and_(cw, abs_mask), cw);
    const T sw = sqrt0(Ops::sub(dist2, Ops::mul(cw, cw)));
    const T co = Ops::load(b.cos_o + k), so = Ops::load(b.sin_o + k), r = Ops::load(b.radius + k);
    const T in_cone = Ops::cmpgt(Ops::mul(cw, Ops::and_(cw, abs_mask)),
                                 Ops::mul(Ops::mul(co, Ops::and_(co, abs_mask)), dist2));
    const T r2 = Ops::mul(r, r);
    const T inside = Ops::cmplt(dist2, r2);
    const T cb = sqrt0(Ops::sub(dist2, r2));
    const T cx = Ops::add(Ops::mul(cw, co), Ops::mul(sw, so)), sx = Ops::sub(Ops::mul(sw, co), Ops::mul(cw, so));
    const T cos_p = blend(Ops::or_(Ops::or_(in_cone, inside), Ops::cmpgt(cx, cb)), one,
                          Ops::mul(Ops::add(Ops::mul(cx, cb), Ops::mul(sx, r)), inv_dist2));
    const T ph = Ops::load(b.phi + k);
    const T lit = Ops::and_(Ops::cmpgt(cos_p, Ops::load(b.cos_e + k)), Ops::cmpgt(ph, zero));
    T imp = Ops::mul(Ops::mul(ph, cos_p), inv_d2);
    if (n != vec3(0.0f)) {
      const T ci = Ops::and_(dot(Ops::set1(n.x), Ops::set1(n.y), Ops::set1(n.z), tx, ty, tz), abs_mask);
      const T si = sqrt0(Ops::sub(dist2, Ops::mul(ci, ci)));
      imp = Ops::mul(imp, blend(Ops::or_(inside, Ops::cmpgt(ci, cb)), one,
                                Ops::mul(Ops::add(Ops::mul(ci, cb), Ops::mul(si, r)), inv_dist2)));
    }
    // max(imp, 0) also turns a NaN into 0.
    Ops::store(out + k, Ops::and_(lit, Ops::max(imp, zero)));
  }
};

}  // namespace
}  // namespace tessera
