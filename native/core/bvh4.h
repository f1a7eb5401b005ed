// Four-wide BVH for triangle meshes (the BLAS), collapsed from the binary SAH
// tree, with SSE box tests for the four children at once and triangles stored
// four at a time (structure of arrays) for a SIMD version of the watertight
// test in triangle.h. Every lane does exactly the float operations of the
// scalar intersect_triangle, in the same order, so the results are bit for
// bit those of the scalar test: watertightness carries over unchanged.
#pragma once
#include <cstddef>
#include <emmintrin.h>

#include <vector>

#include "bvh.h"
#include "triangle.h"

namespace tessera {

// 128 bytes, two cache lines. Child boxes per axis as [lo x4][hi x4]; an
// unused child has an inverted box (lo = +inf, hi = -inf), which no ray hits.
struct alignas(64) BVH4Node {
  float box[6][4];      // lo_x, hi_x, lo_y, hi_y, lo_z, hi_z; one lane per child
  uint32_t child[4];    // interior: node offset / 64; leaf: kLeafBit | first block offset / 32 << 3 | (blocks - 1)
  uint32_t num_children;
  uint32_t pad[3];
};
static_assert(sizeof(BVH4Node) == 128, "BVH4Node must stay 128 bytes");
// The node tests find a far plane by flipping bit 4 of its near plane's
// address (bvh4.cpp, intersect_node): the boxes start the node, 64-byte aligned.
static_assert(offsetof(BVH4Node, box) == 0 && alignof(BVH4Node) == 64, "box rows must pair on 32-byte boundaries");

constexpr uint32_t kBVH4LeafBit = 0x80000000u;
constexpr uint32_t kBVH4EmptyChild = 0xFFFFFFFFu;
constexpr uint32_t kBVH4MaxLeafBlocks = 8;
inline bool bvh4_is_leaf(uint32_t ref) { return ref & kBVH4LeafBit; }
inline uint32_t bvh4_leaf_first(uint32_t ref) { return (ref & ~kBVH4LeafBit) >> 3; }
inline uint32_t bvh4_leaf_blocks(uint32_t ref) { return (ref & 7u) + 1; }

// Four triangles of one leaf: v[vertex][axis][lane]. A leaf whose size is not a
// multiple of four repeats its last triangle in the spare lanes.
struct alignas(16) Tri4 {
  float v[3][3][4];
  uint32_t prim[4];  // leaf-order triangle index (Mesh::prim_ids)

  vec3 vertex(int k, int lane) const { return vec3(v[k][0][lane], v[k][1][lane], v[k][2][lane]); }
};
static_assert(sizeof(Tri4) == 160, "Tri4 must stay 160 bytes");

// The nodes and Tri4 blocks of a wide BVH share one array, each node followed
// by the blocks of its leaf children (Embree's allocation order), so the lines
// after a node, which the hardware prefetcher streams in with it, are its
// leaves. Node references count 64-byte lines from the start (nodes are
// cache-line aligned; the root is at 0), leaf references 32-byte units.
struct alignas(64) BVHLine {
  unsigned char bytes[64];
};
constexpr size_t kNodeUnit = 64;
constexpr size_t kBlockUnit = 32;

template <typename Node>
struct WideBVH {
  BVHArray<BVHLine> mem;
  uint32_t num_nodes = 0, num_blocks = 0;
  AABB bounds;
  float sah_cost = 0.0f;  // of the binary tree it was collapsed from

  bool empty() const { return num_nodes == 0; }
  const char* base() const { return reinterpret_cast<const char*>(mem.data()); }
  const Node& node(uint32_t ref) const { return *reinterpret_cast<const Node*>(base() + size_t(ref) * kNodeUnit); }
  // The first of a leaf's bvh4_leaf_blocks(ref) consecutive blocks.
  const Tri4* blocks(uint32_t leaf_ref) const {
    return reinterpret_cast<const Tri4*>(base() + size_t(bvh4_leaf_first(leaf_ref)) * kBlockUnit);
  }
  size_t memory_bytes() const { return mem.capacity() * sizeof(BVHLine); }
  int depth() const;
};

struct BVH4 : WideBVH<BVH4Node> {};

// Collapses a binary BVH whose leaves index triangles in leaf order
// (tri_verts: 3 per triangle, that order) into a BVH4: each node takes the
// children of its largest-area descendants until it has four.
BVH4 collapse_to_bvh4(const BVH& binary, const vec3* tri_verts, const BuildOptions& options = {});

// SAH cost of a BVH4 (one traversal step per node visit, one per Tri4 block),
// relative to the root area.
float sah_cost(const BVH4& bvh, const BuildOptions& options = {});

struct BVH4Hit {
  float t, u, v;
  uint32_t prim;
  // Where the hit triangle's vertices are: lane `lane` of the Tri4 block
  // `tri` (shading reads them there; the mesh keeps no other copy).
  const Tri4* tri;
  uint32_t lane;
};

// Closest hit before tmax (tmax shrinks); kOrdered visits children nearest first.
template <bool kOrdered>
bool bvh4_intersect(const BVH4& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit);
// Any hit before tmax.
bool bvh4_occluded(const BVH4& bvh, const vec3& o, const vec3& d, float tmax);

}  // namespace tessera
