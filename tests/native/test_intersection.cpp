// Hand-made ray/triangle and ray/box cases: hits, misses, edges, vertices,
// parallel rays.
#include <gtest/gtest.h>

#include <random>

#include "core/aabb.h"
#include "core/bvh8.h"
#include "core/mesh.h"
#include "core/simd.h"
#include "core/traverse.h"
#include "core/simd_tri4.h"
#include "core/triangle.h"

using namespace tessera;


namespace {
const vec3 P0(0, 0, 0), P1(1, 0, 0), P2(0, 1, 0);

bool hit_tri(vec3 o, vec3 d, TriangleHit* out = nullptr, float tmax = kInf) {
  TriangleHit h;
  bool r = intersect_triangle(P0, P1, P2, o, RayShear(d), tmax, h);
  if (out) *out = h;
  return r;
}
}  // namespace

TEST(Triangle, HitsInteriorWithDistanceAndBarycentrics) {
  TriangleHit h;
  ASSERT_TRUE(hit_tri(vec3(0.25f, 0.5f, 2.0f), vec3(0, 0, -1), &h));
  EXPECT_FLOAT_EQ(h.t, 2.0f);
  EXPECT_FLOAT_EQ(h.u, 0.25f);
  EXPECT_FLOAT_EQ(h.v, 0.5f);
  ASSERT_TRUE(hit_tri(vec3(0.25f, 0.5f, -2.0f), vec3(0, 0, 1), &h));  // from behind: two-sided
  EXPECT_FLOAT_EQ(h.t, 2.0f);
}

TEST(Triangle, MissesOutsideAndBehindAndBeyondTmax) {
  EXPECT_FALSE(hit_tri(vec3(0.8f, 0.8f, 1.0f), vec3(0, 0, -1)));
  EXPECT_FALSE(hit_tri(vec3(-0.1f, 0.5f, 1.0f), vec3(0, 0, -1)));
  EXPECT_FALSE(hit_tri(vec3(0.2f, 0.2f, -1.0f), vec3(0, 0, -1)));  // triangle behind the origin
  EXPECT_FALSE(hit_tri(vec3(0.2f, 0.2f, 1.0f), vec3(0, 0, -1), nullptr, 0.5f));
}

TEST(Triangle, EdgesAndVerticesCountAsInside) {
  EXPECT_TRUE(hit_tri(vec3(0.5f, 0.0f, 1.0f), vec3(0, 0, -1)));  // on edge p0-p1
  EXPECT_TRUE(hit_tri(vec3(0.5f, 0.5f, 1.0f), vec3(0, 0, -1)));  // on the hypotenuse
  EXPECT_TRUE(hit_tri(vec3(0.0f, 0.0f, 1.0f), vec3(0, 0, -1)));  // on a vertex
  EXPECT_TRUE(hit_tri(vec3(1.0f, 0.0f, 1.0f), vec3(0, 0, -1)));
}

TEST(Triangle, SharedEdgeIsHitByOneOfTheTwoTriangles) {
  // Square split along its diagonal; rays exactly on the diagonal.
  const vec3 a(0, 0, 0), b(1, 0, 0), c(1, 1, 0), d(0, 1, 0);
  int misses = 0;
  for (int i = 0; i <= 1000; ++i) {
    float s = i / 1000.0f;
    vec3 dir = glm::normalize(vec3(0.001f * (i % 7), -0.0007f * (i % 5), -1.0f));
    vec3 o = vec3(s, s, 0) - dir * (3.0f / -dir.z);  // aimed at (s, s, 0) on the diagonal
    RayShear sh(dir);
    TriangleHit h;
    bool h1 = intersect_triangle(a, b, c, o, sh, kInf, h);
    bool h2 = intersect_triangle(a, c, d, o, sh, kInf, h);
    if (!h1 && !h2) ++misses;
  }
  EXPECT_EQ(misses, 0);
}

TEST(Triangle, ParallelAndDegenerateNeverHit) {
  EXPECT_FALSE(hit_tri(vec3(0.2f, 0.2f, 0.0f), vec3(1, 0, 0)));   // in the plane
  EXPECT_FALSE(hit_tri(vec3(0.2f, 0.2f, 0.5f), vec3(1, 0, 0)));   // above, parallel
  TriangleHit h;
  const vec3 q(1, 1, 0);
  EXPECT_FALSE(intersect_triangle(q, q, q, vec3(1, 1, 1), RayShear(vec3(0, 0, -1)), kInf, h));  // zero area
  EXPECT_FALSE(intersect_triangle(vec3(0, 0, 0), vec3(1, 0, 0), vec3(2, 0, 0), vec3(0.5f, 0, 1),
                                  RayShear(vec3(0, 0, -1)), kInf, h));  // collinear
}

