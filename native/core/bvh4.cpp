#include "bvh4.h"
#include "bvh8.h"
#include "simd_tri4.h"
#include "wide_traverse.h"

#include <algorithm>

namespace tessera {

namespace {

// Collapses the binary tree into an N-wide one (Out: BVH4 or BVH8, Node its
// node type): each node takes the children of its largest-area descendants
// until it has N.
template <int N, typename Node, typename Out>
struct Collapser {
  const BVH& bin;
  const vec3* verts;
  Out out;

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

  static void clear(Node& node) {
    for (int c = 0; c < N; ++c) {
      for (int a = 0; a < 3; ++a) node.box[2 * a][c] = kInf, node.box[2 * a + 1][c] = -kInf;
      node.child[c] = kBVH4EmptyChild;
    }
    node.num_children = 0;
    for (uint32_t& p : node.pad) p = 0;
  }
  static void set_child(Node& node, int c, const BVHNode& k, uint32_t ref) {
    node.box[0][c] = k.lo.x, node.box[1][c] = k.hi.x;
    node.box[2][c] = k.lo.y, node.box[3][c] = k.hi.y;
    node.box[4][c] = k.lo.z, node.box[5][c] = k.hi.z;
    node.child[c] = ref;
  }

  // The children of interior node n: its largest-area interior descendants
  // are opened until there are N (or only leaves are left).
  int open_children(const BVHNode& n, uint32_t* kids) const {
    kids[0] = n.first, kids[1] = n.first + 1;
    int count = 2;
    while (count < N) {
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
    return count;
  }

  // Returns the reference to the subtree of binary node i.
  uint32_t emit(uint32_t i) {
    const BVHNode& n = bin.nodes[i];
    if (n.is_leaf()) return emit_leaf(n);
    uint32_t kids[N];
    const int count = open_children(n, kids);
    const uint32_t index = uint32_t(out.nodes.size());
    out.nodes.emplace_back();
    uint32_t refs[N];
    for (int c = 0; c < count; ++c) refs[c] = emit(kids[c]);
    Node& node = out.nodes[index];
    clear(node);
    for (int c = 0; c < count; ++c) set_child(node, c, bin.nodes[kids[c]], refs[c]);
    node.num_children = uint32_t(count);
    return index;
  }

  // Exact sizes of the output arrays (a dry run of emit's choices), so that
  // each is allocated once: no regrowth, no shrink-to-fit copy.
  void count(uint32_t i, size_t& nodes, size_t& blocks) const {
    const BVHNode& n = bin.nodes[i];
    if (n.is_leaf()) {
      blocks += (n.count + 3) / 4;
      return;
    }
    uint32_t kids[N];
    const int k = open_children(n, kids);
    ++nodes;
    for (int c = 0; c < k; ++c) count(kids[c], nodes, blocks);
  }

  void run() {
    if (bin.nodes.empty()) return;
    size_t num_nodes = 0, num_blocks = 0;
    count(0, num_nodes, num_blocks);
    out.nodes.reserve(std::max<size_t>(num_nodes, 1));
    out.tris.reserve(num_blocks);
    const BVHNode& root = bin.nodes[0];
    if (root.is_leaf()) {
      // A single leaf: wrap it in a root with one child.
      out.nodes.emplace_back();
      clear(out.nodes[0]);
      const uint32_t ref = emit_leaf(root);
      set_child(out.nodes[0], 0, root, ref);
      out.nodes[0].num_children = 1;
    } else {
      emit(0);
    }
    out.bounds = AABB{root.lo, root.hi};
  }
};

// Per-ray constants for the box and triangle tests.
struct Ray4 {
  __m128 org_near[3], org_far[3], inv[3];
  __m128 tmax;
  int near_lo[3];  // box row holding the near plane per axis (0: lo, 1: hi)
  TriRay4 tri;

