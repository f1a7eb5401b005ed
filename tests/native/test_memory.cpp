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
