#include "bvh4.h"
#include "bvh8.h"
#include "simd_tri4.h"
#include "wide_traverse.h"

#include <algorithm>
#include <stdexcept>

namespace tessera {

namespace {

// Collapses the binary tree into an N-wide one (Out: BVH4 or BVH8, Node its
// node type): each node takes the children of its largest-area descendants
// until it has N.
template <int N, typename Node, typename Out>
struct Collapser {
  const BVH& bin;
  const vec3* verts;
  const BuildOptions& opt;
  Out out;

  Collapser(const BVH& b, const vec3* v, const BuildOptions& o) : bin(b), verts(v), opt(o) {}
  // Per binary node: triangles below it, and whether the subtree, where it
  // becomes a child of a wide node, is stored as one leaf of packed blocks
  // instead of a node of its own (see plan()).
  std::vector<uint32_t> tris_below;
  std::vector<uint8_t> as_leaf;

  static float area(const BVHNode& n) { return AABB{n.lo, n.hi}.half_area(); }
  static uint32_t blocks_for(uint32_t tris) { return (tris + 3) / 4; }

  // The triangles of binary subtree i, packed four to a block (a
  // subtree's leaves index one contiguous range of the leaf order); the
  // last block repeats its last triangle in its spare lanes.
  uint32_t emit_leaf(uint32_t i) {
    uint32_t lo = ~0u, hi = 0;
    range(i, lo, hi);
    const uint32_t count = hi - lo;
    const uint32_t blocks = blocks_for(count);
    const size_t off = alloc_blocks(blocks);
    if (!dry) {
      Tri4* out_blocks = reinterpret_cast<Tri4*>(mem() + off);
      for (uint32_t b = 0; b < blocks; ++b) {
        Tri4& t = out_blocks[b];
        for (int lane = 0; lane < 4; ++lane) {
          const uint32_t k = lo + std::min(4 * b + lane, count - 1);
          for (int v = 0; v < 3; ++v)
            for (int a = 0; a < 3; ++a) t.v[v][a][lane] = verts[3 * size_t(k) + v][a];
          t.prim[lane] = k;
        }
      }
    }
    out.num_blocks += blocks;
    const size_t unit = off / kBlockUnit;
    if (unit >= (size_t(1) << 28)) throw std::length_error("mesh too large for the wide BVH's 28-bit leaf references");
    return kBVH4LeafBit | (uint32_t(unit) << 3) | (blocks - 1);
  }

  // Arena cursors: nodes and blocks share one when leaves sit next to their
  // parent; otherwise blocks start after the last node (dry-run sizes).
  bool dry = true;
  size_t node_cursor = 0, block_cursor = 0;
  bool shared_cursor() const { return opt.leaves_next_to_parent; }
  char* mem() { return reinterpret_cast<char*>(out.mem.data()); }
  size_t alloc_node() {
    size_t& c = node_cursor;
    c = (c + kNodeUnit - 1) / kNodeUnit * kNodeUnit;
    const size_t off = c;
    c += sizeof(Node);
    return off;
  }
  size_t alloc_blocks(uint32_t blocks) {
    size_t& c = shared_cursor() ? node_cursor : block_cursor;
    c = (c + kBlockUnit - 1) / kBlockUnit * kBlockUnit;
    const size_t off = c;
    c += blocks * sizeof(Tri4);
    return off;
  }

