// Where the BVH's large arrays live (bvh.h, LargePageAllocator): 2 MB aligned
// and mapped from the kernel, so that MADV_HUGEPAGE applies before first
// touch whatever the process's heap held before (a previous scene's
// arrays, Blender's own).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#include "core/bvh.h"
#include "core/mesh.h"

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
  std::vector<float> pos;
  for (int y = 0; y <= kGrid; ++y)
    for (int x = 0; x <= kGrid; ++x) pos.insert(pos.end(), {float(x), float(y), 0.1f * float((x * y) % 3)});
  std::vector<uint32_t> idx;
  for (int y = 0; y < kGrid; ++y)
    for (int x = 0; x < kGrid; ++x) {
      const uint32_t a = uint32_t(y * (kGrid + 1) + x), b = a + 1, c = a + kGrid + 1, d = c + 1;
      idx.insert(idx.end(), {a, b, d, a, d, c});
    }
  idx.insert(idx.end(), {0, 0, 1, 0, 1, 99999});  // two equal corners; an index out of range
  MeshInput in;
  in.positions = pos.data();
  in.num_vertices = pos.size() / 3;
  in.indices = idx.data();
  in.num_triangles = idx.size() / 3;
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
