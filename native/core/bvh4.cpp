#include "bvh4.h"

#include <algorithm>

namespace tessera {
namespace {

struct Collapser {
  const BVH& bin;
  const vec3* verts;
  BVH4 out;

  static float area(const BVHNode& n) { return AABB{n.lo, n.hi}.half_area(); }

  uint32_t emit_leaf(const BVHNode& n) {
    const uint32_t first_block = uint32_t(out.tris.size());
    const uint32_t blocks = (n.count + 3) / 4;
    for (uint32_t b = 0; b < blocks; ++b) {
      Tri4 t;
      for (int lane = 0; lane < 4; ++lane) {
        const uint32_t k = n.first + std::min(4 * b + lane, n.count - 1);
        for (int v = 0; v < 3; ++v)
          for (int a = 0; a < 3; ++a) t.v[v][a][lane] = verts[3 * size_t(k) + v][a];
        t.prim[lane] = k;
      }
      out.tris.push_back(t);
    }
    return kBVH4LeafBit | (first_block << 3) | (blocks - 1);
  }

  // Returns the reference to the subtree of binary node i (which must not be a leaf
  // when called for the root).
  uint32_t emit(uint32_t i) {
    const BVHNode& n = bin.nodes[i];
    if (n.is_leaf()) return emit_leaf(n);
    uint32_t kids[4] = {n.first, n.first + 1, 0, 0};
    int count = 2;
    while (count < 4) {
      int best = -1;
      float best_area = -1.0f;
      for (int c = 0; c < count; ++c) {
        const BVHNode& k = bin.nodes[kids[c]];
        if (!k.is_leaf() && area(k) > best_area) {
          best_area = area(k);
          best = c;
        }
      }
      if (best < 0) break;
      const uint32_t split = kids[best];
      kids[best] = bin.nodes[split].first;
      kids[count++] = bin.nodes[split].first + 1;
    }
    const uint32_t index = uint32_t(out.nodes.size());
    out.nodes.emplace_back();
    uint32_t refs[4];
    for (int c = 0; c < count; ++c) refs[c] = emit(kids[c]);
    BVH4Node& node = out.nodes[index];
    for (int c = 0; c < 4; ++c) {
      if (c < count) {
        const BVHNode& k = bin.nodes[kids[c]];
        node.box[0][c] = k.lo.x, node.box[1][c] = k.hi.x;
        node.box[2][c] = k.lo.y, node.box[3][c] = k.hi.y;
        node.box[4][c] = k.lo.z, node.box[5][c] = k.hi.z;
        node.child[c] = refs[c];
      } else {
        for (int a = 0; a < 3; ++a) node.box[2 * a][c] = kInf, node.box[2 * a + 1][c] = -kInf;
        node.child[c] = kBVH4EmptyChild;
      }
    }
    node.num_children = uint32_t(count);
    node.pad[0] = node.pad[1] = node.pad[2] = 0;
    return index;
  }
};

// Per-ray constants for the box and triangle tests.
struct Ray4 {
  __m128 org_near[3], org_far[3], inv[3];
  __m128 tmax;
  int near_lo[3];  // box row holding the near plane per axis (0: lo, 1: hi) ...
  // ... triangle test (shear to +z), broadcast
  __m128 okx, oky, okz, sx, sy, sz;
  int kx, ky, kz;
  RayShear shear;
  vec3 o;