  void range(uint32_t i, uint32_t& lo, uint32_t& hi) const {
    const BVHNode& n = bin.nodes[i];
    if (n.is_leaf()) {
      lo = std::min(lo, n.first);
      hi = std::max(hi, n.first + n.count);
      return;
    }
    range(n.first, lo, hi);
    range(n.first + 1, lo, hi);
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

  bool is_leaf_child(uint32_t i) const { return bin.nodes[i].is_leaf() || as_leaf[i]; }

  // Wide SAH (unnormalised: area times cost) of binary subtree i as a child
  // of a wide node, choosing bottom-up between a node of its own (the
  // traversal step plus its children, opened as emit() opens them) and one
  // leaf of packed blocks (up to kMaxLeafBlocks; binary leaves never exceed
  // max_leaf_size anyway). A subtree of two or three small leaves costs a
  // whole wide node visit for a two- or three-way split: as a leaf its
  // triangles share blocks and no node is visited (Embree's BVH8 builder
  // gets the same effect by splitting only ranges of more than four triangles).
  static constexpr uint32_t kMaxLeafBlocks = 2;
  float plan(uint32_t i) {
    const BVHNode& n = bin.nodes[i];
    const float a = area(n);
    if (n.is_leaf()) {
      tris_below[i] = n.count;
      return cost_[i] = a * opt.intersection_cost * float(blocks_for(n.count));
    }
    float child_cost = plan(n.first) + plan(n.first + 1);
    tris_below[i] = tris_below[n.first] + tris_below[n.first + 1];
    uint32_t kids[N];
    const int count = open_children(n, kids);
    if (count != 2) {
      child_cost = 0.0f;
      for (int c = 0; c < count; ++c) child_cost += cost_[kids[c]];
    }
    const float node_cost = a * opt.traversal_cost + child_cost;
    const uint32_t blocks = blocks_for(tris_below[i]);
    const float leaf_cost = a * opt.intersection_cost * float(blocks);
    as_leaf[i] = blocks <= kMaxLeafBlocks && leaf_cost <= node_cost;
    cost_[i] = as_leaf[i] ? leaf_cost : node_cost;
    return cost_[i];
  }
  std::vector<float> cost_;

  // Returns the reference to the subtree of binary node i (in the dry run
  // only the cursors move: the exact arena size).
  uint32_t emit(uint32_t i) {
    if (is_leaf_child(i)) return emit_leaf(i);
    const BVHNode& n = bin.nodes[i];
    uint32_t kids[N];
    const int count = open_children(n, kids);
    const size_t off = alloc_node();
    ++out.num_nodes;
    uint32_t refs[N];
    // Leaf children first, right behind the node, then the subtrees.
    for (int c = 0; c < count; ++c)
      if (is_leaf_child(kids[c])) refs[c] = emit_leaf(kids[c]);
    for (int c = 0; c < count; ++c)
      if (!is_leaf_child(kids[c])) refs[c] = emit(kids[c]);
    if (!dry) {
      Node& node = *reinterpret_cast<Node*>(mem() + off);
      clear(node);
      for (int c = 0; c < count; ++c) set_child(node, c, bin.nodes[kids[c]], refs[c]);
      node.num_children = uint32_t(count);
    }
    return uint32_t(off / kNodeUnit);
  }

  // Emits the tree from binary node 0 (a leaf root gets a node with one child).
  void emit_root() {
    const BVHNode& root = bin.nodes[0];
    if (!root.is_leaf()) {
      emit(0);
      return;
    }
    const size_t off = alloc_node();
    ++out.num_nodes;
    const uint32_t ref = emit_leaf(0);
    if (!dry) {
      Node& node = *reinterpret_cast<Node*>(mem() + off);
      clear(node);
      set_child(node, 0, root, ref);
      node.num_children = 1;
    }
  }

  void run() {
    if (bin.nodes.empty()) return;
    tris_below.assign(bin.nodes.size(), 0);
    as_leaf.assign(bin.nodes.size(), 0);
    cost_.assign(bin.nodes.size(), 0.0f);
    if (opt.collapse_small_subtrees) {
      plan(0);
    } else {
      for (size_t i = 0; i < bin.nodes.size(); ++i) tris_below[i] = bin.nodes[i].is_leaf() ? bin.nodes[i].count : 0;
    }
    as_leaf[0] = 0;  // the root stays a node
    // Dry run: the node region's size (blocks after it) and the arena size,
    // so the arena is allocated once: no regrowth, no shrink-to-fit copy.
    dry = true;
    node_cursor = block_cursor = 0;
    emit_root();
    size_t nodes_end = 0;
    if (!shared_cursor()) {
      nodes_end = (node_cursor + kNodeUnit - 1) / kNodeUnit * kNodeUnit;
      node_cursor = 0, block_cursor = nodes_end;
      emit_root();
    }
    const size_t bytes = std::max(node_cursor, block_cursor);
    out.mem.resize((bytes + sizeof(BVHLine) - 1) / sizeof(BVHLine));
    out.num_nodes = out.num_blocks = 0;
    dry = false;
    node_cursor = 0, block_cursor = nodes_end;
    emit_root();
    out.bounds = AABB{bin.nodes[0].lo, bin.nodes[0].hi};
  }
};

// Per-ray constants for the box and triangle tests.
struct Ray4 {
  __m128 org_near[3], org_far[3], inv[3];
  __m128 tmax;      // for the triangle test
  __m128 tmax_far;  // tmax widened as the far planes
  __m128 inv_far[3];
  int near_lo[3];  // box row holding the near plane per axis (0: lo, 1: hi)
  TriRay4 tri;

