#include "scene.h"

#include <algorithm>
#include <array>
#include <cstring>

#include <tbb/parallel_for.h>

#include "octahedral.h"
#include "traverse.h"

namespace tessera {

uint32_t Scene::add_instance(uint32_t mesh, const mat4& to_world, const std::vector<uint32_t>& slot_materials,
                             uint8_t visibility) {
  Instance inst;
  inst.visibility = visibility & kVisibleToAll;
  inst.mesh = mesh;
  inst.to_world = to_world;
  inst.to_local = glm::inverse(to_world);
  inst.normal_to_world = glm::transpose(glm::mat3(inst.to_local));
  inst.identity = to_world == mat4(1.0f);
  inst.mirrored = glm::determinant(glm::mat3(to_world)) < 0.0f;
  inst.material_offset = uint32_t(instance_materials.size());
  inst.num_slots = uint32_t(slot_materials.size());
  instance_materials.insert(instance_materials.end(), slot_materials.begin(), slot_materials.end());
  instances.push_back(inst);
  return uint32_t(instances.size() - 1);
}

static AABB transform_box(const AABB& b, const mat4& m) {
  AABB out;
  if (b.empty()) return out;
  for (int i = 0; i < 8; ++i) {
    vec3 c((i & 1) ? b.hi.x : b.lo.x, (i & 2) ? b.hi.y : b.lo.y, (i & 4) ? b.hi.z : b.lo.z);
    out.grow(vec3(m * vec4(c, 1.0f)));
  }
  return out;
}

namespace {

// Joins the emissive triangles out[first ..] of one instance into rectangles
// (EmissiveTriangle::second) where two of them make one: the same material,
// the same hypotenuse (its two vertices the same in the mesh, bit for bit:
// a quad's diagonal), right angles opposite each other and facing the same
// way. `local` holds each one's mesh vertices, `material` its material.
void join_rectangles(std::vector<EmissiveTriangle>& out, size_t first, const std::vector<const vec3*>& local,
                     const std::vector<uint32_t>& material) {
  struct Corner {
    vec3 r, a, b;  // the right angle's vertex and its two edges (world)
  };
  const size_t n = out.size() - first;
  std::vector<Corner> corner(n);
  // (material, hypotenuse's vertices in the mesh) -> triangle, sorted to find pairs.
  std::vector<std::pair<std::array<uint32_t, 7>, uint32_t>> keyed;
  for (size_t j = 0; j < n; ++j) {
    const EmissiveTriangle& t = out[first + j];
    const vec3 at_corner[3][3] = {{t.p0, t.e1, t.e2}, {t.p0 + t.e1, -t.e1, t.e2 - t.e1}, {t.p0 + t.e2, -t.e2, t.e1 - t.e2}};
    for (int c = 0; c < 3; ++c) {
      const vec3 &a = at_corner[c][1], &b = at_corner[c][2];
      if (!(std::abs(glm::dot(a, b)) <= 1e-5f * glm::length(a) * glm::length(b))) continue;
      corner[j] = {at_corner[c][0], a, b};
      vec3 h0 = local[j][(c + 1) % 3], h1 = local[j][(c + 2) % 3];
      std::array<uint32_t, 7> key{material[j]};
      if (std::lexicographical_compare(&h1.x, &h1.x + 3, &h0.x, &h0.x + 3)) std::swap(h0, h1);
      std::memcpy(&key[1], &h0.x, 12);
      std::memcpy(&key[4], &h1.x, 12);
      keyed.push_back({key, uint32_t(j)});
      break;
    }
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<bool> joined(n, false);
  for (size_t k = 0; k + 1 < keyed.size(); ++k) {
    // Exactly two triangles on that edge with that material.
    if (keyed[k].first != keyed[k + 1].first || (k + 2 < keyed.size() && keyed[k + 2].first == keyed[k].first) ||
        (k > 0 && keyed[k - 1].first == keyed[k].first))
      continue;
    const uint32_t i = keyed[k].second, j = keyed[k + 1].second;
    EmissiveTriangle &ti = out[first + i], &tj = out[first + j];
    const Corner &ci = corner[i], &cj = corner[j];
    // j's right angle is the fourth corner of i's rectangle, and both face the same way.
    const vec3 fourth = ci.r + ci.a + ci.b;
    const float tol = 1e-5f * (glm::length(ci.a) + glm::length(ci.b)) + 1e-6f * max_component(abs(fourth));
    if (!(glm::length(cj.r - fourth) <= tol) || !(glm::dot(ti.n, tj.n) > 0.99999f)) continue;
    const vec3 c = glm::cross(ci.a, ci.b);
    ti.p0 = ci.r, ti.e1 = ci.a, ti.e2 = ci.b;
    ti.area = glm::length(c);
    ti.second = tj.prim;
    ti.local_error = std::max(ti.local_error, tj.local_error);
    joined[j] = true;
    ++k;
  }
  size_t w = first;
  for (size_t j = 0; j < n; ++j)
    if (!joined[j]) out[w++] = out[first + j];
  out.resize(w);
}

}  // namespace

std::vector<EmissiveTriangle> Scene::collect_emissive_triangles() const {
  std::vector<EmissiveTriangle> out;
  // Object-space vertices of the meshes with emitters, read once per mesh
  // however many instances place it (the merged meshes' are still there:
  // release_merged_meshes runs after this).
  std::vector<std::vector<vec3>> verts_of(meshes.size());
  for (uint32_t i = 0; i < instances.size(); ++i) {
    const Instance& inst = instances[i];
    bool any = false;
    for (uint32_t s = 0; s < inst.num_slots; ++s) any |= materials[material_of(inst, s)].is_emissive();
    if (!any && !materials[0].is_emissive()) continue;
    if (!(inst.visibility & kScatteredRays)) continue;  // no ray it lights would see it (Cycles: not a light)
    const Mesh& mesh = meshes[inst.mesh];
    std::vector<vec3>& verts = verts_of[inst.mesh];
    const size_t first = out.size();
    std::vector<const vec3*> mesh_verts;
    std::vector<uint32_t> material;
    for (uint32_t k = 0; k < mesh.prim_ids.size(); ++k) {
      const uint32_t mi = material_of(inst, mesh.slot(mesh.prim_ids[k]));
      const Material& m = materials[mi];
      if (!m.is_emissive()) continue;
      if (verts.empty()) verts = leaf_order_vertices(mesh);
      // Edges from the local-space edges through the linear part of the
      // transform, not as differences of world-space vertices: far from the
      // origin those are rounded to the float spacing there (1/128 at 1e5),
      // which shrank a 0.6-wide light quad's area by 2%, and its light with it.
      const vec3* v = &verts[3 * size_t(k)];
      const glm::mat3 linear(inst.to_world);
      const vec3 p0 = vec3(inst.to_world * vec4(v[0], 1.0f));
      const vec3 e1 = linear * (v[1] - v[0]), e2 = linear * (v[2] - v[0]);
      // The front is where Scene::interaction's normal (normal transform of
      // the local normal) points; the cross product of transformed edges is
      // that times det, so a mirroring transform would flip it.
      vec3 c = glm::cross(e1, e2);
      if (inst.mirrored) c = -c;
      float len = glm::length(c);
      if (!(len > 0.0f) || !std::isfinite(len) || !is_finite(p0)) continue;
      // The shadow ray's end, tested in the instance's space: as
      // shadow_end_error (lights.cpp) for the local magnitudes.
      const float local = std::max({max_component(abs(v[0])), max_component(abs(v[1])),
                                    max_component(abs(v[2]))});
      const float stretch = std::max({glm::length(linear[0]), glm::length(linear[1]), glm::length(linear[2])});
      const float local_error = 2.0f * gamma(8) * local * stretch;
      out.push_back({p0, e1, e2, c / len, 0.5f * len, m.emission_front, m.emission_back, i, k, local_error});
      out.back().visibility = inst.visibility;
      mesh_verts.push_back(v);
      material.push_back(mi);
    }
    join_rectangles(out, first, mesh_verts, material);
  }
  return out;
}

void Scene::rebase_on_camera() {
  const vec3 c(camera.to_world[3]);
  if (!is_finite(c) || max_component(abs(c)) < kRebaseDistance) return;
  // Differences of floats are exact in double: one rounding to float each.
  auto relative = [&](const vec3& p) { return vec3(glm::dvec3(p) - glm::dvec3(c)); };
  for (Instance& inst : instances) {
    mat4 m = inst.to_world;
    m[3] = vec4(relative(vec3(m[3])), 1.0f);
    inst.to_world = m;
    inst.to_local = glm::inverse(m);
    inst.normal_to_world = glm::transpose(glm::mat3(inst.to_local));
    inst.identity = m == mat4(1.0f);
  }
  for (Light& l : lights) l.position = relative(l.position);
  camera.to_world[3] = vec4(0.0f, 0.0f, 0.0f, 1.0f);
  render_origin = vec3(glm::dvec3(render_origin) + glm::dvec3(c));
}

// Instances whose mesh no other instance places move into merged_, if
// there are at least two or the one has a transform (a lone instance
// placed as its mesh is would only be copied; a transformed one, merged,
// takes no ray into object space and no hit back to world space: McGuire's
// Cornell box, one object); tlas_items receives the others. Instances
// whose transform has no finite inverse stay: the TLAS skips them, as it
// always did.
void Scene::merge_single_use_instances(std::vector<uint32_t>& tlas_items) {
  merged_ = Mesh{};
  merged_owner_.clear();
  merged_instances_.clear();
  std::vector<uint32_t> uses(meshes.size(), 0);
  for (const Instance& inst : instances) ++uses[inst.mesh];
  std::vector<uint32_t> single;
  std::vector<size_t> first{0};  // merged input index of each single instance's first triangle
  for (uint32_t i = 0; i < instances.size(); ++i) {
    const Instance& inst = instances[i];
    const bool invertible = std::isfinite(glm::determinant(inst.to_local)) && is_finite(vec3(inst.to_local[0])) &&
                            is_finite(vec3(inst.to_local[1])) && is_finite(vec3(inst.to_local[2])) &&
                            is_finite(vec3(inst.to_local[3]));
    if (uses[inst.mesh] == 1 && invertible && inst.visibility == kVisibleToAll && !meshes[inst.mesh].prim_ids.empty()) {
      single.push_back(i);
      first.push_back(first.back() + meshes[inst.mesh].prim_ids.size());
    } else {
      tlas_items.push_back(i);
    }
  }
  if (single.empty() || (single.size() == 1 && instances[single[0]].identity)) {
    tlas_items.insert(tlas_items.end(), single.begin(), single.end());
    return;
  }
  // Render-space triangles, each instance's in its mesh's leaf order: from
  // tri_verts (meshes added without a tree, prepare_mesh), or read back
  // from the leaf blocks of a mesh built with one.
  std::vector<std::vector<vec3>> read_back(single.size());
  tbb::parallel_for(size_t(0), single.size(), [&](size_t s) {
    const Mesh& mesh = meshes[instances[single[s]].mesh];
    if (mesh.tri_verts.empty()) read_back[s] = leaf_order_vertices(mesh);
  });
  const size_t n = first.back();
  std::vector<vec3> verts(3 * n);
  std::vector<uint32_t> indices(3 * n);
  std::vector<MergedOwner> owner(n);
  tbb::parallel_for(size_t(0), single.size(), [&](size_t s) {
    const uint32_t i = single[s];
    const Instance& inst = instances[i];
    const Mesh& mesh = meshes[inst.mesh];
    const vec3* src = read_back[s].empty() ? mesh.tri_verts.data() : read_back[s].data();
    for (size_t k = 0; k < mesh.prim_ids.size(); ++k) {
      const size_t j = first[s] + k;
      for (int c = 0; c < 3; ++c) {
        const vec3& v = src[3 * k + c];
        verts[3 * j + c] = inst.identity ? v : vec3(inst.to_world * vec4(v, 1.0f));
        indices[3 * j + c] = uint32_t(3 * j + c);
      }
      owner[j] = {i, uint32_t(k)};
    }
  });
  MeshInput in;
  in.positions = &verts[0].x;
  in.num_vertices = verts.size();
  in.indices = indices.data();
  in.num_triangles = n;
  merged_ = build_mesh(in);
  merged_owner_.resize(merged_.prim_ids.size());
  for (size_t j = 0; j < merged_owner_.size(); ++j) merged_owner_[j] = owner[merged_.prim_ids[j]];
  // The merged tree's Tri4 blocks carry the vertices, which shading reads
  // there; the attributes stay in each instance's own mesh.
  std::vector<uint32_t>().swap(merged_.prim_ids);
  // The merged meshes' own vertices and trees serve the emitters' set-up
  // and are freed at the end of commit() (release_merged_meshes).
  merged_instances_ = std::move(single);
  tlas_items.push_back(kMergedItem);
}

// A scene committed again: the meshes the last commit merged have their
// vertices only in the merged BLAS's leaf blocks, placed; they get them
// back in object space (in double through the instance's inverse: exact for
// untransformed instances, else to within rounding of the placed vertex),
// to be merged, or built, again. A triangle the merged build left out
// (degenerate or not finite once placed) comes back with three zero
// vertices: degenerate, left out again (no ray could hit it either way).
void Scene::restore_merged_vertices() {
  if (merged_instances_.empty()) return;
  for (uint32_t i : merged_instances_) {
    Mesh& mesh = meshes[instances[i].mesh];
    if (mesh.tri_verts.empty()) mesh.tri_verts.resize(3 * mesh.prim_ids.size());
  }
  const std::vector<vec3> placed = leaf_block_vertices(merged_, merged_owner_.size());
  for (size_t j = 0; j < merged_owner_.size(); ++j) {
    const MergedOwner& owner = merged_owner_[j];
    const Instance& inst = instances[owner.instance];
    const glm::dmat4 to_local = glm::inverse(glm::dmat4(inst.to_world));
    for (int c = 0; c < 3; ++c) {
      const vec3& p = placed[3 * j + c];
      meshes[inst.mesh].tri_verts[3 * size_t(owner.prim) + c] =
          inst.identity ? p : vec3(to_local * glm::dvec4(glm::dvec3(p), 1.0));
    }
  }
  merged_instances_.clear();
}

// The meshes merged into the render-space BLAS: their own trees are never
// walked and their vertices never read again (the merged BLAS's leaf blocks
// hold them, placed, and shading reads them there). Freed, keeping the
// bounds (Mesh::bounds).
void Scene::release_merged_meshes() {
  for (uint32_t id : merged_instances_) {
    Mesh& mesh = meshes[instances[id].mesh];
    const AABB b = mesh.bounds();
    mesh.bvh = BVH4{};
    mesh.bvh8 = BVH8{};
    mesh.bvh.bounds = b;
    BVHArray<vec3>().swap(mesh.tri_verts);
  }
}

void Scene::commit() {
  restore_merged_vertices();
  rebase_on_camera();
  tlas_items_.clear();
  merge_single_use_instances(tlas_items_);
  hidden_from_ = 0;
  for (uint32_t id : tlas_items_)
    if (id != kMergedItem) hidden_from_ |= uint8_t(~instances[id].visibility & kVisibleToAll);
  // Trees for the meshes the TLAS walks (add_mesh prepares meshes without
  // one: most are merged, and were built twice).
  std::vector<uint32_t> unbuilt;
  for (uint32_t id : tlas_items_)
    if (id != kMergedItem && !meshes[instances[id].mesh].has_bvh()) unbuilt.push_back(instances[id].mesh);
  std::sort(unbuilt.begin(), unbuilt.end());
  unbuilt.erase(std::unique(unbuilt.begin(), unbuilt.end()), unbuilt.end());
  tbb::parallel_for(size_t(0), unbuilt.size(), [&](size_t k) { build_mesh_bvh(meshes[unbuilt[k]]); });
  std::vector<AABB> boxes(tlas_items_.size());
  for (size_t k = 0; k < tlas_items_.size(); ++k) {
    const uint32_t id = tlas_items_[k];
    AABB b = id == kMergedItem ? merged_.bounds() : transform_box(meshes[instances[id].mesh].bounds(), instances[id].to_world);
    if (is_finite(b.lo) && is_finite(b.hi)) boxes[k] = b;
  }
  BuildOptions opt;
  opt.max_leaf_size = 1;  // one instance per leaf: the ray is transformed once per instance
  tlas_ = build_bvh(boxes, opt);
  AABB b = tlas_.bounds();
  float radius = b.empty() ? 1.0f : 0.5f * glm::length(b.extent());
  light_sampler_.build(lights, collect_emissive_triangles(), &background, std::max(radius, 1e-6f));
  release_merged_meshes();
  // The builds' freed scratch (boxes, references, partition buffers, trees
  // merged away) served the builds that followed it in this commit; the
  // render needs none of it, and it is the kernel's again.
  bvh_release_retained();
}

// One TLAS item: the merged triangles, or an instance's mesh with the ray
// in its object space. Closest hit: shrinks tmax and fills hit.
template <bool kAnyHit>
bool Scene::trace_item(uint32_t id, const vec3& o, const vec3& d, float& tmax, Hit* hit) const {
  if (id == kMergedItem) {
    if (kAnyHit) return occluded_mesh(merged_, o, d, tmax);
    MeshHit mh;
    if (!intersect_mesh(merged_, o, d, tmax, mh)) return false;
    const MergedOwner& owner = merged_owner_[mh.prim];
    *hit = {mh.t, mh.u, mh.v, owner.instance, owner.prim, mh.tri, mh.lane, true};
    return true;
  }
  const Instance& inst = instances[id];
  const Mesh& mesh = meshes[inst.mesh];
  vec3 lo = o, ld = d;
  if (!inst.identity) {
    lo = vec3(inst.to_local * vec4(o, 1.0f));
    ld = glm::mat3(inst.to_local) * d;
    // A finite transform can have a non-finite inverse: such an instance is not hit.
    if (!is_finite(lo) || !is_finite(ld)) return false;
  }
  if (kAnyHit) return occluded_mesh(mesh, lo, ld, tmax);
  MeshHit mh;
  if (!intersect_mesh(mesh, lo, ld, tmax, mh)) return false;
  *hit = {mh.t, mh.u, mh.v, id, mh.prim, mh.tri, mh.lane, false};
  return true;
}

template <bool kAnyHit, bool kMasked>
bool Scene::trace(const vec3& o, const vec3& d, float tmax, Hit* hit, uint8_t kind) const {
  if (tlas_.nodes.empty()) return false;
  auto hidden = [&](uint32_t id) { return kMasked && id != kMergedItem && !(instances[id].visibility & kind); };
  // One item (the merged triangles of a scene without instancing, or a lone
  // instance): its BLAS's root test is the TLAS's, skip the walk.
  if (tlas_items_.size() == 1) return !hidden(tlas_items_[0]) && trace_item<kAnyHit>(tlas_items_[0], o, d, tmax, hit);
  TraversalRay ray(o, d, tmax);
  return traverse<kAnyHit>(tlas_.nodes.data(), ray, [&](uint32_t first, uint32_t count, TraversalRay& r) {
    bool any = false;
    for (uint32_t k = first; k < first + count; ++k) {
      const uint32_t id = tlas_items_[tlas_.prim_order[k]];
      if (hidden(id)) continue;
      if (trace_item<kAnyHit>(id, r.o, r.d, r.tmax, hit)) {
        if (kAnyHit) return true;
        any = true;
      }
    }
    return any;
  });
}

// Rays with a NaN or infinite origin or direction hit nothing (the traversal
// kernels assume finite rays).
bool Scene::intersect(const Ray& ray, Hit& hit) const {
  if (!is_finite(ray.o) || !is_finite(ray.d)) return false;
  return trace<false>(ray.o, ray.d, ray.tmax, &hit);
}

bool Scene::intersect_visible(const Ray& ray, Hit& hit, RayKind kind) const {
  if (!is_finite(ray.o) || !is_finite(ray.d)) return false;
  return trace<false, true>(ray.o, ray.d, ray.tmax, &hit, kind);
}

bool Scene::occluded(const vec3& o, const vec3& d, float tmax) const {
  if (!is_finite(o) || !is_finite(d)) return false;
  if (hidden_from_ & kRayShadow) return trace<true, true>(o, d, tmax, nullptr, kRayShadow);
  return trace<true>(o, d, tmax, nullptr);
}

SurfaceInteraction Scene::interaction(const Ray& ray, const Hit& hit) const {
  const Instance& inst = instances[hit.instance];
  const Mesh& mesh = meshes[inst.mesh];
  // The vertices the ray was tested against, from its leaf block.
  const vec3 v[3] = {hit.tri->vertex(0, hit.lane), hit.tri->vertex(1, hit.lane), hit.tri->vertex(2, hit.lane)};
  const uint32_t prim_id = mesh.prim_ids[hit.prim];
  const float b0 = 1.0f - hit.u - hit.v;
  // Point from barycentrics, with its error bound (pbrt-v4, 6.8.4).
  vec3 p = b0 * v[0] + hit.u * v[1] + hit.v * v[2];
  vec3 err = gamma(7) * (abs(b0 * v[0]) + abs(hit.u * v[1]) + abs(hit.v * v[2]));
  vec3 ng = glm::cross(v[1] - v[0], v[2] - v[0]);
  vec3 ns(0.0f);
  if (!mesh.corner_normals.empty()) {
    const uint32_t* n = &mesh.corner_normals[3 * size_t(prim_id)];
    ns = b0 * oct_decode(n[0]) + hit.u * oct_decode(n[1]) + hit.v * oct_decode(n[2]);
  }
  if (!inst.identity) {
    const glm::mat3 m(inst.to_world);
    if (hit.render_space) {
      // Merged: the vertices are already placed. The front is where the
      // normal transform of the object-space normal points (as for the
      // instance's own BLAS); the cross product of placed edges is that
      // times det, so a mirroring transform flips it.
      if (inst.mirrored) ng = -ng;
    } else {
      const glm::mat3 abs_m(abs(m[0]), abs(m[1]), abs(m[2]));
      const vec3 t(inst.to_world[3]);
      vec3 pw = m * p + t;
      err = (1.0f + gamma(3)) * (abs_m * err) + gamma(3) * (abs_m * abs(p) + abs(t));
      p = pw;
      ng = inst.normal_to_world * ng;
    }
    ns = inst.normal_to_world * ns;
  }
  SurfaceInteraction si;
  si.p = p;
  si.p_error = err;
  float ng_len = glm::length(ng);
  si.ng = ng_len > 0.0f && std::isfinite(ng_len) ? ng / ng_len : -ray.d;
  float ns_len = glm::length(ns);
  si.ns = ns_len > 0.0f && std::isfinite(ns_len) ? ns / ns_len : si.ng;
  // Shading normals live on the geometric front side.
  if (glm::dot(si.ns, si.ng) < 0.0f) si.ns = -si.ns;
  si.back_face = glm::dot(ray.d, si.ng) > 0.0f;
  si.material = material_of(inst, mesh.slot(prim_id));
  if (!mesh.corner_uvs.empty()) {
    const vec2* uv = &mesh.corner_uvs[3 * size_t(prim_id)];
    si.uv = b0 * uv[0] + hit.u * uv[1] + hit.v * uv[2];
    const Material& m = materials[si.material];
    if (m.normal_tex.valid()) apply_normal_map(si, m, v, hit.render_space, uv, inst);
  }
  return si;
}

// Tangent-space normal map (Blender's Normal Map node, tangent space): the
// texel maps [0,1] to [-1,1] along (tangent, bitangent, normal); the tangent
// follows the UV's u direction across the triangle (pbrt-v4 eq. 6.x, dp/du).
void Scene::apply_normal_map(SurfaceInteraction& si, const Material& m, const vec3* v, bool render_space,
                             const vec2* uv, const Instance& inst) const {
  const vec2 duv02 = uv[0] - uv[2], duv12 = uv[1] - uv[2];
  const vec3 dp02 = v[0] - v[2], dp12 = v[1] - v[2];
  const float det = duv02.x * duv12.y - duv02.y * duv12.x;
  if (std::abs(det) < 1e-20f) return;
  vec3 dpdu = (duv12.y * dp02 - duv02.y * dp12) / det;
  if (!inst.identity && !render_space) dpdu = glm::mat3(inst.to_world) * dpdu;
  vec3 t = dpdu - si.ns * glm::dot(si.ns, dpdu);
  const float len = glm::length(t);
  if (!(len > 0.0f) || !std::isfinite(len)) return;
  t /= len;
  // Mirrored UVs flip the bitangent, as MikkTSpace's sign does.
  vec3 b = glm::cross(si.ns, t) * (det < 0.0f ? -1.0f : 1.0f);
  const vec4 c = textures[m.normal_tex.texture].eval(si.uv);
  const vec3 n_ts = 2.0f * vec3(c) - vec3(1.0f);
  vec3 n = n_ts.x * t + n_ts.y * b + n_ts.z * si.ns;
  // Strength blends from the interpolated normal to the mapped one (Cycles svm_node_normal_map).
  if (m.normal_strength != 1.0f) n = si.ns + (n - si.ns) * std::max(m.normal_strength, 0.0f);
  const float nlen = glm::length(n);
  if (!(nlen > 0.0f) || !std::isfinite(nlen)) return;
  n /= nlen;
  if (glm::dot(n, si.ng) < 0.0f) n = glm::normalize(n - si.ng * (1.001f * glm::dot(n, si.ng)));
  if (is_finite(n)) si.ns = n;
}

float Scene::texture_value(const TextureRef& ref, vec2 uv, bool after_diffuse) const {
  const vec4 c = textures[ref.texture].eval(uv, after_diffuse);
  return ref.channel == 1 ? c.w : luminance(vec3(c));
}

// The BSDF's inputs blur after a diffuse bounce; alpha (cut-outs, which
// shadow rays test at full resolution) and emission (which light sampling
// evaluates at full resolution, and MIS weighs against it) do not.
Material Scene::textured_material(const Material& base, vec2 uv, bool after_diffuse) const {
  Material m = base;
  if (m.base_color_tex.valid()) {
    const vec4 c = textures[m.base_color_tex.texture].eval(uv, after_diffuse);
    m.base_color = m.base_color_tex.channel == 1 ? vec3(c.w) : vec3(c);
  }
  if (m.metallic_tex.valid()) m.metallic = texture_value(m.metallic_tex, uv, after_diffuse);
  if (m.roughness_tex.valid()) m.roughness = texture_value(m.roughness_tex, uv, after_diffuse);
  if (m.alpha_tex.valid()) m.alpha = texture_value(m.alpha_tex, uv);  // per texel: cut-outs
  if (m.emission_tex.valid()) {
    const vec4 c = textures[m.emission_tex.texture].eval(uv);
    const vec3 e = m.emission_tex.channel == 1 ? vec3(c.w) : vec3(c);
    m.emission_front = e * m.emission_strength_front;
    m.emission_back = e * m.emission_strength_back;
  }
  return m;
}

size_t Scene::num_triangles() const {
  size_t n = 0;
  for (const Mesh& m : meshes) n += m.prim_ids.size();
  return n;
}

size_t Scene::num_instanced_triangles() const {
  size_t n = 0;
  for (const Instance& i : instances) n += meshes[i.mesh].prim_ids.size();
  return n;
}

size_t Scene::memory_bytes() const {
  size_t n = tlas_.memory_bytes() + instances.capacity() * sizeof(Instance) + merged_.memory_bytes() +
             merged_owner_.capacity() * sizeof(MergedOwner);
  for (const Mesh& m : meshes) n += m.memory_bytes();
  return n;
}

}  // namespace tessera
