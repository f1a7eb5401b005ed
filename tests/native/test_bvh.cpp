// BVH invariants on random and real meshes, and closest/any hits equal to
// brute force.
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>

#include "core/mesh.h"
#include "core/simd.h"
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

// Binary tree from build_bvh: every valid box in exactly one leaf, children inside parents.
void check_binary_invariants(const BVH& bvh, const std::vector<AABB>& boxes) {
  ASSERT_FALSE(bvh.nodes.empty());
  std::vector<int> seen(boxes.size(), 0);
  std::vector<uint32_t> stack{0};
  while (!stack.empty()) {
    uint32_t i = stack.back();
    stack.pop_back();
    const BVHNode& n = bvh.nodes[i];
    AABB box{n.lo, n.hi};
    if (n.is_leaf()) {
      for (uint32_t k = n.first; k < n.first + n.count; ++k) {
        seen[bvh.prim_order[k]]++;
        ASSERT_TRUE(box.contains(boxes[bvh.prim_order[k]])) << "primitive outside its leaf box";
      }
    } else {
      for (uint32_t c : {n.first, n.first + 1}) {
        ASSERT_LT(c, bvh.nodes.size());
        ASSERT_TRUE(box.contains(AABB{bvh.nodes[c].lo, bvh.nodes[c].hi})) << "child box not inside its parent";
        stack.push_back(c);
      }
    }
  }
  for (size_t t = 0; t < boxes.size(); ++t) ASSERT_EQ(seen[t], boxes[t].empty() ? 0 : 1) << "primitive " << t;
}

// The input's vertices of a mesh's stored triangles, in leaf order (3 each),
// through prim_ids: what the tree's leaf blocks must hold.
std::vector<vec3> input_vertices(const Mesh& mesh, const TriangleSoup& s) {
  std::vector<vec3> v;
  for (uint32_t id : mesh.prim_ids)
    for (int j = 0; j < 3; ++j) {
      const float* p = &s.positions[3 * size_t(s.indices[3 * size_t(id) + j])];
      v.push_back(vec3(p[0], p[1], p[2]));
    }
  return v;
}

