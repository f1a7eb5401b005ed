#include "mesh.h"

#include <algorithm>
#include <atomic>
#include <stdexcept>

#include <tbb/parallel_for.h>

#include <new>
#include <type_traits>

#include "octahedral.h"
#include "simd.h"


namespace tessera {

size_t Mesh::memory_bytes() const {
  return tri_verts.capacity() * sizeof(vec3) + prim_ids.capacity() * sizeof(uint32_t) +
         material_slots.capacity() * sizeof(uint32_t) + corner_normals.capacity() * sizeof(uint32_t) +
         corner_uvs.capacity() * sizeof(vec2) + bvh.memory_bytes() + bvh8.memory_bytes();
}

namespace {
// What a mesh's tree is built with: Tri4 leaves.
BuildOptions tri4_leaf_options(const BuildOptions& options) {
  BuildOptions opt = options;
  if (opt.sah_block_size <= 0) opt.sah_block_size = 4;
  opt.max_leaf_size = std::clamp(opt.max_leaf_size, 1, int(4 * kBVH4MaxLeafBlocks));
  return opt;
}

// Input triangle i: kept, skipped (an index out of range or a non-finite
// corner) or degenerate (two equal corners). Triangles with two equal
// corners (common in real meshes: 2,429 of modern_hall's 31,247) cannot be
// hit (one edge function is 0, the other two exact opposites), but each one
// sent its whole Tri4 block down the exact-zero path for every ray that
// reached it: they are left out too, and counted apart.
enum class TriangleCheck { Kept, Skipped, Degenerate };
TriangleCheck check_triangle(const MeshInput& in, size_t i) {
  const uint32_t* idx = in.indices + 3 * i;
  if (!(idx[0] < in.num_vertices && idx[1] < in.num_vertices && idx[2] < in.num_vertices)) return TriangleCheck::Skipped;
  const vec3* pos = reinterpret_cast<const vec3*>(in.positions);
  const vec3 &a = pos[idx[0]], &b = pos[idx[1]], &c = pos[idx[2]];
  if (!is_finite(a) || !is_finite(b) || !is_finite(c)) return TriangleCheck::Skipped;
  return a == b || b == c || c == a ? TriangleCheck::Degenerate : TriangleCheck::Kept;
}

// The wide BLAS (BVH8 on AVX2 CPUs unless options ask for 4, else BVH4)
// collapsed from `binary` over `verts` (3 per triangle) in its leaf order.
void attach_tree(Mesh& mesh, const BVH& binary, const vec3* verts, const BuildOptions& options) {
  const BuildOptions opt = tri4_leaf_options(options);
  if (options.bvh_width != 4 && cpu_simd_level() == SimdLevel::AVX2) {
    mesh.bvh8 = collapse_to_bvh8(binary, verts, opt);
    mesh.bvh8.sah_cost = sah_cost(binary, options);
  } else {
    mesh.bvh = collapse_to_bvh4(binary, verts, opt);
    mesh.bvh.sah_cost = sah_cost(binary, options);
  }
}

// Triangle boxes for a build, from the BVH allocator (memory of an earlier
// build, no fresh pages to fault in: bvh_memory.cpp) and left unwritten:
// the caller constructs each box once, in parallel.
struct Boxes {
  size_t bytes;
  AABB* p;
  explicit Boxes(size_t n) : bytes(std::max<size_t>(n, 1) * sizeof(AABB)), p(static_cast<AABB*>(bvh_alloc_bytes(bytes))) {}
  ~Boxes() { bvh_free_bytes(p, bytes); }
  Boxes(const Boxes&) = delete;
  Boxes& operator=(const Boxes&) = delete;
};
static_assert(std::is_trivially_destructible<AABB>::value, "boxes are never destroyed");

// Per-triangle attributes stay in Blender's order (indexed by prim_ids).
void copy_attributes(Mesh& mesh, const MeshInput& in) {
  const size_t nt = in.num_triangles;
  if (in.material_slots) mesh.material_slots.assign(in.material_slots, in.material_slots + nt);
  if (in.corner_normals) {
    const vec3* n = reinterpret_cast<const vec3*>(in.corner_normals);
    mesh.corner_normals.resize(3 * nt);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, 3 * nt, 16384), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) mesh.corner_normals[i] = oct_encode(n[i]);
    });
  }
  if (in.corner_uvs) {
    const vec2* uv = reinterpret_cast<const vec2*>(in.corner_uvs);
    mesh.corner_uvs.assign(uv, uv + 3 * nt);
  }
}
}  // namespace

