// Instancing: a mesh placed many times is stored once (memory ~ one mesh plus
// the instance table and TLAS) and an instanced scene gives the same hits and
// depth image as the same scene with every instance flattened into world space.
#include <gtest/gtest.h>

#include <cstdlib>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include "core/scene.h"
#include "io/mesh_file.h"

using namespace tessera;

namespace {

std::string shared_dir() {
  const char* env = std::getenv("TESSERA_SHARED");
  return env ? env : TESSERA_SHARED_DIR;
}

MeshInput input_of(const TriangleSoup& s) {
  MeshInput in;
  in.positions = s.positions.data();
  in.num_vertices = s.positions.size() / 3;
  in.indices = s.indices.data();
  in.num_triangles = s.num_triangles();
  return in;
}

// Grid placement with a rotation about y and a non-uniform scale per instance.
mat4 placement(int i, int n, float spacing) {
  const int x = i % n, y = (i / n) % n, z = i / (n * n);
  mat4 m = glm::translate(mat4(1.0f), vec3(x * spacing, y * spacing, z * spacing));
  m = glm::rotate(m, 0.37f * float(i), vec3(0.2f, 1.0f, 0.1f));
  return glm::scale(m, vec3(1.0f + 0.1f * float(i % 3), 1.0f, 1.0f - 0.05f * float(i % 4)));
}

// Camera-style rays over the scene bounds: a depth and instance image.
struct Image {
  std::vector<float> t;
  std::vector<uint32_t> inst;
};

Image render_depth(const Scene& s, int res, vec3 eye, vec3 target) {
  const vec3 fwd = glm::normalize(target - eye);
  const vec3 right = glm::normalize(glm::cross(fwd, vec3(0, 1, 0)));
  const vec3 up = glm::cross(right, fwd);
  Image img;
  img.t.resize(size_t(res) * res);
  img.inst.resize(size_t(res) * res);
  for (int y = 0; y < res; ++y)
    for (int x = 0; x < res; ++x) {
      const float u = (x + 0.5f) / res * 2.0f - 1.0f, v = (y + 0.5f) / res * 2.0f - 1.0f;
      Ray r{eye, glm::normalize(fwd + 0.6f * u * right + 0.6f * v * up), kInf};
      Hit h;
      const bool hit = s.intersect(r, h);
      img.t[size_t(y) * res + x] = hit ? h.t : kInf;
      img.inst[size_t(y) * res + x] = hit ? h.instance : ~0u;
      // Any hit agrees with closest hit.
      EXPECT_EQ(s.occluded(r.o, r.d, kInf), hit);
    }
  return img;
}

// Depth images of two placements of the same triangles, seen from outside
// a's bounds: at least min_hits of the pixels hit, and at most 1 in 2000
// disagree (hit against miss, another instance, or distances more than 1e-4
// apart, relative). Transforming the ray (instanced) or the vertices
// (flattened, merged) rounds differently: silhouette pixels may flip,
// distances agree to ~1e-5.
void expect_same_depth_images(const Scene& a_scene, const Scene& b_scene, int res, double min_hits) {
  const AABB sb = a_scene.bounds();
  const vec3 eye = sb.center() + vec3(0.45f, 0.35f, 0.8f) * glm::length(sb.extent());
  const Image a = render_depth(a_scene, res, eye, sb.center()), b = render_depth(b_scene, res, eye, sb.center());
  size_t differ = 0, hits = 0;
  for (size_t i = 0; i < a.t.size(); ++i) {
    const bool ha = a.t[i] != kInf, hb = b.t[i] != kInf;
    hits += ha;
    differ += ha != hb || (ha && (a.inst[i] != b.inst[i] || std::abs(a.t[i] - b.t[i]) > 1e-4f * b.t[i]));
  }
  EXPECT_GT(double(hits), min_hits * double(a.t.size()));
  EXPECT_LE(differ, a.t.size() / 2000) << differ << " of " << a.t.size() << " pixels differ";
}

}  // namespace