TEST(Box, HitsMissesAndParallelRays) {
  const vec3 lo(-1), hi(1);
  auto test = [&](vec3 o, vec3 d, float tmax = kInf) {
    TraversalRay r(o, d, tmax);
    return intersect_box(lo, hi, r.o, r.inv_d, r.tmax);
  };
  EXPECT_FLOAT_EQ(test(vec3(-3, 0, 0), vec3(1, 0, 0)), 2.0f);
  EXPECT_EQ(test(vec3(-3, 2, 0), vec3(1, 0, 0)), kInf);          // parallel, outside the slab
  EXPECT_FLOAT_EQ(test(vec3(-3, 0.5f, 0), vec3(1, 0, 0)), 2.0f); // parallel, inside the slab
  EXPECT_FLOAT_EQ(test(vec3(0, 0, 0), vec3(0, 1, 0)), 0.0f);     // origin inside
  EXPECT_EQ(test(vec3(-3, 0, 0), vec3(-1, 0, 0)), kInf);         // pointing away
  EXPECT_EQ(test(vec3(-3, 0, 0), vec3(1, 0, 0), 1.5f), kInf);    // beyond tmax
  EXPECT_FLOAT_EQ(test(vec3(-3, 0.999f, 0), vec3(1, 0, 0)), 2.0f);  // grazing just inside the face y = 1
  // Flat box (a planar mesh's bounds) is still hit.
  TraversalRay r(vec3(0, 0, 5), vec3(0, 0, -1), kInf);
  EXPECT_FLOAT_EQ(intersect_box(vec3(-1, -1, 0), vec3(1, 1, 0), r.o, r.inv_d, r.tmax), 5.0f);
  // Parallel ray whose origin lies exactly on a face, for either sign of the zero
  // direction component: the two-origin test keeps it inside.
  for (float zero : {0.0f, -0.0f})
    for (float y : {-1.0f, 1.0f}) {
      TraversalRay p(vec3(-3, y, 0), vec3(1, zero, 0), kInf);
      EXPECT_FLOAT_EQ(intersect_box(lo, hi, p.o_lo, p.o_hi, p.inv_d, p.tmax), 2.0f) << y << " " << zero;
    }
}

// The same watertightness through the mesh path (BVH4 + four-triangle SIMD
// test): a grid of squares split along alternating diagonals, rays aimed
// exactly at edges and vertices never pass through.
TEST(Triangle, MeshGridHasNoCracksThroughSimdPath) {
  const int n = 16;
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) pos.insert(pos.end(), {x / float(n), y / float(n), 0.25f * (x % 3) / n});
  auto id = [&](int x, int y) { return uint32_t(y * (n + 1) + x); };
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      if ((x + y) % 2) idx.insert(idx.end(), {id(x, y), id(x + 1, y), id(x + 1, y + 1), id(x, y), id(x + 1, y + 1), id(x, y + 1)});
      else idx.insert(idx.end(), {id(x, y), id(x + 1, y), id(x, y + 1), id(x + 1, y), id(x + 1, y + 1), id(x, y + 1)});
    }
  MeshInput in;
  in.positions = pos.data();
  in.num_vertices = pos.size() / 3;
  in.indices = idx.data();
  in.num_triangles = idx.size() / 3;
  // Width 4 (SSE2), 8 with the AVX2 kernel, 8 with the AVX-512 kernel.
  std::vector<std::pair<int, bool>> widths{{4, false}};
  if (cpu_simd_level() == SimdLevel::AVX2) widths.push_back({8, false});
  if (cpu_has_avx512()) widths.push_back({8, true});
  const bool saved_kernel = g_bvh8_avx512;
  for (auto [width, avx512] : widths) {
  g_bvh8_avx512 = avx512;
  BuildOptions opt;
  opt.bvh_width = width;
  Mesh mesh = build_mesh(in, opt);
  ASSERT_EQ(mesh.width(), width);
  int misses = 0, tests = 0, occl_disagree = 0;
  for (int y = 0; y <= 4 * n; ++y)
    for (int x = 0; x <= 4 * n; ++x) {
      // Points on grid lines (every 4th sample is a vertex, others lie on edges).
      if (x % 4 && y % 4) continue;
      const float px = x / float(4 * n), py = y / float(4 * n);
      if (px <= 0.0f || py <= 0.0f || px >= 1.0f || py >= 1.0f) continue;
      for (int k = 0; k < 3; ++k) {
        vec3 dir = glm::normalize(vec3(0.013f * (k - 1), -0.007f * k, k == 2 ? 1.0f : -1.0f));
        // Target on the surface: interpolate z from the grid (exact on vertices only);
        // use a vertical-ish ray so it crosses the surface near (px, py).
        vec3 target(px, py, 0.1f);
        vec3 o = target - dir * 3.0f;
        float tmax = kInf;
        MeshHit h;
        ++tests;
        if (!intersect_mesh(mesh, o, dir, tmax, h)) ++misses;
        if (occluded_mesh(mesh, o, dir, kInf) != (tmax != kInf)) ++occl_disagree;
      }
    }
  EXPECT_GT(tests, 500);
  EXPECT_EQ(misses, 0) << "width " << width << (avx512 ? " avx512" : "");
  EXPECT_EQ(occl_disagree, 0) << "width " << width << (avx512 ? " avx512" : "");
  }
  g_bvh8_avx512 = saved_kernel;
}