// Mesh BLAS (BVH4 or BVH8): each triangle in exactly one leaf, a leaf is a
// contiguous range of leaf order, the Tri4 lanes hold exactly the input's
// vertices of those triangles, boxes nest; the mesh keeps no other copy.
template <int N, typename Tree>
void check_tree(const Mesh& mesh, const Tree& bvh, const TriangleSoup& s) {
  const size_t num_triangles = s.num_triangles();
  const std::vector<vec3> verts = input_vertices(mesh, s);
  ASSERT_FALSE(bvh.empty()) << "N " << N << " w " << mesh.width() << " " << mesh.bvh.num_nodes << " " << mesh.bvh8.num_nodes;
  const size_t arena = bvh.mem.size() * sizeof(BVHLine);
  size_t nodes_seen = 0, blocks_seen = 0;
  ASSERT_TRUE(mesh.tri_verts.empty()) << "a mesh with a tree keeps its vertices only in the leaf blocks";
  ASSERT_EQ(leaf_order_vertices(mesh), verts);
  std::vector<int> seen(num_triangles, 0);
  std::vector<std::pair<uint32_t, AABB>> stack{{0u, bvh.bounds}};
  size_t leaves_total = 0;
  while (!stack.empty()) {
    auto [i, parent] = stack.back();
    stack.pop_back();
    ASSERT_LE((size_t(i) + 1) * kNodeUnit, arena);
    const auto& n = bvh.node(i);
    ++nodes_seen;
    ASSERT_GE(n.num_children, 1u);
    ASSERT_LE(n.num_children, uint32_t(N));
    for (uint32_t c = 0; c < uint32_t(N); ++c) {
      if (c >= n.num_children) {
        ASSERT_EQ(n.child[c], kBVH4EmptyChild);
        ASSERT_GT(n.box[0][c], n.box[1][c]) << "unused child box must be inverted";
        continue;
      }
      AABB box{vec3(n.box[0][c], n.box[2][c], n.box[4][c]), vec3(n.box[1][c], n.box[3][c], n.box[5][c])};
      ASSERT_TRUE(parent.contains(box)) << "child box not inside its parent";
      const uint32_t ref = n.child[c];
      if (!bvh4_is_leaf(ref)) {
        stack.push_back({ref, box});
        continue;
      }
      uint32_t lo = ~0u, hi = 0;
      std::vector<uint32_t> ks;
      ASSERT_LE(size_t(bvh4_leaf_first(ref)) * kBlockUnit + bvh4_leaf_blocks(ref) * sizeof(Tri4), arena);
      blocks_seen += bvh4_leaf_blocks(ref);
      for (uint32_t b = 0; b < bvh4_leaf_blocks(ref); ++b) {
        const Tri4& t = bvh.blocks(ref)[b];
        for (int lane = 0; lane < 4; ++lane) {
          const uint32_t k = t.prim[lane];
          ASSERT_LT(k, mesh.prim_ids.size());
          for (int j = 0; j < 3; ++j) {
            const vec3& p = verts[3 * k + j];
            ASSERT_EQ(vec3(t.v[j][0][lane], t.v[j][1][lane], t.v[j][2][lane]), p);
            ASSERT_TRUE(glm::all(glm::lessThanEqual(box.lo, p)) && glm::all(glm::lessThanEqual(p, box.hi)))
                << "triangle outside its leaf box";
          }
          if (ks.empty() || ks.back() != k) ks.push_back(k);
          lo = std::min(lo, k), hi = std::max(hi, k);
        }
      }
      ASSERT_EQ(size_t(hi - lo + 1), ks.size()) << "leaf is not one contiguous range";
      for (uint32_t k : ks) seen[mesh.prim_ids[k]]++;
      leaves_total += ks.size();
    }
  }
  EXPECT_EQ(leaves_total, num_triangles);
  EXPECT_EQ(nodes_seen, bvh.num_nodes);
  EXPECT_EQ(blocks_seen, bvh.num_blocks);
  for (size_t t = 0; t < num_triangles; ++t) ASSERT_EQ(seen[t], 1) << "triangle " << t << " not in exactly one leaf";
}

void check_invariants(const Mesh& mesh, const TriangleSoup& s) {
  if (mesh.width() == 8) {
    ASSERT_TRUE(mesh.bvh.empty()) << "one BLAS per mesh";
    check_tree<8>(mesh, mesh.bvh8, s);
  } else {
    ASSERT_TRUE(mesh.bvh8.empty()) << "one BLAS per mesh";
    check_tree<4>(mesh, mesh.bvh, s);
  }
}

// The BLAS widths this CPU runs: 4 always, 8 with AVX2.
std::vector<int> widths() {
  std::vector<int> w{4};
  if (cpu_simd_level() == SimdLevel::AVX2) w.push_back(8);
  return w;
}

BuildOptions with_width(BuildOptions opt, int width) {
  opt.bvh_width = width;
  return opt;
}

struct BruteHit {
  float t = kInf;
  uint32_t prim = ~0u;
};

BruteHit brute_force(const std::vector<vec3>& v, const vec3& o, const vec3& d) {
  BruteHit best;
  RayShear sh(d);
  for (uint32_t k = 0; k < v.size() / 3; ++k) {
    TriangleHit h;
    if (intersect_triangle(v[3 * k], v[3 * k + 1], v[3 * k + 2], o, sh, best.t, h))
      best = {h.t, k};
  }
  return best;
}

