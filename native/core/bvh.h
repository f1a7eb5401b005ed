// Bounding volume hierarchy over boxes: the builders (midpoint, full-sweep SAH,
// binned SAH) and the node layout. One array of 32-byte nodes; a leaf names a
// contiguous range of the reordered primitives, an interior node its first
// child (the second follows it). Used for the per-mesh BLAS and the TLAS.
#pragma once
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include "aabb.h"

namespace tessera {

// Allocator for the node and triangle block arrays: arrays of 2 MB
// or more are 2 MB aligned and their whole 2 MB pages marked MADV_HUGEPAGE
// before first touch, so that incoherent rays over a large mesh miss the TLB
// far less often (Embree's "hugepages" option; the kernel may decline, which
// only costs speed). Freed ones stay mapped, up to a limit, for the next
// build's arrays (bvh_memory.cpp: first touches of fresh pages do not scale
// with threads).
void* bvh_alloc_bytes(size_t bytes);
void bvh_free_bytes(void* p, size_t bytes);
// Bytes of freed arrays kept mapped for reuse (at most kBVHRetainBytes), and
// their release (unmapped).
constexpr size_t kBVHRetainBytes = size_t(256) << 20;
size_t bvh_retained_bytes();
void bvh_release_retained();
template <typename T>
struct LargePageAllocator {
  using value_type = T;
  LargePageAllocator() = default;
  template <typename U>
  LargePageAllocator(const LargePageAllocator<U>&) {}
  T* allocate(size_t n) { return static_cast<T*>(bvh_alloc_bytes(n * sizeof(T))); }
  void deallocate(T* p, size_t n) { bvh_free_bytes(p, n * sizeof(T)); }
  // resize() default-initialises (no zeroing of arrays that are written anyway).
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) { ::new (static_cast<void*>(p)) U; }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) { ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...); }
  template <typename U>
  bool operator==(const LargePageAllocator<U>&) const { return true; }
  template <typename U>
  bool operator!=(const LargePageAllocator<U>&) const { return false; }
};
template <typename T>
using BVHArray = std::vector<T, LargePageAllocator<T>>;


struct BVHNode {
  vec3 lo;
  uint32_t first;  // leaf: first primitive; interior: index of the left child
  vec3 hi;
  uint32_t count;  // leaf: primitive count (> 0); interior: 0
  bool is_leaf() const { return count > 0; }
};
static_assert(sizeof(BVHNode) == 32, "BVHNode must stay 32 bytes");

enum class SplitMethod { Midpoint, SweepSAH, BinnedSAH };

struct BuildOptions {
  SplitMethod method = SplitMethod::BinnedSAH;
  int bins = 32;            // binned SAH only (Embree's object binning uses 32 too)
  // A leaf never holds more, unless primitives are inseparable. 4: one Tri4
  // block per mesh leaf, so the collapse can fill the wide nodes down to
  // single blocks (as Embree's BVH8 builder, whose leaves are 95% one block).
  int max_leaf_size = 4;
  float traversal_cost = 1.0f;
  float intersection_cost = 1.0f;
  // SAH leaf cost counts primitives in blocks of this many (SIMD leaves test
  // four triangles at once). 0: automatic (1 for build_bvh, 4 for build_mesh).
  int sah_block_size = 0;
  bool parallel = true;     // TBB tasks for large subtrees
  // Mesh BLAS width: 0 = automatic (8, the AVX2 BVH8, when the CPU has AVX2;
  // else 4, the SSE2 BVH4), 4 or 8 (8 falls back to 4 without AVX2).
  int bvh_width = 0;
  // Wide BVHs: a binary subtree that the wide SAH prices lower as one leaf of
  // packed Tri4 blocks (at most two) than as a wide node of its own is
  // collapsed into one (off: every binary leaf is a leaf, every interior
  // node that is not opened into its parent a node).
  bool collapse_small_subtrees = true;
  // Wide BVHs: each node's leaf blocks stored right after it (off: all nodes
  // first, then all blocks, both in depth-first order).
  bool leaves_next_to_parent = true;
};

// The nodes are those reached from nodes[0]: the binned builder may leave
// unused slots between the parts that parallel tasks built (never read,
// never touched), so the array is not a list of the tree's nodes.
struct BVH {
  BVHArray<BVHNode> nodes;
  std::vector<uint32_t> prim_order;  // prim_order[i] = input index of the i-th reordered primitive
  // Summed by the binned builder (in a fixed order): the half areas of the
  // interior nodes, and of the leaves times their counts; sah_cost() needs no
  // pass over the nodes. Negative: not summed (sah_cost walks the tree).
  double sah_inner_area = -1.0, sah_leaf_area = 0.0;

  const AABB bounds() const { return nodes.empty() ? AABB{} : AABB{nodes[0].lo, nodes[0].hi}; }
  size_t memory_bytes() const { return nodes.capacity() * sizeof(BVHNode) + prim_order.capacity() * sizeof(uint32_t); }
  int depth() const;
};

// Builds a BVH over primitives given by their bounds (centroids are the box
// centres). Empty boxes (degenerate or invalid primitives) are kept out of the tree.
BVH build_bvh(const std::vector<AABB>& prim_bounds, const BuildOptions& options = {});
// The same over an array of count boxes (build_mesh fills one in parallel).
BVH build_bvh(const AABB* prim_bounds, size_t count, const BuildOptions& options = {});

// SAH cost of a built tree, relative to its root area (MacDonald & Booth 1990).
float sah_cost(const BVH& bvh, const BuildOptions& options = {});

}  // namespace tessera