// The SIMD path gives bit-identical results to the scalar test.
TEST(Triangle, SimdMeshHitsEqualScalarTest) {
  const vec3 a(0, 0, 0), b(1, 0, 0), c(1, 1, 0), d(0, 1, 0);
  std::vector<float> pos = {a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z, d.x, d.y, d.z};
  std::vector<uint32_t> idx = {0, 1, 2, 0, 2, 3};
  MeshInput in;
  in.positions = pos.data();
  in.num_vertices = 4;
  in.indices = idx.data();
  in.num_triangles = 2;
  Mesh mesh = build_mesh(in);
  for (int i = 0; i <= 1000; ++i) {
    float s = i / 1000.0f;
    vec3 dir = glm::normalize(vec3(0.001f * (i % 7), -0.0007f * (i % 5), -1.0f));
    vec3 o = vec3(s, s, 0) - dir * (3.0f / -dir.z);
    RayShear sh(dir);
    TriangleHit h1, h2;
    bool r1 = intersect_triangle(a, b, c, o, sh, kInf, h1);
    bool r2 = intersect_triangle(a, c, d, o, sh, r1 ? h1.t : kInf, h2);
    float t_ref = r2 ? h2.t : (r1 ? h1.t : kInf);
    float tmax = kInf;
    MeshHit mh;
    ASSERT_TRUE(intersect_mesh(mesh, o, dir, tmax, mh)) << i;
    EXPECT_EQ(mh.t, t_ref) << i;
  }
}

namespace {
// 4000 small random triangles in [-1, 1]^3 and two exactly planar squares at
// z = 0.5 (rays graze their faces and edges).
MeshInput random_soup(std::vector<float>& pos, std::vector<uint32_t>& idx) {
  std::mt19937 rng(77);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < 4000; ++i) {
    vec3 c(u(rng), u(rng), u(rng));
    for (int k = 0; k < 3; ++k) {
      vec3 p = c + 0.08f * vec3(u(rng), u(rng), u(rng));
      pos.insert(pos.end(), {p.x, p.y, p.z});
      idx.push_back(uint32_t(3 * i + k));
    }
  }
  const float q[] = {-1, -1, 0.5f, 1, -1, 0.5f, 1, 1, 0.5f, -1, 1, 0.5f};
  const uint32_t base = uint32_t(pos.size() / 3);
  pos.insert(pos.end(), q, q + 12);
  idx.insert(idx.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  MeshInput in;
  in.positions = pos.data();
  in.num_vertices = pos.size() / 3;
  in.indices = idx.data();
  in.num_triangles = idx.size() / 3;
  return in;
}
}  // namespace