// Compares closest and any hits with brute force over the input's triangles
// for n random rays through the bounds.
void check_against_brute_force(const Mesh& mesh, const TriangleSoup& s, size_t n, uint32_t seed) {
  const std::vector<vec3> verts = input_vertices(mesh, s);
  AABB b = mesh.bounds();
  std::atomic<size_t> mismatches{0}, hits{0};
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    std::mt19937 rng(seed * 1000003u + uint32_t(i));
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    vec3 o = b.lo + (b.hi - b.lo) * vec3(u(rng), u(rng), u(rng)) * 1.4f - 0.2f * (b.hi - b.lo);
    vec3 target = b.lo + (b.hi - b.lo) * vec3(u(rng), u(rng), u(rng));
    vec3 d = glm::normalize(target - o);
    BruteHit ref = brute_force(verts, o, d);
    float tmax = kInf;
    MeshHit h;
    bool found = intersect_mesh(mesh, o, d, tmax, h);
    bool ok = found == (ref.prim != ~0u) && (!found || (h.t == ref.t && tmax == h.t));
    // Stored-order traversal finds the same closest distance.
    float tmax_u = kInf;
    MeshHit hu;
    bool found_u = intersect_mesh(mesh, o, d, tmax_u, hu, TraversalOrder::Unordered);
    ok = ok && found_u == found && (!found || hu.t == ref.t);
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

TEST(BVH, BinaryBuildersInvariants) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<AABB> boxes(3000);
  for (AABB& b : boxes) {
    vec3 c(u(rng), u(rng), u(rng));
    b.grow(c - 0.05f * vec3(std::abs(u(rng)), std::abs(u(rng)), std::abs(u(rng))));
    b.grow(c + 0.05f * vec3(std::abs(u(rng)), std::abs(u(rng)), std::abs(u(rng))));
  }
  boxes[17] = AABB{};  // empty boxes stay out of the tree
  for (SplitMethod m : {SplitMethod::BinnedSAH, SplitMethod::SweepSAH, SplitMethod::Midpoint}) {
    for (int block : {1, 4}) {
      BuildOptions opt;
      opt.method = m;
      opt.sah_block_size = block;
      BVH bvh = build_bvh(boxes, opt);
      check_binary_invariants(bvh, boxes);
      EXPECT_EQ(bvh.prim_order.size(), boxes.size() - 1);
      EXPECT_GT(sah_cost(bvh), 0.0f);
    }
  }
}

TEST(BVH, InvariantsOnRandomTriangles) {
  for (SplitMethod m : {SplitMethod::BinnedSAH, SplitMethod::SweepSAH, SplitMethod::Midpoint}) {
    BuildOptions opt;
    opt.method = m;
    TriangleSoup s = random_soup(5000, 7);
    for (int w : widths()) {
      Mesh mesh = make_mesh(s, with_width(opt, w));
      EXPECT_EQ(mesh.width(), w);
      check_invariants(mesh, s);
    }
  }
}

TEST(BVH, MillionRandomRaysMatchBruteForce) {
  TriangleSoup s = random_soup(300, 11, 0.3f);
  for (int w : widths()) {
    Mesh mesh = make_mesh(s, with_width({}, w));
    check_invariants(mesh, s);
    check_against_brute_force(mesh, s, 1000000, 1);
  }
}

TEST(BVH, EveryBuilderMatchesBruteForce) {
  for (SplitMethod m : {SplitMethod::SweepSAH, SplitMethod::Midpoint, SplitMethod::BinnedSAH}) {
    for (int leaf : {1, 3, 8, 32}) {
      BuildOptions opt;
      opt.method = m;
      opt.max_leaf_size = leaf;
      opt.bins = leaf == 3 ? 4 : 32;
      TriangleSoup s = random_soup(1000, 3);
      for (int w : widths()) {
        Mesh mesh = make_mesh(s, with_width(opt, w));
        check_invariants(mesh, s);
        check_against_brute_force(mesh, s, 20000, 2);
      }
    }
  }
}

TEST(BVH, SingleTriangleAndTinyMeshes) {
  for (size_t n : {1, 2, 3, 4, 5, 9}) {
    TriangleSoup s = random_soup(n, 21 + uint32_t(n), 0.5f);
    for (int w : widths()) {
      Mesh mesh = make_mesh(s, with_width({}, w));
      check_invariants(mesh, s);
      check_against_brute_force(mesh, s, 5000, 4);
    }
  }
}

TEST(BVH, RealMeshInvariantsAndBruteForce) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  for (int w : widths()) {
    Mesh mesh = make_mesh(s, with_width({}, w));
    check_invariants(mesh, s);
    check_against_brute_force(mesh, s, 3000, 5);
  }
}

