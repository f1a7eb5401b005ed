// The collapse of a binary SAH tree into the wide BVHs (BVH4, BVH8): wide
// nodes from the binary nodes' largest-area descendants, small subtrees
// collapsed into packed Tri4 leaves by the wide SAH, and the leaf blocks.
#include "bvh4.h"
#include "bvh8.h"
#include "simd_tri4.h"

#include <tbb/parallel_invoke.h>
#include <tbb/task_group.h>
#include <xmmintrin.h>

#include <algorithm>
#include <atomic>
#include <memory>
#include <stdexcept>
#include <type_traits>

namespace tessera {

namespace {

// Collapses the binary tree into an N-wide one (Out: BVH4 or BVH8, Node its
// node type): each node takes the children of its largest-area descendants
// until it has N.
//
// Two passes, both TBB-parallel over subtrees: plan() goes bottom-up over the
// binary tree and fixes, per binary node, whether it becomes a packed leaf and
// how much arena space its subtree takes as a wide node (position-independent:
// every subtree starts on a node, 64-byte aligned); emit() then writes the
// subtrees concurrently, each at the offset its left siblings' sizes give
// (as Embree's builders place nodes by precomputed offsets). The arena is
// allocated once, with its exact size, and its layout is the same however many
// threads run.
template <int N, typename Node, typename Out>
struct Collapser {
  const BVH& bin;
  const vec3* verts;
  const BuildOptions& opt;
  Out out;

  Collapser(const BVH& b, const vec3* v, const BuildOptions& o) : bin(b), verts(v), opt(o) {}

  // Arena offsets count 32-byte units (kBlockUnit); a node is 64-byte aligned.
  static constexpr uint32_t kNodeUnits = uint32_t(sizeof(Node) / kBlockUnit);
  static constexpr uint32_t kBlockUnits = uint32_t(sizeof(Tri4) / kBlockUnit);
  static_assert(sizeof(Node) % kNodeUnit == 0 && sizeof(Tri4) % kBlockUnit == 0 && kNodeUnit == 2 * kBlockUnit,
                "arena units");
  static uint32_t align_node(uint32_t units) { return (units + 1) & ~1u; }

  // Arena space of a subtree emitted as a wide node: with leaves next to
  // their parent everything is in `nodes`; otherwise the node region and the
  // block region (all nodes first, then all blocks) grow separately.
  struct Space {
    uint32_t nodes, blocks;  // no initialisers: the plan array is left unwritten
  };

  // Per binary node (filled by plan(), unwritten before): triangles below
  // it, whether the subtree, where it becomes a child of a wide node, is
  // stored as one leaf of packed blocks instead of a node of its own, its
  // wide SAH cost, and its space as a wide node. One array from the BVH
  // allocator (memory of an earlier build: no fresh pages to fault in).
  struct Planned {
    uint32_t tris_below;
    float cost;
    Space space;
    uint8_t as_leaf;
  };
  static_assert(std::is_trivially_default_constructible<Planned>::value, "resize must not write the plan");
  BVHArray<Planned> planned;
  // Nodes and blocks written, counted per task and summed by the parent
  // after its tasks (a shared atomic made every leaf's lock-prefixed add wait
  // for the block stores before it, and moved between the cores).
  struct Counts {
    uint32_t nodes = 0, blocks = 0;
  };

  static float area(const BVHNode& n) { return AABB{n.lo, n.hi}.half_area(); }
  static uint32_t blocks_for(uint32_t tris) { return (tris + 3) / 4; }
  bool shared() const { return opt.leaves_next_to_parent; }
  char* mem() { return reinterpret_cast<char*>(out.mem.data()); }

