// Memory of the BVH builds' large arrays (LargePageAllocator, bvh.h):
// mappings from the kernel (from 2 MB on 2 MB aligned and marked
// MADV_HUGEPAGE before first touch), and freed ones kept mapped for the next
// build.
#include "bvh.h"

#include <sys/mman.h>

#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <new>

namespace tessera {

namespace {

constexpr size_t kLargePage = size_t(2) << 20;

constexpr size_t kSmallPage = 4096;
// Arrays from this size on are mapped (and retained, below); smaller ones
// come from the heap. Between it and one large page they are mapped in
// small pages: glibc returns blocks of that size to the kernel when they
// are freed (or trims its heap), so each build faulted them in again (the
// collapse's per-node plan, 349 faults in every build of ogre).
constexpr size_t kMappedMin = size_t(256) << 10;

// The bytes mapped for an array: whole large pages from one large page on,
// whole small pages below.
size_t mapped_size(size_t bytes) {
  return bytes >= kLargePage ? (bytes + kLargePage - 1) & ~(kLargePage - 1) : (bytes + kSmallPage - 1) & ~(kSmallPage - 1);
}

// Arrays of at least one large page start on a 2 MB boundary and have their
// whole large pages marked MADV_HUGEPAGE before first touch; the tail stays
// in small pages, so no memory is wasted. They are mapped from the kernel,
// not taken from the heap: once glibc has freed blocks of that size (a
// previous scene's arrays, Blender's own) its mmap threshold grows and it
// serves them from heap memory that was touched before, which keeps its
// small pages whatever madvise says. A build over such memory ran 1.3x as
// long (ogre after nefertiti in bench_bvh --mode compare) and its tree is
// walked with the TLB missing more.
void* map_fresh(size_t size) {
#if defined(__linux__)
  if (size < kLargePage) {
    void* p = mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    return p;
  }
  // Over-map by one large page, then unmap what lies outside the aligned range.
  void* raw = mmap(nullptr, size + kLargePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) throw std::bad_alloc();
  const uintptr_t begin = uintptr_t(raw), aligned = (begin + kLargePage - 1) & ~uintptr_t(kLargePage - 1);
  if (aligned > begin) munmap(raw, aligned - begin);
  if (begin + kLargePage > aligned) munmap(reinterpret_cast<void*>(aligned + size), begin + kLargePage - aligned);
  return reinterpret_cast<void*>(aligned);
#else
  void* p = std::aligned_alloc(size < kLargePage ? kSmallPage : kLargePage, size);
  if (!p) throw std::bad_alloc();
  return p;
#endif
}

void unmap(void* p, size_t size) {
#if defined(__linux__)
  munmap(p, size);
#else
  std::free(p);
#endif
}

// Freed regions kept mapped. The first touch of a fresh page is the kernel's
// work (a fault, the page zeroed): on the benchmark machine (a two-vCPU VM)
// 0.7 ms per 9 MB in large pages and 2.4 ms in small ones, no faster when
// two threads touch different pages, and slower still when they fault on
// the same ones (the parallel collapse writing its arena: 5.4-6.2 ms at two
// threads in some processes, 2.3 ms at one). A mesh build maps about 250
// bytes per triangle (boxes, references, binary nodes, the collapse's plan,
// vertices, the wide tree), a serial cost that left two-thread builds at
// 0.81-0.86 of Embree's speed on nefertiti and ogre: Embree's builds take
// their memory from the heap, which hands a previous build's pages back
// (bench_bvh --mode build counts no faults for them). Keeping freed regions
// gives Tessera's arrays the same reuse without giving up their large pages: a
// request takes the smallest retained region that holds it (the same
// mesh rebuilt asks for the same sizes), unmapping what lies beyond its
// size; among regions of that size, the one whose last array was the
// smallest at least as long as the request (its pages were touched; the
// small pages past the last large page of a shorter one were not);
// regions beyond kBVHRetainBytes in all are unmapped, oldest first.
// Splitting a region at a large-page boundary keeps its large pages.
constexpr int kRetainRegions = 32;

struct Retained {
  std::mutex mutex;
  struct Region {
    void* p;
    size_t size;  // mapped bytes (mapped_size)
    size_t used;  // bytes of the array it last held
  };
  Region regions[kRetainRegions];  // oldest first
  int count = 0;
  size_t total = 0;  // bytes mapped in the regions