// The AVX-512 BVH8 kernel (mask-register node test, sorting-network child
// order, compress-store pushes) gives exactly the AVX2 kernel's closest hits
// (t, u, v, triangle: same visiting order, so ties go the same way) and
// any-hit answers, and its distances are the scalar test's nearest hit.
TEST(Triangle, Bvh8Avx512KernelEqualsAvx2Kernel) {
  if (!cpu_has_avx512()) GTEST_SKIP() << "no AVX-512 on this CPU (or TESSERA_SIMD set)";
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  const MeshInput in = random_soup(pos, idx);
  BuildOptions o8;
  o8.bvh_width = 8;
  const Mesh m = build_mesh(in, o8);
  ASSERT_EQ(m.width(), 8);
  std::mt19937 rng(91);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const bool saved_kernel = g_bvh8_avx512;
  int hits = 0, multi = 0;
  for (int i = 0; i < 200000; ++i) {
    vec3 o(1.5f * u(rng), 1.5f * u(rng), 1.5f * u(rng));
    vec3 d(u(rng), u(rng), u(rng));
    if (i % 5 == 0) d = vec3(0.0f, 0.0f, d.z);  // axis-parallel rays
    if (i % 7 == 0) o.z = 0.5f;                 // origins on the plane
    if (i % 11 == 0) o = vec3(0.0f);            // many children at tnear = 0
    if (i % 13 == 0) d.x = -0.0f;               // the ray setup's clamp and signs
    if (i % 17 == 0) d.y = (i & 1 ? 1e-35f : -1e-31f);
    if (glm::length(d) == 0.0f) continue;
    for (TraversalOrder order : {TraversalOrder::Ordered, TraversalOrder::Unordered}) {
      float t2 = kInf, t5 = kInf;
      MeshHit h2, h5;
      g_bvh8_avx512 = false;
      const bool f2 = intersect_mesh(m, o, d, t2, h2, order);
      g_bvh8_avx512 = true;
      const bool f5 = intersect_mesh(m, o, d, t5, h5, order);
      ASSERT_EQ(f2, f5) << i;
      if (f2) {
        ASSERT_EQ(h2.t, h5.t) << i;
        ASSERT_EQ(h2.u, h5.u) << i;
        ASSERT_EQ(h2.v, h5.v) << i;
        ASSERT_EQ(h2.prim, h5.prim) << i;
        hits += order == TraversalOrder::Ordered;
      }
    }
    for (float tmax : {kInf, 0.3f}) {
      g_bvh8_avx512 = false;
      const bool a = occluded_mesh(m, o, d, tmax);
      g_bvh8_avx512 = true;
      ASSERT_EQ(a, occluded_mesh(m, o, d, tmax)) << i;
    }
    if (i % 100 == 0) {
      // Against the scalar test over every triangle.
      const RayShear sh(d);
      float t_ref = kInf;
      int n_hit = 0;
      for (size_t k = 0; k < m.tri_verts.size() / 3; ++k) {
        TriangleHit th;
        if (intersect_triangle(m.tri_verts[3 * k], m.tri_verts[3 * k + 1], m.tri_verts[3 * k + 2], o, sh, t_ref, th)) {
          t_ref = th.t;
          ++n_hit;
        }
      }
      float t5 = kInf;
      MeshHit h5;
      g_bvh8_avx512 = true;
      const bool f5 = intersect_mesh(m, o, d, t5, h5);
      ASSERT_EQ(f5, t_ref != kInf) << i;
      if (f5) ASSERT_EQ(h5.t, t_ref) << i;
      multi += n_hit > 1;
    }
  }
  g_bvh8_avx512 = saved_kernel;
  EXPECT_GT(hits, 10000);
  EXPECT_GT(multi, 10);
}

