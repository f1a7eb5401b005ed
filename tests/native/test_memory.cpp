// Where the BVH's large arrays live (bvh.h, LargePageAllocator): 2 MB aligned
// and mapped from the kernel, so that MADV_HUGEPAGE applies before first
// touch whatever the process's heap held before (a previous scene's
// arrays, Blender's own); freed ones are kept mapped for the next build
// (bvh_memory.cpp).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <sys/resource.h>

#include <glm/gtc/matrix_transform.hpp>

#include "core/bvh.h"
#include "core/mesh.h"
#include "core/scene.h"
#include "scene_fixtures.h"

using namespace tessera;

namespace {
// The /proc/self/maps line of the mapping that holds p ("" if none).
std::string mapping_of(const void* p) {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  const uintptr_t a = reinterpret_cast<uintptr_t>(p);
  while (std::getline(maps, line)) {
    uintptr_t lo = 0, hi = 0;
    if (std::sscanf(line.c_str(), "%lx-%lx", &lo, &hi) == 2 && lo <= a && a < hi) return line;
  }
  return "";
}

// An n x n grid of quads (2 n^2 triangles) with bumpy heights, as a mesh input.
struct Grid {
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  explicit Grid(int n) {
    for (int y = 0; y <= n; ++y)
      for (int x = 0; x <= n; ++x) pos.insert(pos.end(), {float(x), float(y), 0.5f * float((x * 7 + y * 3) % 5)});
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const uint32_t a = uint32_t(y * (n + 1) + x), b = a + 1, c = a + uint32_t(n) + 1, d = c + 1;
        idx.insert(idx.end(), {a, b, d, a, d, c});
      }
  }
  MeshInput input() const { return fixtures::mesh_input(pos, idx); }
};
}  // namespace

TEST(Memory, LargeBVHArraysAreMappedFromTheKernelWhateverTheHeapHeld) {
#if !defined(__linux__)
  GTEST_SKIP() << "mappings are read from Linux's /proc/self/maps";
#else
  // Freeing a large mapped block raises glibc's mmap threshold to its size
  // (up to 32 MB): from then on it serves blocks that size from its heap,
  // whose pages were touched before and stay small pages (the 1.3x slower
  // builds of bench_bvh --mode compare, ogre after nefertiti).
  constexpr size_t kFreed = size_t(24) << 20;
  char* volatile freed = static_cast<char*>(std::malloc(kFreed));
  ASSERT_NE(nullptr, freed);
  std::memset(freed, 1, kFreed);
  std::free(freed);

  BVHArray<uint8_t> nodes;
  nodes.resize(size_t(8) << 20);
  std::memset(nodes.data(), 0, nodes.size());
  const std::string where = mapping_of(nodes.data());
  std::printf("8 MB BVH array at %p: %s\n", static_cast<void*>(nodes.data()), where.c_str());
  EXPECT_EQ(0u, reinterpret_cast<uintptr_t>(nodes.data()) & ((size_t(2) << 20) - 1)) << "not 2 MB aligned";
  EXPECT_FALSE(where.empty());
  EXPECT_EQ(std::string::npos, where.find("[heap]")) << "served from the heap: " << where;

  BVHArray<uint8_t> small;  // below one large page: the ordinary allocator
  small.resize(4096);
  EXPECT_EQ(0u, reinterpret_cast<uintptr_t>(small.data()) & 63u);
#endif
}

// A mesh holds its arrays at their size: Scene::memory_bytes counts
// capacities, and a vector grown by push_back holds up to twice what it
// uses (prim_ids did: ~4 bytes per triangle on the bunny, 3.5% of its
// memory). Checked after prepare_mesh, after its tree is built, and for
// build_mesh, on a mesh whose triangle count is not a power of two and
// which has triangles left out (two equal corners, out-of-range indices).
TEST(Memory, MeshArraysHoldNoSpareCapacity) {
  constexpr int kGrid = 37;  // 2 * 37 * 37 = 2738 triangles
  Grid grid(kGrid);
  grid.idx.insert(grid.idx.end(), {0, 0, 1, 0, 1, 99999});  // two equal corners; an index out of range
  const MeshInput in = grid.input();
  auto expect_fitted = [](const Mesh& m, const char* when) {
    EXPECT_EQ(m.prim_ids.size(), m.prim_ids.capacity()) << when;
    EXPECT_EQ(m.tri_verts.size(), m.tri_verts.capacity()) << when;
    EXPECT_EQ(m.material_slots.size(), m.material_slots.capacity()) << when;
    EXPECT_EQ(m.corner_normals.size(), m.corner_normals.capacity()) << when;
    EXPECT_EQ(m.corner_uvs.size(), m.corner_uvs.capacity()) << when;
  };
  Mesh prepared = prepare_mesh(in);
  EXPECT_EQ(size_t(2 * kGrid * kGrid), prepared.prim_ids.size());
  expect_fitted(prepared, "prepare_mesh");
  build_mesh_bvh(prepared);
  expect_fitted(prepared, "build_mesh_bvh");
  expect_fitted(build_mesh(in), "build_mesh");
}

