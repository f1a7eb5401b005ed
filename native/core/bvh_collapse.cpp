// The collapse of a binary SAH tree into the wide BVHs (BVH4, BVH8): wide
// nodes from the binary nodes' largest-area descendants, small subtrees
// collapsed into packed Tri4 leaves by the wide SAH, and the leaf blocks.
#include "bvh4.h"
#include "bvh8.h"
#include "simd_tri4.h"

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

}  // namespace tessera
