// BVH invariants on random and real meshes, and closest/any hits equal to
// brute force.
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <cstdlib>
#include <random>

#include "core/mesh.h"
#include "io/mesh_file.h"

using namespace tessera;

namespace {

std::string shared_dir() {
  const char* env = std::getenv("TESSERA_SHARED");
  return env ? env : TESSERA_SHARED_DIR;
}

TriangleSoup random_soup(size_t n, uint32_t seed, float size = 0.1f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-1.0f, 1.0f), off(-size, size);
  TriangleSoup s;
  for (size_t i = 0; i < n; ++i) {
    vec3 c(pos(rng), pos(rng), pos(rng));
    for (int k = 0; k < 3; ++k) {
      vec3 p = c + vec3(off(rng), off(rng), off(rng));
      s.positions.insert(s.positions.end(), {p.x, p.y, p.z});
      s.indices.push_back(uint32_t(3 * i + k));
    }
  }
  return s;
}

Mesh make_mesh(const TriangleSoup& s, const BuildOptions& opt = {}) {
  MeshInput in;
  in.positions = s.positions.data();
  in.num_vertices = s.positions.size() / 3;
  in.indices = s.indices.data();
  in.num_triangles = s.num_triangles();
  return build_mesh(in, opt);
}

void check_invariants(const Mesh& mesh, size_t num_triangles) {
  const BVH& bvh = mesh.bvh;
  ASSERT_FALSE(bvh.nodes.empty());
  std::vector<int> seen(num_triangles, 0);
  std::vector<uint32_t> stack{0};
  size_t leaves_total = 0;
  while (!stack.empty()) {
    uint32_t i = stack.back();
    stack.pop_back();
    const BVHNode& n = bvh.nodes[i];
    AABB box{n.lo, n.hi};
    if (n.is_leaf()) {
      for (uint32_t k = n.first; k < n.first + n.count; ++k) {
        seen[mesh.prim_ids[k]]++;
        ++leaves_total;
        for (int j = 0; j < 3; ++j) {
          const vec3& p = mesh.tri_verts[3 * k + j];
          ASSERT_TRUE(glm::all(glm::lessThanEqual(box.lo, p)) && glm::all(glm::lessThanEqual(p, box.hi)))
              << "triangle outside its leaf box";
        }
      }
    } else {
      for (uint32_t c : {n.first, n.first + 1}) {
        ASSERT_LT(c, bvh.nodes.size());
        ASSERT_TRUE(box.contains(AABB{bvh.nodes[c].lo, bvh.nodes[c].hi})) << "child box not inside its parent";
        stack.push_back(c);
      }
    }
  }
  EXPECT_EQ(leaves_total, num_triangles);
  for (size_t t = 0; t < num_triangles; ++t) ASSERT_EQ(seen[t], 1) << "triangle " << t << " not in exactly one leaf";
}

struct BruteHit {
  float t = kInf;
  uint32_t prim = ~0u;
};

BruteHit brute_force(const Mesh& mesh, const vec3& o, const vec3& d) {
  BruteHit best;
  RayShear sh(d);
  for (uint32_t k = 0; k < mesh.prim_ids.size(); ++k) {
    TriangleHit h;
    if (intersect_triangle(mesh.tri_verts[3 * k], mesh.tri_verts[3 * k + 1], mesh.tri_verts[3 * k + 2], o, sh, best.t, h))
      best = {h.t, k};
  }
  return best;
}

// Compares closest and any hits with brute force for n random rays through the bounds.
void check_against_brute_force(const Mesh& mesh, size_t n, uint32_t seed) {
  AABB b = mesh.bounds();
  std::atomic<size_t> mismatches{0}, hits{0};
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    std::mt19937 rng(seed * 1000003u + uint32_t(i));
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    vec3 o = b.lo + (b.hi - b.lo) * vec3(u(rng), u(rng), u(rng)) * 1.4f - 0.2f * (b.hi - b.lo);
    vec3 target = b.lo + (b.hi - b.lo) * vec3(u(rng), u(rng), u(rng));
    vec3 d = glm::normalize(target - o);
    BruteHit ref = brute_force(mesh, o, d);
    float tmax = kInf;
    MeshHit h;
    bool found = intersect_mesh(mesh, o, d, tmax, h);
    bool ok = found == (ref.prim != ~0u) && (!found || (h.t == ref.t));
    if (found) ++hits;
    // Any hit agrees with closest hit, also with a range that ends before the hit.
    ok = ok && occluded_mesh(mesh, o, d, kInf) == found;
    if (found) ok = ok && !occluded_mesh(mesh, o, d, ref.t * 0.999f);  // nothing nearer than the closest hit
    if (!ok) ++mismatches;
  });
  EXPECT_EQ(mismatches.load(), 0u);
  EXPECT_GT(hits.load(), n / 20) << "the test rays should hit the mesh often";
}

}  // namespace