Mesh build_mesh(const MeshInput& in, const BuildOptions& options) {
  Mesh mesh;
  const size_t nt = in.num_triangles;
  mesh.num_input_triangles = nt;
  // Triangle boxes, written once each in parallel (no serial construction
  // of the array first); invalid triangles get an empty box and are skipped.
  Boxes boxes(nt);
  const vec3* pos = reinterpret_cast<const vec3*>(in.positions);
  std::atomic<size_t> degenerate{0};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, nt, 4096), [&](const tbb::blocked_range<size_t>& r) {
    size_t block_degenerate = 0;
    for (size_t i = r.begin(); i < r.end(); ++i) {
      AABB box;
      const TriangleCheck check = check_triangle(in, i);
      if (check == TriangleCheck::Kept)
        for (int k = 0; k < 3; ++k) box.grow(pos[in.indices[3 * i + k]]);
      block_degenerate += check == TriangleCheck::Degenerate;
      new (&boxes.p[i]) AABB(box);
    }
    degenerate += block_degenerate;
  });
  BVH binary = build_bvh(boxes.p, nt, tri4_leaf_options(options));
  const size_t kept = binary.prim_order.size();
  mesh.num_degenerate_triangles = degenerate.load();
  mesh.num_skipped_triangles = nt - kept - mesh.num_degenerate_triangles;
  // Unwritten by resize (BVHArray; zeroing them was a serial pass over 36
  // bytes per triangle): each vertex is written once, in parallel.
  static_assert(std::is_trivially_default_constructible<vec3>::value, "resize must not write the vertices");
  mesh.tri_verts.resize(3 * kept);
  mesh.prim_ids = std::move(binary.prim_order);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, kept, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const uint32_t* idx = in.indices + 3 * mesh.prim_ids[i];
      for (int k = 0; k < 3; ++k) mesh.tri_verts[3 * i + k] = pos[idx[k]];
    }
  });
  attach_tree(mesh, binary, mesh.tri_verts.data(), options);
  BVHArray<vec3>().swap(mesh.tri_verts);  // the Tri4 blocks hold them now
  copy_attributes(mesh, in);
  return mesh;
}

Mesh prepare_mesh(const MeshInput& in) {
  Mesh mesh;
  const size_t nt = in.num_triangles;
  mesh.num_input_triangles = nt;
  const vec3* pos = reinterpret_cast<const vec3*>(in.positions);
  // Two parallel passes over fixed blocks of triangles (the same result for
  // any thread count): the checks, counting each block's kept triangles;
  // then each block writes its kept ones, in input order, at the offset the
  // blocks before it give (a prefix sum), and bounds them.
  constexpr size_t kBlock = 4096;
  const size_t nblocks = (nt + kBlock - 1) / kBlock;
  struct Block {
    size_t kept = 0, degenerate = 0, offset = 0;
    AABB bounds;
  };
  std::vector<Block> blocks(nblocks);
  std::vector<uint8_t> keep(nt);
  tbb::parallel_for(size_t(0), nblocks, [&](size_t b) {
    Block& blk = blocks[b];
    for (size_t i = b * kBlock, e = std::min(nt, i + kBlock); i < e; ++i) {
      const TriangleCheck check = check_triangle(in, i);
      keep[i] = check == TriangleCheck::Kept;
      blk.kept += keep[i];
      blk.degenerate += check == TriangleCheck::Degenerate;
    }
  });
  size_t kept = 0, degenerate = 0;
  for (Block& blk : blocks) blk.offset = kept, kept += blk.kept, degenerate += blk.degenerate;
  mesh.num_degenerate_triangles = degenerate;
  mesh.num_skipped_triangles = nt - kept - degenerate;
  mesh.prim_ids.resize(kept);
  mesh.tri_verts.resize(3 * kept);
  tbb::parallel_for(size_t(0), nblocks, [&](size_t b) {
    Block& blk = blocks[b];
    size_t o = blk.offset;
    AABB box;
    for (size_t i = b * kBlock, e = std::min(nt, i + kBlock); i < e; ++i) {
      if (!keep[i]) continue;
      mesh.prim_ids[o] = uint32_t(i);
      const uint32_t* idx = in.indices + 3 * i;
      for (int k = 0; k < 3; ++k) box.grow(mesh.tri_verts[3 * o + k] = pos[idx[k]]);
      ++o;
    }
    blk.bounds = box;
  });
  AABB bounds;
  for (const Block& blk : blocks) bounds.grow(blk.bounds);
  mesh.bvh.bounds = bounds;  // Mesh::bounds() without a tree
  copy_attributes(mesh, in);
  return mesh;
}