// The AVX-512 kernel's node test by multiply-add (per-ray constants o inv
// rounded outwards) stays conservative far from the origin: the random soup
// moved out to 1e4 and 1e6 (and axis-parallel rays there, whose o inv is
// ~1e36, and from 1e9, where it is inf and the kernel falls back to the
// subtract-then-multiply test), rays aimed exactly at vertices (box corners)
// and along the planar squares' edges: the closest hit equals the scalar
// test over every triangle, and the AVX2 kernel's.
TEST(Triangle, Bvh8Avx512KernelFarFromOriginMatchesBruteForce) {
  if (!cpu_has_avx512()) GTEST_SKIP() << "no AVX-512 on this CPU (or TESSERA_SIMD set)";
  const bool saved_kernel = g_bvh8_avx512;
  for (float offset : {1e4f, 1e6f}) {
    std::vector<float> pos;
    std::vector<uint32_t> idx;
    MeshInput in = random_soup(pos, idx);
    const vec3 shift(offset, -0.5f * offset, 0.25f * offset);
    for (size_t i = 0; i < pos.size(); i += 3) pos[i] += shift.x, pos[i + 1] += shift.y, pos[i + 2] += shift.z;
    BuildOptions o8;
    o8.bvh_width = 8;
    const Mesh m = build_mesh(in, o8);
    ASSERT_EQ(m.width(), 8);
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::uniform_int_distribution<size_t> pick(0, pos.size() / 3 - 1);
    int hits = 0;
    for (int i = 0; i < 3000; ++i) {
      vec3 o = shift + vec3(1.5f * u(rng), 1.5f * u(rng), 1.5f * u(rng));
      const size_t v = pick(rng);
      vec3 d = vec3(pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]) - o;  // at a vertex
      if (i % 3 == 0) d = vec3(u(rng), u(rng), u(rng));
      if (i % 5 == 0) o.z = shift.z + 0.5f, d.z = 0.0f;  // in the squares' plane
      if (i % 7 == 0) d = vec3(0.0f, 0.0f, i & 8 ? 1.0f : -1.0f), o.x = shift.x + (i & 16 ? 1.0f : -1.0f);  // along an edge
      if (i % 11 == 0) d.y = (i & 1 ? 1e-35f : -1e-31f);
      if (i % 13 == 0) o.x = 1e9f;  // o inv overflows on the parallel axes
      if (glm::length(d) == 0.0f) continue;
      const RayShear sh(d);
      float t_ref = kInf;
      for (size_t k = 0; k < m.tri_verts.size() / 3; ++k) {
        TriangleHit th;
        if (intersect_triangle(m.tri_verts[3 * k], m.tri_verts[3 * k + 1], m.tri_verts[3 * k + 2], o, sh, t_ref, th))
          t_ref = th.t;
      }
      for (bool avx512 : {false, true}) {
        g_bvh8_avx512 = avx512;
        float t = kInf;
        MeshHit h;
        const bool f = intersect_mesh(m, o, d, t, h);
        ASSERT_EQ(f, t_ref != kInf) << "offset " << offset << " ray " << i << (avx512 ? " avx512" : " avx2");
        if (f) ASSERT_EQ(h.t, t_ref) << "offset " << offset << " ray " << i << (avx512 ? " avx512" : " avx2");
        ASSERT_EQ(occluded_mesh(m, o, d, kInf), t_ref != kInf) << "offset " << offset << " ray " << i;
      }
      hits += t_ref != kInf;
    }
    EXPECT_GT(hits, 1000) << "offset " << offset;
  }
  g_bvh8_avx512 = saved_kernel;
}