TEST(BVH, BinnedSAHIsCloseToFullSweep) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  BuildOptions binned, sweep;
  sweep.method = SplitMethod::SweepSAH;
  float cb = mesh_sah_cost(make_mesh(s, binned)), cs = mesh_sah_cost(make_mesh(s, sweep));
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
  check_against_brute_force(mesh, s, 2000, 9);
}

// Triangles with two equal corners can never be hit: they are left out of
// the tree (each one sent its Tri4 block down the exact-zero path for every
// ray reaching it), counted apart from the invalid ones (which the add-on
// reports as a problem in the mesh).
TEST(BVH, TrianglesWithTwoEqualCornersAreLeftOutNotReported) {
  TriangleSoup s = random_soup(100, 5);
  auto corner = [&](int t, int k) { return &s.positions[3 * s.indices[3 * t + k]]; };
  auto copy_corner = [&](int t, int from, int to) { std::copy(corner(t, from), corner(t, from) + 3, corner(t, to)); };
  copy_corner(3, 0, 1);                             // triangle 3: corners 0 and 1 equal
  copy_corner(4, 2, 0), copy_corner(4, 2, 1);       // triangle 4: all three equal
  s.positions[3 * s.indices[3 * 7]] = std::nanf("");  // triangle 7: NaN corner (invalid)
  for (int w : widths()) {
    Mesh mesh = make_mesh(s, with_width({}, w));
    EXPECT_EQ(mesh.num_degenerate_triangles, 2u);
    EXPECT_EQ(mesh.num_skipped_triangles, 1u);
    EXPECT_EQ(mesh.prim_ids.size(), 97u);
    for (uint32_t id : mesh.prim_ids) EXPECT_TRUE(id != 3 && id != 4 && id != 7);
    check_against_brute_force(mesh, s, 2000, 9);
  }
}

TEST(BVH, IdenticalTrianglesStayWithinTraversalDepth) {
  // 100k copies of one triangle: centroids cannot be separated.
  TriangleSoup s;
  s.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  for (int i = 0; i < 100000; ++i) s.indices.insert(s.indices.end(), {0, 1, 2});
  Mesh mesh = make_mesh(s);
  EXPECT_LE(mesh.width() == 8 ? mesh.bvh8.depth() : mesh.bvh.depth(), 64);
  check_invariants(mesh, s);
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

// The collapse sizes its arena exactly (one allocation, no slack), and it is
// cache-line aligned; one of 2 MB or more starts on a 2 MB boundary (large pages).
TEST(BVH, WideArraysAreExactAndAligned) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/igea.ply");
  for (int w : widths()) {
    Mesh mesh = make_mesh(s, with_width({}, w));
    auto check = [](const auto& a) {
      EXPECT_EQ(a.capacity(), a.size());
      const size_t bytes = a.size() * sizeof(a[0]);
      const uintptr_t p = reinterpret_cast<uintptr_t>(a.data());
      EXPECT_EQ(p % 64, 0u);
      if (bytes >= (size_t(2) << 20)) EXPECT_EQ(p % (size_t(2) << 20), 0u) << bytes << " bytes";
    };
    if (w == 8) check(mesh.bvh8.mem);
    else check(mesh.bvh.mem);
    EXPECT_GE(mesh.width() == 8 ? mesh.bvh8.num_blocks * sizeof(Tri4) : mesh.bvh.num_blocks * sizeof(Tri4),
              size_t(2) << 20) << "igea's triangle blocks should span large pages";
  }
}

// Each wide node's leaf blocks sit right behind it in the arena, in child
// order (the lines the hardware prefetcher streams in with the node).
TEST(BVH, LeafBlocksFollowTheirNode) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  for (int w : widths()) {
    const Mesh mesh = make_mesh(s, with_width({}, w));
    auto check = [](const auto& bvh, size_t node_bytes) {
      size_t checked = 0;
      std::vector<uint32_t> stack{0u};
      while (!stack.empty()) {
        const uint32_t i = stack.back();
        stack.pop_back();
        const auto& n = bvh.node(i);
        size_t next = size_t(i) * kNodeUnit + node_bytes;
        for (uint32_t c = 0; c < n.num_children; ++c) {
          const uint32_t ref = n.child[c];
          if (!bvh4_is_leaf(ref)) {
            stack.push_back(ref);
            continue;
          }
          ASSERT_EQ(size_t(bvh4_leaf_first(ref)) * kBlockUnit, next) << "node " << i << " child " << c;
          next += bvh4_leaf_blocks(ref) * sizeof(Tri4);
          ++checked;
        }
      }
      EXPECT_GT(checked, 1000u);
    };
    if (mesh.width() == 8) check(mesh.bvh8, sizeof(BVH8Node));
    else check(mesh.bvh, sizeof(BVH4Node));
  }
}