  // The triangles of binary subtree i, packed four to a block at arena unit
  // `unit` (a subtree's leaves index one contiguous range of the leaf order,
  // starting at its leftmost leaf); the last block repeats its last triangle
  // in its spare lanes.
  uint32_t emit_leaf(uint32_t i, uint32_t unit, Counts& counts) {
    uint32_t first = i;
    while (!bin.nodes[first].is_leaf()) first = bin.nodes[first].first;
    const uint32_t lo = bin.nodes[first].first, count = planned[i].tris_below;
    const uint32_t blocks = blocks_for(count);
    if (unit >= (uint32_t(1) << 28)) throw std::length_error("mesh too large for the wide BVH's 28-bit leaf references");
    Tri4* out_blocks = reinterpret_cast<Tri4*>(mem() + size_t(unit) * kBlockUnit);
    // A triangle's nine floats are contiguous: two 4 x 4 transposes give the
    // lanes of its first eight, the ninth goes lane by lane.
    for (uint32_t b = 0; b < blocks; ++b) {
      Tri4& t = out_blocks[b];
      const float* p[4];
      for (uint32_t lane = 0; lane < 4; ++lane) {
        const uint32_t k = lo + std::min(4 * b + lane, count - 1);
        p[lane] = &verts[3 * size_t(k)].x;
        t.prim[lane] = k;
      }
      __m128 a0 = _mm_loadu_ps(p[0]), a1 = _mm_loadu_ps(p[1]), a2 = _mm_loadu_ps(p[2]), a3 = _mm_loadu_ps(p[3]);
      __m128 b0 = _mm_loadu_ps(p[0] + 4), b1 = _mm_loadu_ps(p[1] + 4), b2 = _mm_loadu_ps(p[2] + 4),
             b3 = _mm_loadu_ps(p[3] + 4);
      _MM_TRANSPOSE4_PS(a0, a1, a2, a3);  // v0.x v0.y v0.z v1.x
      _MM_TRANSPOSE4_PS(b0, b1, b2, b3);  // v1.y v1.z v2.x v2.y
      _mm_store_ps(t.v[0][0], a0), _mm_store_ps(t.v[0][1], a1), _mm_store_ps(t.v[0][2], a2);
      _mm_store_ps(t.v[1][0], a3), _mm_store_ps(t.v[1][1], b0), _mm_store_ps(t.v[1][2], b1);
      _mm_store_ps(t.v[2][0], b2), _mm_store_ps(t.v[2][1], b3);
      _mm_store_ps(t.v[2][2], _mm_setr_ps(p[0][8], p[1][8], p[2][8], p[3][8]));
    }
    counts.blocks += blocks;
    return kBVH4LeafBit | (unit << 3) | (blocks - 1);
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
    // Per child: its area if it can be opened (interior), -1 if not (a
    // leaf), so the search below reads no nodes.
    auto key = [this](uint32_t i) {
      const BVHNode& k = bin.nodes[i];
      return k.is_leaf() ? -1.0f : area(k);
    };
    kids[0] = n.first, kids[1] = n.first + 1;
    float keys[N];
    keys[0] = key(kids[0]), keys[1] = key(kids[1]);
    int count = 2;
    while (count < N) {
      int best = -1;
      float best_key = -1.0f;
      for (int c = 0; c < count; ++c) {
        if (keys[c] > best_key) {
          best_key = keys[c];
          best = c;
        }
      }
      if (best < 0) break;
      const uint32_t split = kids[best];
      kids[best] = bin.nodes[split].first;
      kids[count] = bin.nodes[split].first + 1;
      keys[best] = key(kids[best]);
      keys[count] = key(kids[count]);
      ++count;
    }
    return count;
  }


  bool is_leaf_child(uint32_t i) const { return bin.nodes[i].is_leaf() || planned[i].as_leaf; }

  // Wide SAH (unnormalised: area times cost) of binary subtree i as a child
  // of a wide node, choosing bottom-up between a node of its own (the
  // traversal step plus its children, opened as emit() opens them) and one
  // leaf of packed blocks (up to kMaxLeafBlocks; binary leaves never exceed
  // max_leaf_size anyway). A subtree of two or three small leaves costs a
  // whole wide node visit for a two- or three-way split: as a leaf its
  // triangles share blocks and no node is visited (Embree's BVH8 builder
  // gets the same effect by splitting only ranges of more than four triangles).
  // Also the subtree's arena space as a wide node (see Space).
  static constexpr uint32_t kMaxLeafBlocks = 2;
  static constexpr int kParallelPlanDepth = 6;  // 64 tasks at most
  void plan(uint32_t i, int depth) {
    const BVHNode& n = bin.nodes[i];
    const float a = area(n);
    if (n.is_leaf()) {
      planned[i].tris_below = n.count;
      planned[i].as_leaf = 0;
      planned[i].cost = a * opt.intersection_cost * float(blocks_for(n.count));
      planned[i].space = Space{};
      return;
    }
    if (opt.parallel && depth < kParallelPlanDepth) {
      tbb::parallel_invoke([&] { plan(n.first, depth + 1); }, [&] { plan(n.first + 1, depth + 1); });
    } else {
      plan(n.first, depth + 1);
      plan(n.first + 1, depth + 1);
    }
    planned[i].tris_below = planned[n.first].tris_below + planned[n.first + 1].tris_below;
    uint32_t kids[N];
    const int count = open_children(n, kids);
    float child_cost = 0.0f;
    Space s{};
    uint32_t leaf_units = 0;
    for (int c = 0; c < count; ++c) {
      child_cost += planned[kids[c]].cost;
      if (is_leaf_child(kids[c])) {
        leaf_units += kBlockUnits * blocks_for(planned[kids[c]].tris_below);
      } else {
        s.nodes += planned[kids[c]].space.nodes;
        s.blocks += planned[kids[c]].space.blocks;
      }
    }
    if (shared()) {
      s.nodes += align_node(kNodeUnits + leaf_units);
    } else {
      s.nodes += kNodeUnits;
      s.blocks += leaf_units;
    }
    planned[i].space = s;
    const float node_cost = a * opt.traversal_cost + child_cost;
    const uint32_t blocks = blocks_for(planned[i].tris_below);
    const float leaf_cost = a * opt.intersection_cost * float(blocks);
    planned[i].as_leaf = opt.collapse_small_subtrees && blocks <= kMaxLeafBlocks && leaf_cost <= node_cost;
    planned[i].cost = planned[i].as_leaf ? leaf_cost : node_cost;
  }

