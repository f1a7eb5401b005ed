#include "mesh.h"

#include <tbb/parallel_for.h>

#include "traverse.h"

namespace tessera {

size_t Mesh::memory_bytes() const {
  return tri_verts.capacity() * sizeof(vec3) + prim_ids.capacity() * sizeof(uint32_t) +
         material_slots.capacity() * sizeof(uint32_t) + corner_normals.capacity() * sizeof(vec3) +
         corner_uvs.capacity() * sizeof(vec2) + bvh.memory_bytes();
}

Mesh build_mesh(const MeshInput& in, const BuildOptions& options) {
  Mesh mesh;
  const size_t nt = in.num_triangles;
  mesh.num_input_triangles = nt;
  std::vector<AABB> boxes(nt);
  const vec3* pos = reinterpret_cast<const vec3*>(in.positions);
  tbb::parallel_for(size_t(0), nt, [&](size_t i) {
    const uint32_t* idx = in.indices + 3 * i;
    if (idx[0] >= in.num_vertices || idx[1] >= in.num_vertices || idx[2] >= in.num_vertices) return;
    AABB box;
    for (int k = 0; k < 3; ++k) {
      if (!is_finite(pos[idx[k]])) return;  // box stays empty: the triangle is skipped
      box.grow(pos[idx[k]]);
    }
    boxes[i] = box;
  });
  mesh.bvh = build_bvh(boxes, options);
  const size_t kept = mesh.bvh.prim_order.size();
  mesh.num_skipped_triangles = nt - kept;
  mesh.tri_verts.resize(3 * kept);
  mesh.prim_ids = mesh.bvh.prim_order;
  tbb::parallel_for(size_t(0), kept, [&](size_t i) {
    const uint32_t* idx = in.indices + 3 * mesh.prim_ids[i];
    for (int k = 0; k < 3; ++k) mesh.tri_verts[3 * i + k] = pos[idx[k]];
  });
  // The BVH's own order array is now the mesh's prim_ids; do not keep it twice.
  mesh.bvh.prim_order = {};
  if (in.material_slots) mesh.material_slots.assign(in.material_slots, in.material_slots + nt);
  if (in.corner_normals) {
    const vec3* n = reinterpret_cast<const vec3*>(in.corner_normals);
    mesh.corner_normals.assign(n, n + 3 * nt);
  }
  if (in.corner_uvs) {
    const vec2* uv = reinterpret_cast<const vec2*>(in.corner_uvs);
    mesh.corner_uvs.assign(uv, uv + 3 * nt);
  }
  return mesh;
}

template <bool kAnyHit>
static bool trace_mesh(const Mesh& mesh, const vec3& o, const vec3& d, float& tmax, MeshHit* hit) {
  if (mesh.bvh.nodes.empty()) return false;
  TraversalRay ray(o, d, tmax);
  const RayShear shear(d);
  const vec3* verts = mesh.tri_verts.data();
  bool found = traverse<kAnyHit>(mesh.bvh.nodes.data(), ray, [&](uint32_t first, uint32_t count, TraversalRay& r) {
    bool any = false;
    for (uint32_t i = first; i < first + count; ++i) {
      TriangleHit th;
      if (intersect_triangle(verts[3 * i], verts[3 * i + 1], verts[3 * i + 2], r.o, shear, r.tmax, th)) {
        r.tmax = th.t;
        any = true;
        if (kAnyHit) return true;
        *hit = {th.t, th.u, th.v, i};
      }
    }
    return any;
  });
  tmax = ray.tmax;
  return found;
}

bool intersect_mesh(const Mesh& mesh, const vec3& o, const vec3& d, float& tmax, MeshHit& hit) {
  return trace_mesh<false>(mesh, o, d, tmax, &hit);
}

bool occluded_mesh(const Mesh& mesh, const vec3& o, const vec3& d, float tmax) {
  return trace_mesh<true>(mesh, o, d, tmax, nullptr);
}

}  // namespace tessera