// Small subtrees collapsed into packed multi-block leaves where the wide SAH
// prices them lower: fewer nodes, no higher SAH than without, and the same
// hits (see also the brute-force tests, which run with the default options).
TEST(BVH, SmallSubtreesCollapseIntoLeaves) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/igea.ply");
  for (int w : widths()) {
    BuildOptions off = with_width({}, w);
    off.collapse_small_subtrees = false;
    const Mesh a = make_mesh(s, with_width({}, w)), b = make_mesh(s, off);
    auto nodes = [](const Mesh& m) { return m.width() == 8 ? m.bvh8.num_nodes : m.bvh.num_nodes; };
    auto wide_sah = [](const Mesh& m) { return m.width() == 8 ? sah_cost(m.bvh8) : sah_cost(m.bvh); };
    EXPECT_LT(nodes(a), nodes(b) * 9 / 10) << "width " << w;
    EXPECT_LE(wide_sah(a), wide_sah(b)) << "width " << w;
    const AABB box = a.bounds();
    const vec3 c = box.center();
    const float r = glm::length(box.extent());
    for (int i = 0; i < 2000; ++i) {
      const float u = (i + 0.5f) / 2000.0f, phi = 2.39996323f * i;
      const vec3 d(std::sqrt(1 - u * u) * std::cos(phi), std::sqrt(1 - u * u) * std::sin(phi), u);
      const vec3 o = c - r * d + 0.01f * r * vec3(std::sin(3.0f * i), std::cos(5.0f * i), 0.0f);
      float ta = kInf, tb = kInf;
      MeshHit ha, hb;
      const bool hit_a = intersect_mesh(a, o, d, ta, ha), hit_b = intersect_mesh(b, o, d, tb, hb);
      ASSERT_EQ(hit_a, hit_b) << "ray " << i;
      if (hit_a) ASSERT_EQ(ha.t, hb.t) << "ray " << i;
    }
  }
}

namespace {

// Two wide trees with the same layout: the same arena size and counts, and
// every node reached from the root and every leaf block byte for byte equal
// (the padding between them is never read).
template <typename Tree>
void expect_same_wide_tree(const Tree& a, const Tree& b) {
  ASSERT_EQ(a.mem.size(), b.mem.size());
  ASSERT_EQ(a.num_nodes, b.num_nodes);
  ASSERT_EQ(a.num_blocks, b.num_blocks);
  size_t nodes = 0, blocks = 0;
  std::vector<uint32_t> stack{0u};
  while (!stack.empty()) {
    const uint32_t i = stack.back();
    stack.pop_back();
    const auto& na = a.node(i);
    ASSERT_EQ(std::memcmp(&na, &b.node(i), sizeof(na)), 0) << "node " << i;
    ++nodes;
    for (uint32_t c = 0; c < na.num_children; ++c) {
      const uint32_t ref = na.child[c];
      if (!bvh4_is_leaf(ref)) {
        stack.push_back(ref);
        continue;
      }
      const uint32_t nb = bvh4_leaf_blocks(ref);
      ASSERT_EQ(std::memcmp(a.blocks(ref), b.blocks(ref), nb * sizeof(Tri4)), 0) << "leaf " << ref;
      blocks += nb;
    }
  }
  EXPECT_EQ(nodes, a.num_nodes);
  EXPECT_EQ(blocks, a.num_blocks);
}

}  // namespace