  Ray4(const vec3& origin, const vec3& d, float t_max) : shear(d), o(origin) {
    for (int i = 0; i < 3; ++i) {
      // Same guard as TraversalRay: avoid 0 * inf = NaN in the slab test.
      float di = std::abs(d[i]) < 1e-30f ? std::copysign(1e-30f, d[i]) : d[i];
      float inv_i = 1.0f / di;
      inv[i] = _mm_set1_ps(inv_i);
      near_lo[i] = inv_i >= 0.0f ? 0 : 1;
      // Separate origins for the lo / hi planes (see the two-origin intersect_box in aabb.h).
      const float delta = parallel_axis_delta(origin[i], d[i]);
      const float o_lo = origin[i] + delta, o_hi = origin[i] - delta;
      org_near[i] = _mm_set1_ps(near_lo[i] == 0 ? o_lo : o_hi);
      org_far[i] = _mm_set1_ps(near_lo[i] == 0 ? o_hi : o_lo);
    }
    tmax = _mm_set1_ps(t_max);
    kx = shear.kx, ky = shear.ky, kz = shear.kz;
    okx = _mm_set1_ps(origin[kx]);
    oky = _mm_set1_ps(origin[ky]);
    okz = _mm_set1_ps(origin[kz]);
    sx = _mm_set1_ps(shear.sx);
    sy = _mm_set1_ps(shear.sy);
    sz = _mm_set1_ps(shear.sz);
  }
};

const __m128 kWiden = _mm_set1_ps(1.0f + 2.0f * gamma(3));

// Slab test of the ray against the four child boxes: same arithmetic as
// intersect_box in aabb.h. Returns the hit mask, entry distances in tnear.
inline int intersect_node(const BVH4Node& n, const Ray4& r, __m128& tnear) {
  const int nx = r.near_lo[0], ny = r.near_lo[1], nz = r.near_lo[2];
  const __m128 tnx = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[0 + nx]), r.org_near[0]), r.inv[0]);
  const __m128 tfx = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[1 - nx]), r.org_far[0]), r.inv[0]);
  const __m128 tny = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[2 + ny]), r.org_near[1]), r.inv[1]);
  const __m128 tfy = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[3 - ny]), r.org_far[1]), r.inv[1]);
  const __m128 tnz = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[4 + nz]), r.org_near[2]), r.inv[2]);
  const __m128 tfz = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[5 - nz]), r.org_far[2]), r.inv[2]);
  tnear = _mm_max_ps(_mm_max_ps(tnx, tny), _mm_max_ps(tnz, _mm_setzero_ps()));
  const __m128 tfar = _mm_mul_ps(_mm_min_ps(_mm_min_ps(tfx, tfy), _mm_min_ps(tfz, r.tmax)), kWiden);
  return _mm_movemask_ps(_mm_cmple_ps(tnear, tfar));
}

// Watertight test of one ray against four triangles (see triangle.h for the
// scalar version; the lanes repeat its operations exactly). Returns the mask
// of lanes hit within (0, tmax) and their t, u, v.
inline int intersect_tri4(const Tri4& tri, const Ray4& r, __m128& t_out, __m128& u_out, __m128& v_out) {
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
  const __m128 any_zero = _mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)), _mm_cmpeq_ps(w, zero));
  if (__builtin_expect(_mm_movemask_ps(any_zero) != 0, 0)) {
    // An edge function is exactly zero: the scalar test redoes it in double.
    alignas(16) float ts[4], us[4], vs[4];
    alignas(16) float tm[4];
    _mm_store_ps(tm, r.tmax);
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
  const __m128 neg = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)), _mm_cmplt_ps(w, zero));
  const __m128 pos = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u, zero), _mm_cmpgt_ps(v, zero)), _mm_cmpgt_ps(w, zero));
  __m128 valid = _mm_andnot_ps(_mm_and_ps(neg, pos), _mm_castsi128_ps(_mm_set1_epi32(-1)));
  const __m128 det = _mm_add_ps(_mm_add_ps(u, v), w);
  valid = _mm_and_ps(valid, _mm_cmpneq_ps(det, zero));
  if (_mm_movemask_ps(valid) == 0) return 0;
  const __m128 az = _mm_mul_ps(r.sz, az0), bz = _mm_mul_ps(r.sz, bz0), cz = _mm_mul_ps(r.sz, cz0);
  const __m128 t_scaled = _mm_add_ps(_mm_add_ps(_mm_mul_ps(u, az), _mm_mul_ps(v, bz)), _mm_mul_ps(w, cz));
  const __m128 tmd = _mm_mul_ps(r.tmax, det);
  const __m128 det_neg = _mm_cmplt_ps(det, zero);
  const __m128 fail_neg = _mm_or_ps(_mm_cmpge_ps(t_scaled, zero), _mm_cmplt_ps(t_scaled, tmd));
  const __m128 fail_pos = _mm_or_ps(_mm_cmple_ps(t_scaled, zero), _mm_cmpgt_ps(t_scaled, tmd));
  const __m128 fail = _mm_or_ps(_mm_and_ps(det_neg, fail_neg), _mm_andnot_ps(det_neg, fail_pos));
  valid = _mm_andnot_ps(fail, valid);
  if (_mm_movemask_ps(valid) == 0) return 0;
  const __m128 inv_det = _mm_div_ps(_mm_set1_ps(1.0f), det);
  const __m128 t = _mm_mul_ps(t_scaled, inv_det);
  // The conservative t error bound of triangle_t_error, lane by lane.
  const __m128 sign = _mm_set1_ps(-0.0f);
  auto abs4 = [&](__m128 x) { return _mm_andnot_ps(sign, x); };
  auto g = [](int n) { return _mm_set1_ps(gamma(n)); };
  const __m128 max_xt = _mm_max_ps(abs4(ax), _mm_max_ps(abs4(bx), abs4(cx)));
  const __m128 max_yt = _mm_max_ps(abs4(ay), _mm_max_ps(abs4(by), abs4(cy)));
  const __m128 max_zt = _mm_max_ps(abs4(az), _mm_max_ps(abs4(bz), abs4(cz)));
  const __m128 delta_x = _mm_mul_ps(g(5), _mm_add_ps(max_xt, max_zt));
  const __m128 delta_y = _mm_mul_ps(g(5), _mm_add_ps(max_yt, max_zt));
  const __m128 delta_z = _mm_mul_ps(g(3), max_zt);
  const __m128 delta_e = _mm_mul_ps(_mm_set1_ps(2.0f),
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_mul_ps(g(2), max_xt), max_yt), _mm_mul_ps(delta_y, max_xt)),
                 _mm_mul_ps(delta_x, max_yt)));
  const __m128 max_e = _mm_max_ps(abs4(u), _mm_max_ps(abs4(v), abs4(w)));
  const __m128 delta_t = _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(3.0f),
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_mul_ps(g(3), max_e), max_zt), _mm_mul_ps(delta_e, max_zt)),
                 _mm_mul_ps(delta_z, max_e))), abs4(inv_det));
  valid = _mm_and_ps(valid, _mm_and_ps(_mm_cmpgt_ps(t, delta_t), _mm_cmplt_ps(t, r.tmax)));
  t_out = t;
  u_out = _mm_mul_ps(v, inv_det);
  v_out = _mm_mul_ps(w, inv_det);
  return _mm_movemask_ps(valid);
}