TEST(Instancing, InstancedAndFlattenedScenesGiveTheSameImage) {
  const TriangleSoup bunny = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  const int n = 3, count = n * n * n;  // 27 instances: the flattened scene stays small
  const AABB mb = [&] {
    AABB b;
    for (size_t i = 0; i < bunny.positions.size(); i += 3)
      b.grow(vec3(bunny.positions[i], bunny.positions[i + 1], bunny.positions[i + 2]));
    return b;
  }();
  const float spacing = 1.2f * glm::length(mb.extent());
  Scene inst, flat;
  inst.meshes.push_back(build_mesh(input_of(bunny)));
  for (int i = 0; i < count; ++i) {
    inst.add_instance(0, placement(i, n, spacing), {});
    TriangleSoup w = bunny;
    const mat4 m = placement(i, n, spacing);
    for (size_t k = 0; k < w.positions.size(); k += 3) {
      const vec3 p = vec3(m * vec4(w.positions[k], w.positions[k + 1], w.positions[k + 2], 1.0f));
      w.positions[k] = p.x, w.positions[k + 1] = p.y, w.positions[k + 2] = p.z;
    }
    flat.meshes.push_back(build_mesh(input_of(w)));
    flat.add_instance(uint32_t(flat.meshes.size() - 1), mat4(1.0f), {});
  }
  inst.commit();
  flat.commit();
  EXPECT_EQ(inst.num_triangles(), bunny.num_triangles());
  EXPECT_EQ(inst.num_instanced_triangles(), count * bunny.num_triangles());
  EXPECT_EQ(flat.num_triangles(), count * bunny.num_triangles());

  expect_same_depth_images(inst, flat, 160, 1.0 / 20);
}

// A mesh placed once with a transform goes into the render-space BLAS as
// well (no ray into object space, no hit back to world space per ray), with
// the hits of its own BLAS; one placed as it is keeps its BLAS (merging
// would only copy it).
TEST(Instancing, LoneTransformedInstanceIsMerged) {
  const TriangleSoup bunny = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  const mat4 m = placement(5, 2, 0.3f);
  Scene lone, own, identity;
  lone.meshes.push_back(build_mesh(input_of(bunny)));
  lone.add_instance(0, m, {});
  own.meshes.push_back(build_mesh(input_of(bunny)));
  own.add_instance(0, m, {});
  own.add_instance(0, glm::translate(mat4(1.0f), vec3(1e4f)), {});  // placed twice: its own BLAS, as before
  identity.meshes.push_back(build_mesh(input_of(bunny)));
  identity.add_instance(0, mat4(1.0f), {});
  lone.commit();
  own.commit();
  identity.commit();
  EXPECT_EQ(lone.num_merged_instances(), 1u);
  EXPECT_EQ(own.num_merged_instances(), 0u);
  EXPECT_EQ(identity.num_merged_instances(), 0u);

  expect_same_depth_images(lone, own, 128, 1.0 / 10);
}