// The build runs as TBB tasks (parallel binning and partitions at the top,
// subtrees, the collapse's plan and emission); the tree must not depend on
// how many threads ran it, nor (for the collapse) on whether it ran in
// parallel at all: the subtrees are placed at offsets computed beforehand.
TEST(BVH, ParallelBuildIsIndependentOfThreadCount) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/igea.ply");
  for (int w : widths()) {
    for (bool next_to_parent : {true, false}) {
      BuildOptions opt = with_width({}, w);
      opt.leaves_next_to_parent = next_to_parent;
      Mesh one, two;
      tbb::task_arena(1).execute([&] { one = make_mesh(s, opt); });
      tbb::task_arena(2).execute([&] { two = make_mesh(s, opt); });
      ASSERT_EQ(one.prim_ids, two.prim_ids);
      EXPECT_EQ(mesh_sah_cost(one), mesh_sah_cost(two));
      if (one.width() == 8) expect_same_wide_tree(one.bvh8, two.bvh8);
      else expect_same_wide_tree(one.bvh, two.bvh);
    }
  }
}

// A build's arrays may be memory another build freed (bvh_memory.cpp keeps
// it mapped): nothing of what it held may reach the tree. A mesh built over
// igea's retained arrays and one built over fresh (zero) pages are the same.
TEST(BVH, TreeIndependentOfRetainedMemory) {
  const TriangleSoup big = load_mesh_file(shared_dir() + "/meshes/igea.ply");
  const TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  for (int w : widths()) {
    const BuildOptions opt = with_width({}, w);
    bvh_release_retained();
    Mesh fresh = make_mesh(s, opt);
    { Mesh other = make_mesh(big, opt); }
    { Mesh other = make_mesh(big, opt); }  // the second one's arrays come from the first's
    ASSERT_GT(bvh_retained_bytes(), 0u);
    const Mesh reused = make_mesh(s, opt);
    ASSERT_EQ(fresh.prim_ids, reused.prim_ids);
    ASSERT_EQ(leaf_order_vertices(fresh), leaf_order_vertices(reused));
    EXPECT_EQ(mesh_sah_cost(fresh), mesh_sah_cost(reused));
    if (fresh.width() == 8) expect_same_wide_tree(fresh.bvh8, reused.bvh8);
    else expect_same_wide_tree(fresh.bvh, reused.bvh);
  }
}

// The add-on's path (prepare_mesh, then build_mesh_bvh at commit: both
// parallel) gives the mesh build_mesh gives, at one and two threads, with
// invalid and degenerate triangles spread over the input.
TEST(BVH, PreparedMeshBuildsTheSameTreeAsBuildMesh) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/igea.ply");
  const size_t nv = s.positions.size() / 3;
  for (size_t t = 7; t < s.num_triangles(); t += 1009) {
    if (t % 3 == 0) s.indices[3 * t + 1] = uint32_t(nv + 5);        // index out of range: skipped
    else if (t % 3 == 1) s.indices[3 * t + 2] = s.indices[3 * t];  // two equal corners: degenerate
    else s.positions[3 * s.indices[3 * t]] = std::nanf("");         // non-finite corner: skipped (and its neighbours)
  }
  MeshInput in;
  in.positions = s.positions.data();
  in.num_vertices = nv;
  in.indices = s.indices.data();
  in.num_triangles = s.num_triangles();
  for (int w : widths()) {
    const BuildOptions opt = with_width({}, w);
    const Mesh direct = build_mesh(in, opt);
    EXPECT_GT(direct.num_skipped_triangles, 50u);
    EXPECT_GT(direct.num_degenerate_triangles, 50u);
    for (int threads : {1, 2}) {
      Mesh prepared;
      tbb::task_arena(threads).execute([&] {
        prepared = prepare_mesh(in);
        EXPECT_EQ(prepared.bounds().lo, direct.bounds().lo);
        EXPECT_EQ(prepared.bounds().hi, direct.bounds().hi);
        build_mesh_bvh(prepared, opt);
      });
      EXPECT_EQ(prepared.num_skipped_triangles, direct.num_skipped_triangles);
      EXPECT_EQ(prepared.num_degenerate_triangles, direct.num_degenerate_triangles);
      ASSERT_EQ(prepared.prim_ids, direct.prim_ids) << threads << " threads";
      ASSERT_EQ(leaf_order_vertices(prepared), leaf_order_vertices(direct));
      EXPECT_EQ(mesh_sah_cost(prepared), mesh_sah_cost(direct));
      if (direct.width() == 8) expect_same_wide_tree(prepared.bvh8, direct.bvh8);
      else expect_same_wide_tree(prepared.bvh, direct.bvh);
    }
  }
}