  Ray4(const vec3& origin, const vec3& d, float t_max) : tri(origin, d) {
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

// BVH4 for wide_intersect / wide_occluded.
struct Bvh4Traits {
  static constexpr int kWidth = 4;
  static constexpr int kStackSize = 256;
  using Node = BVH4Node;
  using Ray = Ray4;
  static int test(const Node& n, const Ray& r, float* dist) {
    __m128 tn;
    const int mask = intersect_node(n, r, tn);
    _mm_store_ps(dist, tn);
    return mask;
  }
  static __m128 tri_tmax(const Ray& r) { return r.tmax; }
  static void set_tmax(Ray& r, float t) { r.tmax = _mm_set1_ps(t); }
  static void prefetch(const Node* nodes, uint32_t ref) {
    const char* p = reinterpret_cast<const char*>(&nodes[ref]);
    _mm_prefetch(p, _MM_HINT_T0);
    _mm_prefetch(p + 64, _MM_HINT_T0);
  }
};

}  // namespace

BVH4 collapse_to_bvh4(const BVH& binary, const vec3* tri_verts) {
  Collapser<4, BVH4Node, BVH4> c{binary, tri_verts, {}};
  c.run();
  return std::move(c.out);
}

BVH8 collapse_to_bvh8(const BVH& binary, const vec3* tri_verts) {
  Collapser<8, BVH8Node, BVH8> c{binary, tri_verts, {}};
  c.run();
  return std::move(c.out);
}

template <typename Tree>
static float wide_sah_cost(const Tree& bvh, const BuildOptions& options) {
  if (bvh.nodes.empty()) return 0.0f;
  const float root_area = bvh.bounds.half_area();
  if (root_area <= 0.0f) return 0.0f;
  double cost = options.traversal_cost;  // the root is always visited
  for (const auto& n : bvh.nodes)
    for (uint32_t c = 0; c < n.num_children; ++c) {
      AABB b{vec3(n.box[0][c], n.box[2][c], n.box[4][c]), vec3(n.box[1][c], n.box[3][c], n.box[5][c])};
      const float a = b.half_area() / root_area;
      cost += bvh4_is_leaf(n.child[c]) ? options.intersection_cost * bvh4_leaf_blocks(n.child[c]) * a
                                       : options.traversal_cost * a;
    }
  return float(cost);
}

template <typename Tree>
static int wide_depth(const Tree& t) {
  if (t.nodes.empty()) return 0;
  int best = 0;
  std::vector<std::pair<uint32_t, int>> stack{{0u, 1}};
  while (!stack.empty()) {
    auto [i, d] = stack.back();
    stack.pop_back();
    best = std::max(best, d);
    for (uint32_t c = 0; c < t.nodes[i].num_children; ++c)
      if (!bvh4_is_leaf(t.nodes[i].child[c])) stack.push_back({t.nodes[i].child[c], d + 1});
  }
  return best;
}

float sah_cost(const BVH4& bvh, const BuildOptions& options) { return wide_sah_cost(bvh, options); }
float sah_cost(const BVH8& bvh, const BuildOptions& options) { return wide_sah_cost(bvh, options); }
int BVH4::depth() const { return wide_depth(*this); }
int BVH8::depth() const { return wide_depth(*this); }

template <bool kOrdered>
bool bvh4_intersect(const BVH4& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  if (bvh.nodes.empty()) return false;
  Ray4 ray(o, d, tmax);
  return wide_intersect<Bvh4Traits, kOrdered>(bvh.nodes.data(), bvh.tris.data(), ray, tmax, hit);
}

template bool bvh4_intersect<true>(const BVH4&, const vec3&, const vec3&, float&, BVH4Hit&);
template bool bvh4_intersect<false>(const BVH4&, const vec3&, const vec3&, float&, BVH4Hit&);

bool bvh4_occluded(const BVH4& bvh, const vec3& o, const vec3& d, float tmax) {
  if (bvh.nodes.empty()) return false;
  Ray4 ray(o, d, tmax);
  return wide_occluded<Bvh4Traits>(bvh.nodes.data(), bvh.tris.data(), ray);
}

}  // namespace tessera