constexpr int kStackSize = 256;
struct StackEntry {
  uint32_t ref;
  float t;
};

}  // namespace

BVH4 collapse_to_bvh4(const BVH& binary, const vec3* tri_verts) {
  Collapser c{binary, tri_verts, {}};
  if (binary.nodes.empty()) return {};
  size_t leaves = 0;
  for (const BVHNode& n : binary.nodes) leaves += n.is_leaf();
  c.out.nodes.reserve(binary.nodes.size() / 2 + 1);
  c.out.tris.reserve(leaves + binary.prim_order.size() / 4 + 1);
  const BVHNode& root = binary.nodes[0];
  if (root.is_leaf()) {
    // A single leaf: wrap it in a root with one child.
    BVH4Node node;
    for (int ch = 0; ch < 4; ++ch)
      for (int a = 0; a < 3; ++a) node.box[2 * a][ch] = kInf, node.box[2 * a + 1][ch] = -kInf;
    for (uint32_t& ch : node.child) ch = kBVH4EmptyChild;
    c.out.nodes.push_back(node);
    const uint32_t ref = c.emit_leaf(root);
    BVH4Node& n = c.out.nodes[0];
    n.box[0][0] = root.lo.x, n.box[1][0] = root.hi.x, n.box[2][0] = root.lo.y;
    n.box[3][0] = root.hi.y, n.box[4][0] = root.lo.z, n.box[5][0] = root.hi.z;
    n.child[0] = ref;
    n.num_children = 1;
    n.pad[0] = n.pad[1] = n.pad[2] = 0;
  } else {
    c.emit(0);
  }
  c.out.bounds = AABB{root.lo, root.hi};
  return std::move(c.out);
}

float sah_cost(const BVH4& bvh, const BuildOptions& options) {
  if (bvh.nodes.empty()) return 0.0f;
  const float root_area = bvh.bounds.half_area();
  if (root_area <= 0.0f) return 0.0f;
  double cost = options.traversal_cost;  // the root is always visited
  for (const BVH4Node& n : bvh.nodes)
    for (uint32_t c = 0; c < n.num_children; ++c) {
      AABB b{vec3(n.box[0][c], n.box[2][c], n.box[4][c]), vec3(n.box[1][c], n.box[3][c], n.box[5][c])};
      const float a = b.half_area() / root_area;
      cost += bvh4_is_leaf(n.child[c]) ? options.intersection_cost * bvh4_leaf_blocks(n.child[c]) * a
                                       : options.traversal_cost * a;
    }
  return float(cost);
}

int BVH4::depth() const {
  if (nodes.empty()) return 0;
  int best = 0;
  std::vector<std::pair<uint32_t, int>> stack{{0u, 1}};
  while (!stack.empty()) {
    auto [i, d] = stack.back();
    stack.pop_back();
    best = std::max(best, d);
    for (uint32_t c = 0; c < nodes[i].num_children; ++c)
      if (!bvh4_is_leaf(nodes[i].child[c])) stack.push_back({nodes[i].child[c], d + 1});
  }
  return best;
}

