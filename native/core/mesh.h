// A triangle mesh in its own (object) space with its BVH: the bottom level
// (BLAS) of the two-level acceleration structure. Stored once however many
// instances use it. Once it has a tree, its vertices live only in the tree's
// Tri4 leaf blocks (in BVH leaf order, a leaf one contiguous run of memory),
// where traversal tests them and shading reads the hit's; attributes stay in
// Blender's triangle order and are reached through prim_ids only when a hit
// is shaded.
#pragma once
#include <string>
#include <vector>
#include "bvh.h"
#include "bvh4.h"
#include "bvh8.h"
#include "triangle.h"

namespace tessera {

struct MeshInput {
  const float* positions = nullptr;       // 3 per vertex
  size_t num_vertices = 0;
  const uint32_t* indices = nullptr;      // 3 per triangle
  size_t num_triangles = 0;
  const uint32_t* material_slots = nullptr;  // 1 per triangle, or null (all slot 0)
  const float* corner_normals = nullptr;  // 9 per triangle (smooth shading), or null (flat)
  const float* corner_uvs = nullptr;      // 6 per triangle, or null (no UV map needed)
};

struct Mesh {
  // 3 per triangle (resize leaves them unwritten), only while the mesh has
  // no tree (prepare_mesh): the tree's build moves them into its Tri4
  // blocks and frees them, and Scene::commit frees those of the meshes it
  // merged into its render-space BLAS. leaf_order_vertices reads either.
  BVHArray<vec3> tri_verts;
  std::vector<uint32_t> prim_ids;       // leaf order -> Blender triangle index
  std::vector<uint32_t> material_slots; // Blender order; empty: all slot 0
  std::vector<uint32_t> corner_normals; // Blender order, 3 per triangle, octahedral (octahedral.h); empty: flat
  std::vector<vec2> corner_uvs;         // Blender order, 3 per triangle; empty: none
  // The BLAS over tri_verts (leaves: contiguous ranges), one of: the SSE2
  // four-wide BVH4, or the AVX2 eight-wide BVH8 (BuildOptions::bvh_width).
  BVH4 bvh;
  BVH8 bvh8;
  size_t num_input_triangles = 0;
  size_t num_skipped_triangles = 0;     // non-finite or out-of-range vertices
  size_t num_degenerate_triangles = 0;  // two equal corners: never hit, left out

  AABB bounds() const { return bvh8.empty() ? bvh.bounds : bvh8.bounds; }
  bool has_bvh() const { return !bvh8.empty() || !bvh.empty(); }
  int width() const { return bvh8.empty() ? 4 : 8; }
  uint32_t slot(uint32_t prim_id) const { return material_slots.empty() ? 0 : material_slots[prim_id]; }
  size_t memory_bytes() const;
};

// Validates the input (indices in range, finite positions), builds the BVH
// and stores the triangles in leaf order. Invalid triangles are skipped and
// counted, never stored.
Mesh build_mesh(const MeshInput& in, const BuildOptions& options = {});

// The same validation and triangles without a BVH (input order; bounds()
// works): Scene::commit builds trees only for the meshes it does not merge
// into its render-space BLAS, so a scene's single-use meshes are not built
// twice.
Mesh prepare_mesh(const MeshInput& in);
// Builds a prepared mesh's BVH, putting its triangles in leaf order; does
// nothing if it has one.
void build_mesh_bvh(Mesh& mesh, const BuildOptions& options = {});

struct MeshHit {
  float t, u, v;
  uint32_t prim;    // leaf-order index
  const Tri4* tri;  // the vertices: lane `lane` of this leaf block (Tri4::vertex)
  uint32_t lane;
};

// The mesh's triangles in leaf order, 3 vertices each: tri_verts, or read
// back from the tree's leaf blocks (a walk over the tree; for set-up and
// tests, not per ray).
std::vector<vec3> leaf_order_vertices(const Mesh& mesh);
// The tree's leaf blocks alone, for a tree over num_triangles (the merged
// BLAS keeps no prim_ids).
std::vector<vec3> leaf_block_vertices(const Mesh& mesh, size_t num_triangles);

// Children visited nearest first (default) or in stored order (for benchmarks).
enum class TraversalOrder { Ordered, Unordered };

// Closest hit in object space. ray.tmax shrinks to the hit distance.
bool intersect_mesh(const Mesh& mesh, const vec3& o, const vec3& d, float& tmax, MeshHit& hit,
                    TraversalOrder order = TraversalOrder::Ordered);
// Any hit before tmax.
bool occluded_mesh(const Mesh& mesh, const vec3& o, const vec3& d, float tmax);

// SAH cost (relative to the root area) of the binary tree the mesh's BVH4 was
// collapsed from, computed at build time with the build options' costs.
float mesh_sah_cost(const Mesh& mesh);

}  // namespace tessera