TEST(Instancing, ThousandInstancesStoreOneMesh) {
  const TriangleSoup bunny = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  Scene one, many;
  one.meshes.push_back(build_mesh(input_of(bunny)));
  one.add_instance(0, mat4(1.0f), {});
  one.commit();
  many.meshes.push_back(build_mesh(input_of(bunny)));
  const int n = 10;
  for (int i = 0; i < n * n * n; ++i) many.add_instance(0, placement(i, n, 0.3f), {});
  many.commit();
  EXPECT_EQ(many.instances.size(), 1000u);
  EXPECT_EQ(many.meshes.size(), 1u);
  EXPECT_EQ(many.num_triangles(), bunny.num_triangles());
  EXPECT_EQ(many.num_instanced_triangles(), 1000 * bunny.num_triangles());
  const size_t mesh_bytes = one.meshes[0].memory_bytes();
  const size_t per_instance = (many.memory_bytes() - one.memory_bytes()) / 999;
  // One mesh plus a small table per instance (Instance + TLAS node share +
  // material slots), never a copy of the triangles.
  EXPECT_LT(many.memory_bytes(), mesh_bytes + 1000 * 512) << "instanced scene is not ~one mesh";
  EXPECT_LT(per_instance, 512u);
  std::printf("mesh %zu bytes (%.1f per triangle), 1000 instances: %zu bytes (%zu per instance)\n", mesh_bytes,
              double(mesh_bytes) / bunny.num_triangles(), many.memory_bytes(), per_instance);
  // Every instance is reachable: a ray down the y axis through each grid cell
  // centre column hits something.
  size_t hit_count = 0;
  for (int i = 0; i < n * n * n; ++i) {
    const vec3 c = vec3(many.instances[i].to_world * vec4(one.meshes[0].bounds().center(), 1.0f));
    Ray r{c + vec3(0.0f, 0.0f, 50.0f), vec3(0.0f, 0.0f, -1.0f), kInf};
    Hit h;
    hit_count += many.intersect(r, h);
  }
  EXPECT_GT(hit_count, 900u);
}