  Ray4(const vec3& origin, const vec3& d, float t_max) : tri(origin, d) {
    for (int i = 0; i < 3; ++i) {
      // Same guard as TraversalRay: avoid 0 * inf = NaN in the slab test.
      float di = std::abs(d[i]) < 1e-30f ? std::copysign(1e-30f, d[i]) : d[i];
      float inv_i = 1.0f / di;
      inv[i] = _mm_set1_ps(inv_i);
      inv_far[i] = _mm_set1_ps(widen_far(inv_i));
      near_lo[i] = int(!(inv_i >= 0.0f));
      // Separate origins for the lo / hi planes (see the two-origin intersect_box in aabb.h):
      // near o + delta (inv >= 0) or o - delta, far the other; no branch on the sign.
      const float delta = parallel_axis_delta(origin[i], d[i]);
      const float signed_delta = flip_sign(delta, near_lo[i]);
      org_near[i] = _mm_set1_ps(origin[i] + signed_delta);
      org_far[i] = _mm_set1_ps(origin[i] - signed_delta);
    }
    set_tmax(t_max);
  }
  void set_tmax(float t) {
    tmax = _mm_set1_ps(t);
    tmax_far = _mm_set1_ps(widen_far(t));
  }
};

// Slab test of the ray against the four child boxes: intersect_box's
// arithmetic on the near planes, at least as wide on the far planes (the
// widening folded into inv_far and tmax_far, as in the BVH8's test; see
// bvh8_avx2.cpp), the final compare on the bit patterns as signed integers
// (tnear >= +0, so a negative tfar culls; SSE2 has no integer max/min).
// Returns the hit mask, entry distances in tnear.
inline int intersect_node(const BVH4Node& n, const Ray4& r, __m128& tnear) {
  const int nx = r.near_lo[0], ny = r.near_lo[1], nz = r.near_lo[2];
  const __m128 tnx = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[0 + nx]), r.org_near[0]), r.inv[0]);
  const __m128 tfx = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[1 - nx]), r.org_far[0]), r.inv_far[0]);
  const __m128 tny = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[2 + ny]), r.org_near[1]), r.inv[1]);
  const __m128 tfy = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[3 - ny]), r.org_far[1]), r.inv_far[1]);
  const __m128 tnz = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[4 + nz]), r.org_near[2]), r.inv[2]);
  const __m128 tfz = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[5 - nz]), r.org_far[2]), r.inv_far[2]);
  tnear = _mm_max_ps(_mm_max_ps(tnx, tny), _mm_max_ps(tnz, _mm_setzero_ps()));
  const __m128 tfar = _mm_min_ps(_mm_min_ps(tfx, tfy), _mm_min_ps(tfz, r.tmax_far));
  return ~_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(_mm_castps_si128(tnear), _mm_castps_si128(tfar)))) & 0xF;
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
  static void set_tmax(Ray& r, float t) { r.set_tmax(t); }
  static void prefetch(const char* base, uint32_t ref) {
    const char* p = base + size_t(ref) * kNodeUnit;
    _mm_prefetch(p, _MM_HINT_T0);
    _mm_prefetch(p + 64, _MM_HINT_T0);
  }
};

}  // namespace

BVH4 collapse_to_bvh4(const BVH& binary, const vec3* tri_verts, const BuildOptions& options) {
  Collapser<4, BVH4Node, BVH4> c(binary, tri_verts, options);
  c.run();
  return std::move(c.out);
}

BVH8 collapse_to_bvh8(const BVH& binary, const vec3* tri_verts, const BuildOptions& options) {
  Collapser<8, BVH8Node, BVH8> c(binary, tri_verts, options);
  c.run();
  return std::move(c.out);
}

template <typename Tree>
static float wide_sah_cost(const Tree& bvh, const BuildOptions& options) {
  if (bvh.empty()) return 0.0f;
  const float root_area = bvh.bounds.half_area();
  if (root_area <= 0.0f) return 0.0f;
  double cost = options.traversal_cost;  // the root is always visited
  std::vector<uint32_t> stack{0u};
  while (!stack.empty()) {
    const auto& n = bvh.node(stack.back());
    stack.pop_back();
    for (uint32_t c = 0; c < n.num_children; ++c) {
      AABB b{vec3(n.box[0][c], n.box[2][c], n.box[4][c]), vec3(n.box[1][c], n.box[3][c], n.box[5][c])};
      const float a = b.half_area() / root_area;
      if (bvh4_is_leaf(n.child[c])) {
        cost += options.intersection_cost * bvh4_leaf_blocks(n.child[c]) * a;
      } else {
        cost += options.traversal_cost * a;
        stack.push_back(n.child[c]);
      }
    }
  }
  return float(cost);
}

template <typename Node>
int WideBVH<Node>::depth() const {
  if (empty()) return 0;
  int best = 0;
  std::vector<std::pair<uint32_t, int>> stack{{0u, 1}};
  while (!stack.empty()) {
    auto [i, d] = stack.back();
    stack.pop_back();
    best = std::max(best, d);
    for (uint32_t c = 0; c < node(i).num_children; ++c)
      if (!bvh4_is_leaf(node(i).child[c])) stack.push_back({node(i).child[c], d + 1});
  }
  return best;
}
template struct WideBVH<BVH4Node>;
template struct WideBVH<BVH8Node>;

float sah_cost(const BVH4& bvh, const BuildOptions& options) { return wide_sah_cost(bvh, options); }
float sah_cost(const BVH8& bvh, const BuildOptions& options) { return wide_sah_cost(bvh, options); }

template <bool kOrdered>
bool bvh4_intersect(const BVH4& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit) {
  if (bvh.empty()) return false;
  Ray4 ray(o, d, tmax);
  return wide_intersect<Bvh4Traits, kOrdered>(bvh.base(), ray, tmax, hit);
}

template bool bvh4_intersect<true>(const BVH4&, const vec3&, const vec3&, float&, BVH4Hit&);
template bool bvh4_intersect<false>(const BVH4&, const vec3&, const vec3&, float&, BVH4Hit&);

bool bvh4_occluded(const BVH4& bvh, const vec3& o, const vec3& d, float tmax) {
  if (bvh.empty()) return false;
  Ray4 ray(o, d, tmax);
  return wide_occluded<Bvh4Traits>(bvh.base(), ray);
}

}  // namespace tessera