template <bool kOrdered>
bool bvh4_intersect(const BVH4& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  if (bvh.nodes.empty()) return false;
  Ray4 ray(o, d, tmax);
  const BVH4Node* nodes = bvh.nodes.data();
  const Tri4* tris = bvh.tris.data();
  StackEntry stack[kStackSize];
  int sp = 0;
  uint32_t ref = 0;
  bool found = false;
  float t_best = tmax;
  for (;;) {
    if (!bvh4_is_leaf(ref)) {
      const BVH4Node& n = nodes[ref];
      __m128 tn;
      int mask = intersect_node(n, ray, tn);
      if (mask != 0) {
        alignas(16) float dist[4];
        _mm_store_ps(dist, tn);
        int first = __builtin_ctz(mask);
        mask &= mask - 1;
        if (mask == 0) {  // one child hit: descend without the stack
          ref = n.child[first];
          continue;
        }
        if (!kOrdered) {
          // Stored order: push the others in reverse, descend into the first.
          int lanes[4], k = 0;
          for (int m = mask; m; m &= m - 1) lanes[k++] = __builtin_ctz(m);
          for (int j = k - 1; j >= 0; --j) stack[sp++] = {n.child[lanes[j]], dist[lanes[j]]};
          ref = n.child[first];
          continue;
        }
        // Fetch the hit children's nodes while sorting.
        for (int m = mask | (1 << first); m; m &= m - 1) {
          const uint32_t c = n.child[__builtin_ctz(m)];
          if (!bvh4_is_leaf(c)) {
            _mm_prefetch(reinterpret_cast<const char*>(&nodes[c]), _MM_HINT_T0);
            _mm_prefetch(reinterpret_cast<const char*>(&nodes[c]) + 64, _MM_HINT_T0);
          }
        }
        // Nearest first: insertion sort of the (at most four) hit children by
        // distance, farthest pushed first.
        StackEntry e[4];
        int k = 0;
        e[k++] = {n.child[first], dist[first]};
        for (int m = mask; m; m &= m - 1) {
          const int c = __builtin_ctz(m);
          StackEntry x{n.child[c], dist[c]};
          int j = k++;
          while (j > 0 && e[j - 1].t > x.t) {
            e[j] = e[j - 1];
            --j;
          }
          e[j] = x;
        }
        for (int j = k - 1; j > 0; --j) stack[sp++] = e[j];
        ref = e[0].ref;
        continue;
      }
    } else {
      const uint32_t first = bvh4_leaf_first(ref), blocks = bvh4_leaf_blocks(ref);
      for (uint32_t b = first; b < first + blocks; ++b) {
        __m128 t, u, v;
        int mask = intersect_tri4(tris[b], ray, t, u, v);
        if (mask == 0) continue;
        alignas(16) float ts[4], us[4], vs[4];
        _mm_store_ps(ts, t);
        _mm_store_ps(us, u);
        _mm_store_ps(vs, v);
        // Nearest lane; on equal distances the lower lane (earlier triangle) wins.
        int best = -1;
        for (int m = mask; m; m &= m - 1) {
          const int lane = __builtin_ctz(m);
          if (best < 0 || ts[lane] < ts[best]) best = lane;
        }
        t_best = ts[best];
        hit = {ts[best], us[best], vs[best], tris[b].prim[best]};
        ray.tmax = _mm_set1_ps(t_best);
        found = true;
      }
    }
    // Pop, skipping entries farther than the nearest hit so far.
    for (;;) {
      if (sp == 0) {
        tmax = t_best;
        return found;
      }
      --sp;
      if (stack[sp].t <= t_best) break;
    }
    ref = stack[sp].ref;
  }
}

template bool bvh4_intersect<true>(const BVH4&, const vec3&, const vec3&, float&, BVH4Hit&);
template bool bvh4_intersect<false>(const BVH4&, const vec3&, const vec3&, float&, BVH4Hit&);

bool bvh4_occluded(const BVH4& bvh, const vec3& o, const vec3& d, float tmax) {
  if (bvh.nodes.empty()) return false;
  Ray4 ray(o, d, tmax);
  const BVH4Node* nodes = bvh.nodes.data();
  const Tri4* tris = bvh.tris.data();
  uint32_t stack[kStackSize];
  int sp = 0;
  uint32_t ref = 0;
  for (;;) {
    if (!bvh4_is_leaf(ref)) {
      const BVH4Node& n = nodes[ref];
      __m128 tn;
      int mask = intersect_node(n, ray, tn);
      if (mask != 0) {
        const int first = __builtin_ctz(mask);
        for (int m = mask & (mask - 1); m; m &= m - 1) stack[sp++] = n.child[__builtin_ctz(m)];
        ref = n.child[first];
        continue;
      }
    } else {
      const uint32_t first = bvh4_leaf_first(ref), blocks = bvh4_leaf_blocks(ref);
      for (uint32_t b = first; b < first + blocks; ++b) {
        __m128 t, u, v;
        if (intersect_tri4(tris[b], ray, t, u, v)) return true;
      }
    }
    if (sp == 0) return false;
    ref = stack[--sp];
  }
}

}  // namespace tessera