TEST(BVH, ParallelCollapseMatchesSerialCollapse) {
  TriangleSoup s = load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj");
  std::vector<AABB> boxes(s.num_triangles());
  const vec3* pos = reinterpret_cast<const vec3*>(s.positions.data());
  for (size_t i = 0; i < boxes.size(); ++i)
    for (int k = 0; k < 3; ++k) boxes[i].grow(pos[s.indices[3 * i + k]]);
  BuildOptions opt;
  opt.sah_block_size = 4;
  const BVH binary = build_bvh(boxes, opt);
  std::vector<vec3> verts(3 * binary.prim_order.size());
  for (size_t i = 0; i < binary.prim_order.size(); ++i)
    for (int k = 0; k < 3; ++k) verts[3 * i + k] = pos[s.indices[3 * binary.prim_order[i] + k]];
  for (bool next_to_parent : {true, false}) {
    BuildOptions par = opt, ser = opt;
    par.leaves_next_to_parent = ser.leaves_next_to_parent = next_to_parent;
    ser.parallel = false;
    tbb::task_arena(2).execute([&] {
      expect_same_wide_tree(collapse_to_bvh4(binary, verts.data(), par), collapse_to_bvh4(binary, verts.data(), ser));
      if (cpu_simd_level() == SimdLevel::AVX2)
        expect_same_wide_tree(collapse_to_bvh8(binary, verts.data(), par), collapse_to_bvh8(binary, verts.data(), ser));
    });
  }
}

namespace {

// Triangle boxes of a mesh file, in input order.
std::vector<AABB> triangle_boxes(const TriangleSoup& s) {
  std::vector<AABB> boxes(s.num_triangles());
  const vec3* pos = reinterpret_cast<const vec3*>(s.positions.data());
  for (size_t i = 0; i < boxes.size(); ++i)
    for (int k = 0; k < 3; ++k) boxes[i].grow(pos[s.indices[3 * i + k]]);
  return boxes;
}

// The same binary tree as reached from the roots (the arrays may differ in
// layout and in unused slots): equal boxes, leaf ranges and shapes.
void expect_same_binary_tree(const BVH& a, const BVH& b) {
  ASSERT_EQ(a.prim_order, b.prim_order);
  std::vector<std::pair<uint32_t, uint32_t>> stack{{0u, 0u}};
  size_t visited = 0;
  while (!stack.empty()) {
    const auto [i, j] = stack.back();
    stack.pop_back();
    const BVHNode &na = a.nodes[i], &nb = b.nodes[j];
    ASSERT_EQ(std::memcmp(&na.lo, &nb.lo, sizeof(vec3)), 0);
    ASSERT_EQ(std::memcmp(&na.hi, &nb.hi, sizeof(vec3)), 0);
    ASSERT_EQ(na.is_leaf(), nb.is_leaf());
    ++visited;
    if (na.is_leaf()) {
      ASSERT_EQ(na.first, nb.first);
      ASSERT_EQ(na.count, nb.count);
    } else {
      stack.push_back({na.first, nb.first});
      stack.push_back({na.first + 1, nb.first + 1});
    }
  }
  EXPECT_GT(visited, a.prim_order.size() / 4);
}

}  // namespace