TEST(BVH, InvariantsOnRandomTriangles) {
  for (SplitMethod m : {SplitMethod::BinnedSAH, SplitMethod::SweepSAH, SplitMethod::Midpoint}) {
    BuildOptions opt;
    opt.method = m;
    TriangleSoup s = random_soup(5000, 7);
    Mesh mesh = make_mesh(s, opt);
    check_invariants(mesh, s.num_triangles());
  }
}

TEST(BVH, MillionRandomRaysMatchBruteForce) {
  TriangleSoup s = random_soup(300, 11, 0.3f);
  Mesh mesh = make_mesh(s);
  check_invariants(mesh, s.num_triangles());
  check_against_brute_force(mesh, 1000000, 1);
}

TEST(BVH, EveryBuilderMatchesBruteForce) {
  for (SplitMethod m : {SplitMethod::SweepSAH, SplitMethod::Midpoint}) {
    BuildOptions opt;
    opt.method = m;
    Mesh mesh = make_mesh(random_soup(1000, 3), opt);
    check_against_brute_force(mesh, 20000, 2);
  }
}

TEST(BVH, RealMeshInvariantsAndBruteForce) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  Mesh mesh = make_mesh(s);
  check_invariants(mesh, s.num_triangles());
  check_against_brute_force(mesh, 3000, 5);
}

TEST(BVH, BinnedSAHIsCloseToFullSweep) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  BuildOptions binned, sweep;
  sweep.method = SplitMethod::SweepSAH;
  float cb = sah_cost(make_mesh(s, binned).bvh), cs = sah_cost(make_mesh(s, sweep).bvh);
  EXPECT_LT(cb, cs * 1.05f) << "binned SAH cost " << cb << " vs sweep " << cs;
}

TEST(BVH, InvalidTrianglesAreSkippedNotStored) {
  TriangleSoup s = random_soup(100, 5);
  s.positions[0] = std::nanf("");                 // triangle 0: NaN vertex
  s.indices[3 * 1 + 2] = 1000000;                 // triangle 1: index out of range
  s.positions[3 * 6 + 1] = std::numeric_limits<float>::infinity();  // triangle 2: Inf vertex
  Mesh mesh = make_mesh(s);
  EXPECT_EQ(mesh.num_skipped_triangles, 3u);
  EXPECT_EQ(mesh.prim_ids.size(), 97u);
  check_against_brute_force(mesh, 2000, 9);
}

TEST(BVH, IdenticalTrianglesStayWithinTraversalDepth) {
  // 100k copies of one triangle: centroids cannot be separated.
  TriangleSoup s;
  s.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  for (int i = 0; i < 100000; ++i) s.indices.insert(s.indices.end(), {0, 1, 2});
  Mesh mesh = make_mesh(s);
  EXPECT_LE(mesh.bvh.depth(), 64);
  float tmax = kInf;
  MeshHit h;
  EXPECT_TRUE(intersect_mesh(mesh, vec3(0.2f, 0.2f, 1), vec3(0, 0, -1), tmax, h));
  EXPECT_FLOAT_EQ(h.t, 1.0f);
}

TEST(BVH, EmptyMesh) {
  TriangleSoup s;
  Mesh mesh = make_mesh(s);
  float tmax = kInf;
  MeshHit h;
  EXPECT_FALSE(intersect_mesh(mesh, vec3(0), vec3(0, 0, 1), tmax, h));
  EXPECT_FALSE(occluded_mesh(mesh, vec3(0), vec3(0, 0, 1), kInf));
}