// The AVX2 BVH8 (eight-wide nodes) and the SSE2 BVH4 give bit-identical
// closest hits (t, u, v, triangle) and the same any-hit answers: both use the
// same binary tree, the same slab arithmetic per lane and the same Tri4 test.
TEST(Triangle, Bvh8HitsEqualBvh4BitForBit) {
  if (cpu_simd_level() != SimdLevel::AVX2) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937 rng(77);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  for (int i = 0; i < 4000; ++i) {
    vec3 c(u(rng), u(rng), u(rng));
    for (int k = 0; k < 3; ++k) {
      vec3 p = c + 0.08f * vec3(u(rng), u(rng), u(rng));
      pos.insert(pos.end(), {p.x, p.y, p.z});
      idx.push_back(uint32_t(3 * i + k));
    }
  }
  // A few axis-aligned, exactly planar squares so that rays graze faces and edges.
  const float q[] = {-1, -1, 0.5f, 1, -1, 0.5f, 1, 1, 0.5f, -1, 1, 0.5f};
  const uint32_t base = uint32_t(pos.size() / 3);
  pos.insert(pos.end(), q, q + 12);
  idx.insert(idx.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  MeshInput in;
  in.positions = pos.data();
  in.num_vertices = pos.size() / 3;
  in.indices = idx.data();
  in.num_triangles = idx.size() / 3;
  BuildOptions o4, o8;
  o4.bvh_width = 4;
  o8.bvh_width = 8;
  Mesh m4 = build_mesh(in, o4), m8 = build_mesh(in, o8);
  ASSERT_EQ(m4.width(), 4);
  ASSERT_EQ(m8.width(), 8);
  ASSERT_EQ(m4.prim_ids, m8.prim_ids);
  int hits = 0;
  for (int i = 0; i < 200000; ++i) {
    vec3 o(1.5f * u(rng), 1.5f * u(rng), 1.5f * u(rng));
    vec3 d(u(rng), u(rng), u(rng));
    if (i % 5 == 0) d = vec3(0.0f, 0.0f, d.z);  // axis-parallel rays
    if (i % 7 == 0) o.z = 0.5f;                 // origins on the plane
    if (glm::length(d) == 0.0f) continue;
    float t4 = kInf, t8 = kInf;
    MeshHit h4, h8;
    for (TraversalOrder order : {TraversalOrder::Ordered, TraversalOrder::Unordered}) {
      t4 = t8 = kInf;
      const bool f4 = intersect_mesh(m4, o, d, t4, h4, order);
      const bool f8 = intersect_mesh(m8, o, d, t8, h8, order);
      ASSERT_EQ(f4, f8) << i;
      if (f4) {
        ASSERT_EQ(h4.t, h8.t) << i;
        ASSERT_EQ(h4.u, h8.u) << i;
        ASSERT_EQ(h4.v, h8.v) << i;
        ASSERT_EQ(h4.prim, h8.prim) << i;
        hits += order == TraversalOrder::Ordered;
      }
    }
    ASSERT_EQ(occluded_mesh(m4, o, d, kInf), occluded_mesh(m8, o, d, kInf)) << i;
    ASSERT_EQ(occluded_mesh(m4, o, d, 0.3f), occluded_mesh(m8, o, d, 0.3f)) << i;
  }
  EXPECT_GT(hits, 10000);
}

// Zero-area triangles (two equal vertices, or three in a line) and rays
// through grid vertices and edges make edge functions exactly zero: the Tri4
// test redoes those lanes' edge functions in double, as the scalar test does.
// Every kernel's closest hit is the scalar test's (nearest t over all
// triangles; t, u, v of the triangle found, bit for bit), any hit agrees.
TEST(Triangle, ZeroEdgeLanesEqualScalarTestInEveryKernel) {
  const int n = 12;
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) pos.insert(pos.end(), {x / float(n), y / float(n), 0.125f * (x % 2)});
  auto id = [&](int x, int y) { return uint32_t(y * (n + 1) + x); };
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      idx.insert(idx.end(), {id(x, y), id(x + 1, y), id(x + 1, y + 1), id(x, y), id(x + 1, y + 1), id(x, y + 1)});
      if ((x + y) % 3 == 0) idx.insert(idx.end(), {id(x, y), id(x + 1, y), id(x + 1, y)});  // two equal vertices
      if ((x + y) % 5 == 0 && x + 2 <= n) idx.insert(idx.end(), {id(x, y), id(x + 1, y), id(x + 2, y)});  // in a line
    }
  MeshInput in;
  in.positions = pos.data();
  in.num_vertices = pos.size() / 3;
  in.indices = idx.data();
  in.num_triangles = idx.size() / 3;
  std::vector<std::pair<int, bool>> kernels{{4, false}};
  if (cpu_simd_level() == SimdLevel::AVX2) kernels.push_back({8, false});
  if (cpu_has_avx512()) kernels.push_back({8, true});
  const bool saved_kernel = g_bvh8_avx512;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int lane_hits = 0;
  for (auto [width, avx512] : kernels) {
    g_bvh8_avx512 = avx512;
    BuildOptions opt;
    opt.bvh_width = width;
    const Mesh m = build_mesh(in, opt);
    ASSERT_EQ(m.width(), width);
    int hits = 0, near_miss = 0;
    for (int i = 0; i < 20000; ++i) {
      // Through a grid vertex or a point on a grid edge, from above or below.
      const int gx = int(rng() % (4 * n + 1)), gy = (i & 1) ? 4 * int(rng() % (n + 1)) : int(rng() % (4 * n + 1));
      const vec3 target(gx / float(4 * n), gy / float(4 * n), (gx % 8 == 4) ? 0.125f : 0.0f);
      vec3 d(0.2f * u(rng), 0.2f * u(rng), i % 3 ? -1.0f : 1.0f);
      if (i % 4 == 0) d.x = 0.0f;
      if (i % 6 == 0) d = vec3(u(rng), 0.0f, 0.05f * u(rng));  // grazing
      const vec3 o = target - 2.0f * d;
      const RayShear sh(d);
      float t_ref = kInf;
      for (size_t k = 0; k < m.tri_verts.size() / 3; ++k) {
        TriangleHit th;
        if (intersect_triangle(m.tri_verts[3 * k], m.tri_verts[3 * k + 1], m.tri_verts[3 * k + 2], o, sh, t_ref, th))
          t_ref = th.t;
      }
      for (TraversalOrder order : {TraversalOrder::Ordered, TraversalOrder::Unordered}) {
        float tmax = kInf;
        MeshHit h;
        const bool f = intersect_mesh(m, o, d, tmax, h, order);
        ASSERT_EQ(f, t_ref != kInf) << i << " width " << width << (avx512 ? " avx512" : "");
        if (!f) continue;
        TriangleHit th;
        const vec3* v = &m.tri_verts[3 * size_t(h.prim)];
        ASSERT_TRUE(intersect_triangle(v[0], v[1], v[2], o, sh, kInf, th)) << i;
        ASSERT_EQ(h.t, th.t) << i;
        ASSERT_EQ(h.u, th.u) << i;
        ASSERT_EQ(h.v, th.v) << i;
        // The nearest hit, or (where triangles meet at a vertex) one an ulp
        // or so farther: a box whose entry distance rounds above the hit so
        // far is culled, though a triangle in it may round below.
        ASSERT_LE(h.t - t_ref, 1e-6f * t_ref) << i;
        near_miss += h.t != t_ref;
        hits += order == TraversalOrder::Ordered;
      }
      ASSERT_EQ(occluded_mesh(m, o, d, kInf), t_ref != kInf) << i;
      // The Tri4 test (SSE2 compilation) against the scalar one, lane by
      // lane, over every block of four triangles (zero lanes included).
      if (width == 4 && i % 10 == 0) {
        const size_t num = m.tri_verts.size() / 3;
        const TriRay4 r4(o, d);
        for (size_t k = 0; k < num; k += 4) {
          Tri4 blk;
          for (int l = 0; l < 4; ++l) {
            const size_t j = std::min(k + l, num - 1);
            for (int c = 0; c < 3; ++c)
              for (int a = 0; a < 3; ++a) blk.v[c][a][l] = m.tri_verts[3 * j + c][a];
            blk.prim[l] = uint32_t(j);
          }
          __m128 t4, u4, v4;
          const int mask = intersect_tri4(blk, r4, _mm_set1_ps(kInf), t4, u4, v4);
          alignas(16) float ts[4], us[4], vs[4];
          _mm_store_ps(ts, t4), _mm_store_ps(us, u4), _mm_store_ps(vs, v4);
          for (int l = 0; l < 4; ++l) {
            const size_t j = std::min(k + l, num - 1);
            TriangleHit th;
            const bool hit = intersect_triangle(m.tri_verts[3 * j], m.tri_verts[3 * j + 1], m.tri_verts[3 * j + 2], o, sh, kInf, th);
            ASSERT_EQ(bool(mask >> l & 1), hit) << i << " " << j;
            if (hit) {
              ASSERT_EQ(ts[l], th.t) << i << " " << j;
              ASSERT_EQ(us[l], th.u) << i << " " << j;
              ASSERT_EQ(vs[l], th.v) << i << " " << j;
              ++lane_hits;
            }
          }
        }
      }
    }
    EXPECT_GT(hits, 5000) << "width " << width;
    EXPECT_LT(near_miss, hits / 100) << "width " << width;
  }
  EXPECT_GT(lane_hits, 1000);
  g_bvh8_avx512 = saved_kernel;
}