namespace {
#if defined(__linux__)
// Minor page faults of the calling thread so far (first touches of fresh pages).
long thread_faults() {
  rusage u;
  getrusage(RUSAGE_THREAD, &u);
  return u.ru_minflt;
}
#endif
}  // namespace

// A freed large array stays mapped, and the next array of its size (after
// rounding up to large pages) gets the same pages: writing all of it takes
// no page fault. A larger retained region serves a smaller request (the
// smallest that fits), the rest of it unmapped.
TEST(Memory, FreedLargeArraysAreReusedWithoutFaults) {
#if !defined(__linux__)
  GTEST_SKIP() << "retention and fault counts are Linux's";
#else
  bvh_release_retained();
  ASSERT_EQ(0u, bvh_retained_bytes());
  constexpr size_t kMB = size_t(1) << 20;
  const uint8_t* first = nullptr;
  {
    BVHArray<uint8_t> a;
    a.resize(6 * kMB);
    std::memset(a.data(), 1, a.size());
    first = a.data();
  }
  EXPECT_EQ(6 * kMB, bvh_retained_bytes());
  {
    BVHArray<uint8_t> b;
    b.resize(5 * kMB + 12345);  // rounds up to the same 6 MB
    EXPECT_EQ(first, b.data());
    EXPECT_EQ(0u, bvh_retained_bytes());
    const long f0 = thread_faults();
    std::memset(b.data(), 2, b.size());
    EXPECT_EQ(0, thread_faults() - f0) << "the retained pages were not reused";
  }
  {
    BVHArray<uint8_t> large;
    large.resize(10 * kMB);
    std::memset(large.data(), 3, large.size());
    const uint8_t* large_p = large.data();
    BVHArray<uint8_t>().swap(large);  // retained: 6 MB and 10 MB
    EXPECT_EQ(16 * kMB, bvh_retained_bytes());
    BVHArray<uint8_t> c;
    c.resize(8 * kMB);  // only the 10 MB region holds it: its last 2 MB are unmapped
    EXPECT_EQ(large_p, c.data());
    EXPECT_EQ(6 * kMB, bvh_retained_bytes());
    const long f0 = thread_faults();
    std::memset(c.data(), 4, c.size());
    EXPECT_EQ(0, thread_faults() - f0);
  }
  EXPECT_EQ(14 * kMB, bvh_retained_bytes());
  bvh_release_retained();
  EXPECT_EQ(0u, bvh_retained_bytes());
#endif
}

// Retention is bounded: freeing more than kBVHRetainBytes of arrays keeps at
// most that much (the oldest are unmapped), and an array larger than the
// bound is unmapped at once. The arrays are never touched here (mapping
// costs no memory until then).
TEST(Memory, RetainedMemoryIsBounded) {
#if !defined(__linux__)
  GTEST_SKIP() << "retention is Linux's";
#else
  bvh_release_retained();
  constexpr size_t kArray = size_t(24) << 20;
  {
    std::vector<BVHArray<uint8_t>> arrays(2 * kBVHRetainBytes / kArray);
    for (auto& a : arrays) a.resize(kArray);
  }
  EXPECT_LE(bvh_retained_bytes(), kBVHRetainBytes);
  EXPECT_GE(bvh_retained_bytes(), kBVHRetainBytes - kArray);
  bvh_release_retained();
  {
    BVHArray<uint8_t> huge;
    huge.resize(kBVHRetainBytes + kArray);
  }
  EXPECT_EQ(0u, bvh_retained_bytes());
#endif
}

// The build keeps freed arrays mapped for the builds that follow
// (bvh_memory.cpp), but a render needs none of them: after a scene's
// commit(), and after a scene is freed (its trees go back to that memory
// first), nothing stays retained in the host process (Blender).
TEST(Memory, ACommittedOrFreedSceneRetainsNoBuildMemory) {
  bvh_release_retained();
  const Grid grid(160);  // 51,200 triangles: boxes, references and trees of 256 KB and more
  const MeshInput in = grid.input();
  {
    Mesh scratch = build_mesh(in);  // a build outside any scene keeps its scratch for the next
  }
  EXPECT_GT(bvh_retained_bytes(), 0u) << "the build allocator retained nothing: this test checks nothing";
  {
    Scene scene;
    for (int k = 0; k < 3; ++k) {
      scene.meshes.push_back(prepare_mesh(in));
      scene.add_instance(uint32_t(k), glm::translate(mat4(1.0f), vec3(0.0f, 0.0f, 10.0f * k)), {0});
      scene.add_instance(uint32_t(k), glm::translate(mat4(1.0f), vec3(200.0f, 0.0f, 10.0f * k)), {0});
    }
    scene.commit();
    EXPECT_EQ(0u, bvh_retained_bytes()) << "after commit()";
  }
  EXPECT_EQ(0u, bvh_retained_bytes()) << "after the scene was freed";
}
