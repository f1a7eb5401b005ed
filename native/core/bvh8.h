// Eight-wide BVH for triangle meshes, used when the CPU has AVX2: collapsed
// from the same binary SAH tree as the BVH4, one 8-wide slab test per node,
// triangles in the same Tri4 blocks and the same watertight SIMD triangle
// test as the BVH4, so hits are bit for bit those of the BVH4 and of the
// scalar test (but for the order of children whose entry distances tie
// within an ulp; bvh8_traverse.h). The traversal (bvh8_traverse.h) is
// compiled for AVX2 and FMA (bvh8_avx2.cpp) and for AVX-512
// (bvh8_avx512.cpp) in their own functions, only ever called after
// cpu_simd_level() said AVX2.
#pragma once
#include <vector>

#include "bvh4.h"

namespace tessera {

// 256 bytes, four cache lines: child boxes per axis as [lo x8][hi x8] (the
// first two lines hold x and y, the third z, the fourth the references). An
// unused child has an inverted box (lo = +inf, hi = -inf), which no ray hits.
// Child references are encoded as in the BVH4 (kBVH4LeafBit, Tri4 blocks).
struct alignas(64) BVH8Node {
  float box[6][8];
  uint32_t child[8];
  uint32_t num_children;
  uint32_t pad[7];
};
static_assert(sizeof(BVH8Node) == 256, "BVH8Node must stay 256 bytes");
// The node tests find a far plane by flipping bit 5 of its near plane's
// address (bvh8_avx2.cpp, bvh8_avx512.cpp): the boxes start the node, 64-byte aligned.
static_assert(offsetof(BVH8Node, box) == 0 && alignof(BVH8Node) == 64, "box rows must pair on 64-byte boundaries");

struct BVH8 : WideBVH<BVH8Node> {};

// As collapse_to_bvh4, with up to eight children per node.
BVH8 collapse_to_bvh8(const BVH& binary, const vec3* tri_verts, const BuildOptions& options = {});
float sah_cost(const BVH8& bvh, const BuildOptions& options = {});

// BVH8 traversal (bvh8_avx2.cpp). Call only when cpu_simd_level() == AVX2.
// Runs the AVX-512 kernels below when g_bvh8_avx512 is set (at start-up:
// cpu_has_avx512()), the AVX2 ones otherwise; both give the same hits.
template <bool kOrdered>
bool bvh8_intersect_avx2(const BVH8& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit);
bool bvh8_occluded_avx2(const BVH8& bvh, const vec3& o, const vec3& d, float tmax);

// The kernel choice; tests and benchmarks may flip it (never while tracing).
extern bool g_bvh8_avx512;

// AVX-512 traversal (bvh8_avx512.cpp). Call only when cpu_has_avx512().
template <bool kOrdered>
bool bvh8_intersect_avx512(const BVH8& bvh, const vec3& o, const vec3& d, float& tmax, BVH4Hit& hit);
bool bvh8_occluded_avx512(const BVH8& bvh, const vec3& o, const vec3& d, float tmax);

}  // namespace tessera