// RayShear picks its axes without branches (a table over max_dimension's
// comparisons and a masked swap): the same axes and values as the
// max_dimension and swap form, on every sign and ordering of the components
// (ties, zeros and negative zeros included).
TEST(Intersection, BranchFreeShearMatchesMaxDimension) {
  const float vals[] = {0.0f, -0.0f, 0.25f, -0.25f, 0.5f, -0.5f, 1.0f, -1.0f};
  for (float x : vals)
    for (float y : vals)
      for (float z : vals) {
        const vec3 d(x, y, z);
        if (d == vec3(0.0f)) continue;
        int kz = max_dimension(glm::abs(d));
        int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
        if (d[kz] < 0.0f) std::swap(kx, ky);
        const RayShear s(d);
        ASSERT_EQ(s.kz, kz) << x << " " << y << " " << z;
        ASSERT_EQ(s.kx, kx) << x << " " << y << " " << z;
        ASSERT_EQ(s.ky, ky) << x << " " << y << " " << z;
        ASSERT_EQ(s.sx, d[kx] / d[kz]);
        ASSERT_EQ(s.sy, d[ky] / d[kz]);
        ASSERT_EQ(s.sz, 1.0f / d[kz]);
      }
}

// Closest hit must not depend on the order triangles are tested in. Two
// coplanar triangles of modern_hall (overlapping: the same wall twice) and a
// ray that hits both at distances one ulp apart: the range test on
// t_scaled against tmax * det used to reject the nearer one (its rounded t
// below tmax) once the farther one had set tmax, so BVH4 and BVH8 (different
// visiting orders) returned different hits.
TEST(Triangle, ClosestHitIndependentOfTestOrder) {
  const vec3 A[3] = {vec3(-10.2392635f, 0.59454298f, 2.59882995e-08f), vec3(-14.1093121f, 0.59454298f, 2.59882995e-08f),
                     vec3(-14.1093121f, -0.0890169963f, -3.89105637e-09f)};
  const vec3 B[3] = {vec3(-13.7577667f, -0.0860169977f, -3.7599226e-09f), vec3(-14.1093121f, -0.0860169977f, -3.7599226e-09f),
                     vec3(-14.1093121f, 0.59454298f, 2.59882995e-08f)};
  const vec3 o(-12.3104649f, 1.637887f, -1.37166548f), d(-0.678468108f, -0.509929895f, 0.528821826f);
  const RayShear sh(d);
  TriangleHit ha, hb;
  ASSERT_TRUE(intersect_triangle(A[0], A[1], A[2], o, sh, kInf, ha));
  ASSERT_TRUE(intersect_triangle(B[0], B[1], B[2], o, sh, kInf, hb));
  ASSERT_NE(ha.t, hb.t);
  const float t_min = std::min(ha.t, hb.t);
  // Tested with tmax = the other's distance, the nearer one still hits.
  TriangleHit h;
  if (ha.t < hb.t) EXPECT_TRUE(intersect_triangle(A[0], A[1], A[2], o, sh, hb.t, h));
  else EXPECT_TRUE(intersect_triangle(B[0], B[1], B[2], o, sh, ha.t, h));
  // Each triangle its own leaf, both input orders, every traversal kernel.
  std::vector<std::pair<int, bool>> widths{{4, false}};
  if (cpu_simd_level() == SimdLevel::AVX2) widths.push_back({8, false});
  if (cpu_has_avx512()) widths.push_back({8, true});
  const bool saved_kernel = g_bvh8_avx512;
  for (int order = 0; order < 2; ++order) {
    std::vector<float> pos;
    for (const vec3* t : {order ? B : A, order ? A : B})
      for (int k = 0; k < 3; ++k) pos.insert(pos.end(), {t[k].x, t[k].y, t[k].z});
    std::vector<uint32_t> idx = {0, 1, 2, 3, 4, 5};
    MeshInput in;
    in.positions = pos.data();
    in.num_vertices = 6;
    in.indices = idx.data();
    in.num_triangles = 2;
    for (auto [width, avx512] : widths) {
      g_bvh8_avx512 = avx512;
      BuildOptions opt;
      opt.bvh_width = width;
      opt.max_leaf_size = 1;
      opt.collapse_small_subtrees = false;
      Mesh mesh = build_mesh(in, opt);
      for (TraversalOrder to : {TraversalOrder::Ordered, TraversalOrder::Unordered}) {
        float tmax = kInf;
        MeshHit mh;
        ASSERT_TRUE(intersect_mesh(mesh, o, d, tmax, mh, to));
        EXPECT_EQ(mh.t, t_min) << "order " << order << " width " << width << (avx512 ? " avx512" : "")
                               << (to == TraversalOrder::Ordered ? " ordered" : " unordered");
      }
    }
  }
  g_bvh8_avx512 = saved_kernel;
}