  // Subtrees of more triangles than this are emitted as TBB tasks.
  static constexpr uint32_t kParallelEmit = 1024;

  // Writes binary node i as a wide node at arena unit `unit` (its leaf blocks
  // right behind it, or at `block_unit` in the block region), then its
  // subtrees at the offsets plan()'s sizes give; returns its reference.
  uint32_t emit(uint32_t i, uint32_t unit, uint32_t block_unit, Counts& counts) {
    const BVHNode& n = bin.nodes[i];
    uint32_t kids[N];
    const int count = open_children(n, kids);
    counts.nodes += 1;
    uint32_t refs[N];
    Counts task_counts[N];
    // Leaf children first, right behind the node, then the subtrees.
    uint32_t b = shared() ? unit + kNodeUnits : block_unit;
    for (int c = 0; c < count; ++c)
      if (is_leaf_child(kids[c])) {
        refs[c] = emit_leaf(kids[c], b, counts);
        b += kBlockUnits * blocks_for(planned[kids[c]].tris_below);
      }
    uint32_t next = shared() ? align_node(b) : unit + kNodeUnits;
    uint32_t next_block = shared() ? 0 : b;
    tbb::task_group tasks;
    bool spawned = false;
    for (int c = 0; c < count; ++c) {
      const uint32_t k = kids[c];
      if (is_leaf_child(k)) continue;
      if (opt.parallel && planned[k].tris_below > kParallelEmit) {
        tasks.run([this, &refs, &task_counts, c, k, next, next_block] {
          refs[c] = emit(k, next, next_block, task_counts[c]);
        });
        spawned = true;
      } else {
        refs[c] = emit(k, next, next_block, counts);
      }
      next += planned[k].space.nodes;
      next_block += planned[k].space.blocks;
    }
    if (spawned) {
      tasks.wait();
      for (const Counts& t : task_counts) counts.nodes += t.nodes, counts.blocks += t.blocks;
    }
    Node& node = *reinterpret_cast<Node*>(mem() + size_t(unit) * kBlockUnit);
    clear(node);
    for (int c = 0; c < count; ++c) set_child(node, c, bin.nodes[kids[c]], refs[c]);
    node.num_children = uint32_t(count);
    return unit / 2;  // node references count 64-byte lines
  }

  void run() {
    if (bin.nodes.empty()) return;
    const BVHNode& root = bin.nodes[0];
    size_t units = 0;
    Counts counts;
    if (root.is_leaf()) {
      // A leaf root gets a node with one child; its blocks follow the node.
      planned.resize(1);
      planned[0].tris_below = root.count;
      planned[0].as_leaf = 0;
      units = kNodeUnits + kBlockUnits * blocks_for(root.count);
      out.mem.resize((units * kBlockUnit + sizeof(BVHLine) - 1) / sizeof(BVHLine));
      Node& node = *reinterpret_cast<Node*>(mem());
      clear(node);
      set_child(node, 0, root, emit_leaf(0, kNodeUnits, counts));
      node.num_children = 1;
      counts.nodes = 1;
    } else {
      const size_t n = bin.nodes.size();
      planned.resize(n);
      plan(0, 0);
      planned[0].as_leaf = 0;  // the root stays a node
      const Space s = planned[0].space;
      units = size_t(s.nodes) + s.blocks;  // the node region ends 64-byte aligned
      out.mem.resize((units * kBlockUnit + sizeof(BVHLine) - 1) / sizeof(BVHLine));
      emit(0, 0, s.nodes, counts);
    }
    out.num_nodes = counts.nodes;
    out.num_blocks = counts.blocks;
    out.bounds = AABB{root.lo, root.hi};
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