// The binary tree itself (not only the wide tree collapsed from it) and its
// SAH cost do not depend on how many threads built it: node pairs come from
// per-task chunks, so only the array layout may differ.
TEST(BVH, BinaryTreeIsIndependentOfThreadCount) {
  const std::vector<AABB> boxes = triangle_boxes(load_mesh_file(shared_dir() + "/meshes/igea.ply"));
  for (int block : {1, 4}) {
    BuildOptions opt;
    opt.sah_block_size = block;
    BVH one, two;
    tbb::task_arena(1).execute([&] { one = build_bvh(boxes, opt); });
    tbb::task_arena(2).execute([&] { two = build_bvh(boxes, opt); });
    expect_same_binary_tree(one, two);
    EXPECT_EQ(sah_cost(one), sah_cost(two));
    check_binary_invariants(two, boxes);
  }
}

// sah_cost() of a binned build uses the sums the build kept; they equal the
// cost of walking the tree.
TEST(BVH, BuildSAHSumsEqualTheTreeWalk) {
  const std::vector<AABB> boxes = triangle_boxes(load_mesh_file(shared_dir() + "/meshes/stanford-bunny.obj"));
  for (int block : {1, 4}) {
    BuildOptions opt;
    opt.sah_block_size = block;
    BVH bvh = build_bvh(boxes, opt);
    ASSERT_GE(bvh.sah_inner_area, 0.0);
    BuildOptions costs;
    costs.traversal_cost = 1.5f;
    costs.intersection_cost = 0.75f;
    const float kept = sah_cost(bvh, costs);
    bvh.sah_inner_area = -1.0;  // not summed: sah_cost walks the tree
    const float walked = sah_cost(bvh, costs);
    EXPECT_NEAR(kept, walked, 1e-5f * walked);
    EXPECT_GT(walked, 1.0f);
  }
}

// Invalid boxes (empty, NaN, infinite) spread over a range large enough for
// the parallel partition: the references are made in one pass and moved
// down past the invalid ones afterwards (through the scratch buffer when the
// build has one, in place when not). Every valid box is in the tree once,
// the invalid ones nowhere, and threads do not change the tree.
TEST(BVH, InvalidBoxesInALargeBuildAreLeftOut) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<AABB> boxes(100000);
  for (AABB& b : boxes) {
    const vec3 c(u(rng), u(rng), u(rng));
    b.grow(c - 0.01f * vec3(std::abs(u(rng)), std::abs(u(rng)), std::abs(u(rng))));
    b.grow(c + 0.01f * vec3(std::abs(u(rng)), std::abs(u(rng)), std::abs(u(rng))));
  }
  std::vector<bool> valid(boxes.size(), true);
  for (size_t i = 5; i < boxes.size(); i += 997) {
    switch ((i / 997) % 4) {
      case 0: boxes[i] = AABB{}; break;                                           // empty
      case 1: boxes[i].lo.y = std::nanf(""); break;                               // NaN
      case 2: boxes[i].hi.z = std::numeric_limits<float>::infinity(); break;      // infinite
      case 3: std::swap(boxes[i].lo.x, boxes[i].hi.x); break;                     // lo.x > hi.x: empty
    }
    valid[i] = false;
  }
  const size_t num_valid = size_t(std::count(valid.begin(), valid.end(), true));
  for (bool parallel : {true, false}) {
    BuildOptions opt;
    opt.parallel = parallel;
    BVH one, two;
    tbb::task_arena(1).execute([&] { one = build_bvh(boxes, opt); });
    tbb::task_arena(2).execute([&] { two = build_bvh(boxes, opt); });
    ASSERT_EQ(one.prim_order.size(), num_valid);
    std::vector<int> seen(boxes.size(), 0);
    for (uint32_t p : one.prim_order) seen[p]++;
    for (size_t i = 0; i < boxes.size(); ++i) ASSERT_EQ(seen[i], valid[i] ? 1 : 0) << "box " << i;
    expect_same_binary_tree(one, two);
    // Leaves bound their boxes.
    std::vector<uint32_t> stack{0u};
    while (!stack.empty()) {
      const BVHNode& n = one.nodes[stack.back()];
      stack.pop_back();
      if (!n.is_leaf()) {
        stack.push_back(n.first), stack.push_back(n.first + 1);
        continue;
      }
      for (uint32_t k = n.first; k < n.first + n.count; ++k)
        ASSERT_TRUE(AABB({n.lo, n.hi}).contains(boxes[one.prim_order[k]]));
    }
  }
}