void build_mesh_bvh(Mesh& mesh, const BuildOptions& options) {
  if (mesh.has_bvh() || mesh.prim_ids.empty()) return;
  const size_t n = mesh.prim_ids.size();
  Boxes boxes(n);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      AABB box;
      for (int k = 0; k < 3; ++k) box.grow(mesh.tri_verts[3 * i + k]);
      new (&boxes.p[i]) AABB(box);
    }
  });
  BVH binary = build_bvh(boxes.p, n, tri4_leaf_options(options));
  // Leaf order: binary.prim_order indexes the prepared order (copied in
  // parallel, as build_mesh does).
  const size_t kept = binary.prim_order.size();
  BVHArray<vec3> verts;
  verts.resize(3 * kept);
  std::vector<uint32_t> ids(kept);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, kept, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const uint32_t j = binary.prim_order[i];
      ids[i] = mesh.prim_ids[j];
      for (int k = 0; k < 3; ++k) verts[3 * i + k] = mesh.tri_verts[3 * j + k];
    }
  });
  mesh.prim_ids.swap(ids);
  attach_tree(mesh, binary, verts.data(), options);
  BVHArray<vec3>().swap(mesh.tri_verts);  // the Tri4 blocks hold them now
}

bool intersect_mesh(const Mesh& mesh, const vec3& o, const vec3& d, float& tmax, MeshHit& hit, TraversalOrder order) {
  BVH4Hit h;
  if (!mesh.bvh8.empty()) {
    const bool found = order == TraversalOrder::Ordered ? bvh8_intersect_avx2<true>(mesh.bvh8, o, d, tmax, h)
                                                        : bvh8_intersect_avx2<false>(mesh.bvh8, o, d, tmax, h);
    if (found) hit = {h.t, h.u, h.v, h.prim, h.tri, h.lane};
    return found;
  }
  const bool found = order == TraversalOrder::Ordered ? bvh4_intersect<true>(mesh.bvh, o, d, tmax, h)
                                                      : bvh4_intersect<false>(mesh.bvh, o, d, tmax, h);
  if (found) hit = {h.t, h.u, h.v, h.prim, h.tri, h.lane};
  return found;
}

bool occluded_mesh(const Mesh& mesh, const vec3& o, const vec3& d, float tmax) {
  if (!mesh.bvh8.empty()) return bvh8_occluded_avx2(mesh.bvh8, o, d, tmax);
  return bvh4_occluded(mesh.bvh, o, d, tmax);
}

namespace {
// Every leaf block of a wide tree, its lanes' vertices written at their
// leaf-order index (the spare lanes repeat a triangle: the same values).
template <typename Tree>
void read_leaf_blocks(const Tree& tree, std::vector<vec3>& out) {
  if (tree.empty()) return;
  std::vector<uint32_t> stack{0u};
  while (!stack.empty()) {
    const auto& n = tree.node(stack.back());
    stack.pop_back();
    for (uint32_t c = 0; c < n.num_children; ++c) {
      const uint32_t ref = n.child[c];
      if (!bvh4_is_leaf(ref)) {
        stack.push_back(ref);
        continue;
      }
      const Tri4* blocks = tree.blocks(ref);
      for (uint32_t b = 0; b < bvh4_leaf_blocks(ref); ++b)
        for (int lane = 0; lane < 4; ++lane)
          for (int k = 0; k < 3; ++k) out[3 * size_t(blocks[b].prim[lane]) + k] = blocks[b].vertex(k, lane);
    }
  }
}
}  // namespace

std::vector<vec3> leaf_order_vertices(const Mesh& mesh) {
  if (!mesh.tri_verts.empty()) return std::vector<vec3>(mesh.tri_verts.begin(), mesh.tri_verts.end());
  if (!mesh.prim_ids.empty() && !mesh.has_bvh())
    throw std::logic_error(
        "leaf_order_vertices: this mesh's vertices live in the render-space BVH of the scene that merged it at "
        "commit(); read the scene's meshes before committing it");
  return leaf_block_vertices(mesh, mesh.prim_ids.size());
}

std::vector<vec3> leaf_block_vertices(const Mesh& mesh, size_t num_triangles) {
  std::vector<vec3> out(3 * num_triangles);
  if (!mesh.bvh8.empty()) read_leaf_blocks(mesh.bvh8, out);
  else read_leaf_blocks(mesh.bvh, out);
  return out;
}

float mesh_sah_cost(const Mesh& mesh) { return mesh.bvh8.empty() ? mesh.bvh.sah_cost : mesh.bvh8.sah_cost; }

}  // namespace tessera