  // Whether region a serves a request for an array of `want` bytes better than b.
  static bool better(const Region& a, const Region& b, size_t want) {
    if (a.size != b.size) return a.size < b.size;
    const bool a_covers = a.used >= want, b_covers = b.used >= want;
    if (a_covers != b_covers) return a_covers;
    return a_covers ? a.used < b.used : a.used > b.used;
  }

  void* take(size_t size, size_t want) {
#if defined(__linux__)
    std::lock_guard<std::mutex> lock(mutex);
    int best = -1;
    for (int k = 0; k < count; ++k)
      if (regions[k].size >= size && (best < 0 || better(regions[k], regions[best], want))) best = k;
    if (best < 0) return nullptr;
    const Region r = regions[best];
    for (int k = best; k + 1 < count; ++k) regions[k] = regions[k + 1];
    --count;
    total -= r.size;
    if (r.size > size) munmap(static_cast<char*>(r.p) + size, r.size - size);
    return r.p;
#else
    (void)size, (void)want;
    return nullptr;  // aligned_alloc'd blocks cannot be split
#endif
  }

  // Keeps [p, p + size) mapped, unmapping the oldest regions (outside the
  // lock) while there are more than the limits allow.
  void give(void* p, size_t size, size_t used) {
#if defined(__linux__)
    Region evict[kRetainRegions + 1];
    int num_evict = 0;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (size > kBVHRetainBytes) {
        evict[num_evict++] = {p, size, used};
      } else {
        if (count == kRetainRegions) evict[num_evict++] = pop_oldest();
        regions[count++] = {p, size, used};
        total += size;
        while (total > kBVHRetainBytes) evict[num_evict++] = pop_oldest();
      }
    }
    for (int k = 0; k < num_evict; ++k) munmap(evict[k].p, evict[k].size);  // outside the lock
#else
    (void)used;
    unmap(p, size);
#endif
  }

  Region pop_oldest() {
    const Region r = regions[0];
    for (int k = 0; k + 1 < count; ++k) regions[k] = regions[k + 1];
    --count;
    total -= r.size;
    return r;
  }

  void release() {
    std::lock_guard<std::mutex> lock(mutex);
    while (count > 0) {
      const Region r = pop_oldest();
      unmap(r.p, r.size);
    }
  }
};

Retained& retained() {
  static Retained* r = new Retained;  // never destroyed: arrays may be freed during static destruction
  return *r;
}

}  // namespace

void* bvh_alloc_bytes(size_t bytes) {
  if (bytes < kMappedMin) return ::operator new(bytes, std::align_val_t(64));
  const size_t size = mapped_size(bytes);
  void* p = retained().take(size, bytes);
  if (!p) p = map_fresh(size);
#ifdef MADV_HUGEPAGE
  // Again on a retained region: it may have held a smaller array before.
  if (bytes >= kLargePage) madvise(p, bytes & ~(kLargePage - 1), MADV_HUGEPAGE);
#endif
  return p;
}

void bvh_free_bytes(void* p, size_t bytes) {
  if (bytes < kMappedMin) ::operator delete(p, std::align_val_t(64));
  else retained().give(p, mapped_size(bytes), bytes);
}

size_t bvh_retained_bytes() {
  Retained& r = retained();
  std::lock_guard<std::mutex> lock(r.mutex);
  return r.total;
}

void bvh_release_retained() { retained().release(); }

}  // namespace tessera