// Meshes that one instance places share one render-space BLAS (Scene::
// merge_single_use_instances); meshes placed more often keep theirs. Hits
// report the instance and its mesh's triangle as before (checked against
// brute force over every instance's world-space triangles), and the merged
// meshes' own trees are freed, so memory does not double.
// prepared: meshes added as the add-on adds them (prepare_mesh, no tree
// until commit builds one for the meshes it does not merge).
static void check_single_use_meshes_share_one_blas(bool prepared) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  auto soup = [&](int n) {
    TriangleSoup s;
    for (int t = 0; t < n; ++t) {
      const vec3 c(u01(rng), u01(rng), u01(rng));
      for (int k = 0; k < 3; ++k) {
        const vec3 p = c + 0.15f * vec3(u01(rng) - 0.5f, u01(rng) - 0.5f, u01(rng) - 0.5f);
        s.positions.insert(s.positions.end(), {p.x, p.y, p.z});
        s.indices.push_back(uint32_t(3 * t + k));
      }
    }
    return s;
  };
  std::vector<TriangleSoup> soups;
  Scene s;
  size_t mesh_bytes = 0;
  for (int m = 0; m < 6; ++m) {
    soups.push_back(soup(300 + 50 * m));
    s.meshes.push_back(prepared ? prepare_mesh(input_of(soups.back())) : build_mesh(input_of(soups.back())));
    mesh_bytes += prepared ? build_mesh(input_of(soups.back())).memory_bytes() : s.meshes.back().memory_bytes();
  }
  // Meshes 0-4 placed once each, mesh 5 three times.
  for (int i = 0; i < 8; ++i) s.add_instance(uint32_t(std::min(i, 5)), placement(i, 2, 1.1f), {});
  s.commit();
  EXPECT_EQ(s.num_merged_instances(), 5u);
  EXPECT_LT(s.memory_bytes(), mesh_bytes * 13 / 10) << "merging kept two trees per mesh";
  // Only the instanced mesh has (or, prepared, was given) a tree of its own.
  for (int m = 0; m < 5; ++m) EXPECT_FALSE(s.meshes[m].has_bvh()) << "mesh " << m;
  EXPECT_TRUE(s.meshes[5].has_bvh());

  // Each vertex is stored once: the merged meshes' only in the merged
  // BLAS's leaf blocks (placed), the instanced mesh's in its tree's.
  for (const Mesh& m : s.meshes) EXPECT_TRUE(m.tri_verts.empty());

  const AABB sb = s.bounds();
  size_t hits = 0, differ = 0, rays = 0;
  struct Found {
    bool hit;
    float t;
    uint32_t instance, tri;
    vec3 p, ng;
  };
  std::vector<std::pair<Ray, Found>> found;
  for (int r = 0; r < 4000; ++r) {
    const vec3 o = sb.center() + 1.5f * glm::length(sb.extent()) * glm::normalize(vec3(u01(rng) - 0.5f, u01(rng) - 0.5f, u01(rng) - 0.5f));
    const vec3 target = sb.lo + sb.extent() * vec3(u01(rng), u01(rng), u01(rng));
    const vec3 d = glm::normalize(target - o);
    // Brute force in world space.
    const RayShear shear(d);
    float best = kInf;
    uint32_t best_inst = ~0u, best_tri = ~0u;
    for (uint32_t i = 0; i < s.instances.size(); ++i) {
      const TriangleSoup& w = soups[s.instances[i].mesh];
      for (uint32_t t = 0; t < w.num_triangles(); ++t) {
        vec3 p[3];
        for (int k = 0; k < 3; ++k) {
          const float* q = &w.positions[3 * w.indices[3 * t + k]];
          p[k] = vec3(s.instances[i].to_world * vec4(q[0], q[1], q[2], 1.0f));
        }
        TriangleHit th;
        if (intersect_triangle(p[0], p[1], p[2], o, shear, best, th)) best = th.t, best_inst = i, best_tri = t;
      }
    }
    Hit h;
    const bool hit = s.intersect(Ray{o, d, kInf}, h);
    EXPECT_EQ(s.occluded(o, d, kInf), hit);
    ++rays;
    hits += best != kInf;
    const uint32_t tri = hit ? s.meshes[s.instances[h.instance].mesh].prim_ids[h.prim] : ~0u;
    if (hit != (best != kInf) || (hit && (h.instance != best_inst || tri != best_tri || std::abs(h.t - best) > 1e-4f * best)))
      ++differ;
    const Ray ray{o, d, kInf};
    const SurfaceInteraction si = hit ? s.interaction(ray, h) : SurfaceInteraction{};
    found.push_back({ray, {hit, h.t, h.instance, tri, si.p, si.ng}});
  }
  EXPECT_GT(hits, rays / 4);
  EXPECT_LE(differ, rays / 500) << differ << " of " << rays << " rays differ from brute force";

  // Committed again (the Python API allows it), the merged meshes get their
  // vertices back from the merged BLAS: the same hits and shading points to
  // within rounding (the instances rotate and scale).
  const size_t bytes = s.memory_bytes();
  s.commit();
  EXPECT_EQ(s.num_merged_instances(), 5u);
  EXPECT_EQ(s.memory_bytes(), bytes);
  size_t moved = 0;
  for (const auto& [ray, before] : found) {
    Hit h;
    const bool hit = s.intersect(ray, h);
    ASSERT_EQ(hit, before.hit);
    if (!hit) continue;
    const uint32_t tri = s.meshes[s.instances[h.instance].mesh].prim_ids[h.prim];
    const SurfaceInteraction si = s.interaction(ray, h);
    moved += h.instance != before.instance || tri != before.tri;
    if (h.instance == before.instance && tri == before.tri) {
      EXPECT_NEAR(h.t, before.t, 1e-5f * before.t);
      EXPECT_LE(glm::length(si.p - before.p), 1e-5f);
      EXPECT_GT(glm::dot(si.ng, before.ng), 0.9999f);
    }
  }
  EXPECT_LE(moved, found.size() / 1000) << "hits that moved to another triangle after the second commit";
}

TEST(Instancing, SingleUseMeshesShareOneBLAS) { check_single_use_meshes_share_one_blas(false); }

// The add-on's meshes: a single-use mesh's tree is never built (before,
// every mesh got a BLAS in add_mesh that the merge then threw away).
TEST(Instancing, PreparedMeshesGetATreeOnlyWhenTheTLASWalksThem) { check_single_use_meshes_share_one_blas(true); }
