#include "bvh.h"

#include <tbb/parallel_invoke.h>
#include <tbb/parallel_sort.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/combinable.h>
#include <emmintrin.h>

#include <cstdlib>
#include <cstring>

#include <algorithm>
#include <functional>
#include <atomic>
#include <memory>
#include <numeric>
#include <stdexcept>

namespace tessera {

namespace {

struct Split {
  int axis = -1;
  float pos = 0.0f;     // centroid coordinate (binned / midpoint) ...
  uint32_t index = 0;   // ... or the sorted rank (sweep)
  float cost = kInf;
};

struct Builder {
  const std::vector<AABB>& bounds;
  const BuildOptions& opt;
  std::vector<vec3> centroids;
  std::vector<uint32_t> prims;
  BVHArray<BVHNode> nodes;
  std::atomic<uint32_t> node_count{1};

  uint32_t block = 1;

  Builder(const std::vector<AABB>& b, const BuildOptions& o)
      : bounds(b), opt(o), block(uint32_t(std::max(1, o.sah_block_size))) {}

  float blocks(uint32_t n) const { return float((n + block - 1) / block); }

  AABB range_bounds(uint32_t begin, uint32_t end, AABB* centroid_bounds) const {
    AABB box, cbox;
    for (uint32_t i = begin; i < end; ++i) {
      box.grow(bounds[prims[i]]);
      cbox.grow(centroids[prims[i]]);
    }
    *centroid_bounds = cbox;
    return box;
  }

  // Binned SAH (Wald 2007): bins along each axis of the centroid bounds.
  Split find_binned(uint32_t begin, uint32_t end, const AABB& cbox) const {
    constexpr int kMaxBins = 256;
    const int nb = std::clamp(opt.bins, 2, kMaxBins);
    Split best;
    for (int axis = 0; axis < 3; ++axis) {
      float lo = cbox.lo[axis], hi = cbox.hi[axis];
      if (!(hi > lo)) continue;
      AABB bin_box[kMaxBins];
      uint32_t bin_count[kMaxBins] = {};
      const float scale = nb / (hi - lo);
      for (uint32_t i = begin; i < end; ++i) {
        int b = std::min(nb - 1, int((centroids[prims[i]][axis] - lo) * scale));
        bin_box[b].grow(bounds[prims[i]]);
        bin_count[b]++;
      }
      float right_area[kMaxBins];
      uint32_t right_count[kMaxBins];
      AABB acc;
      uint32_t cnt = 0;
      for (int b = nb - 1; b > 0; --b) {
        acc.grow(bin_box[b]);
        cnt += bin_count[b];
        right_area[b] = acc.half_area();
        right_count[b] = cnt;
      }
      acc = AABB{};
      cnt = 0;
      for (int b = 0; b < nb - 1; ++b) {
        acc.grow(bin_box[b]);
        cnt += bin_count[b];
        if (cnt == 0 || right_count[b + 1] == 0) continue;
        float cost = acc.half_area() * blocks(cnt) + right_area[b + 1] * blocks(right_count[b + 1]);
        if (cost < best.cost) best = {axis, lo + (b + 1) / scale, 0, cost};
      }
    }
    return best;
  }

  // Full-sweep SAH: sort along each axis and evaluate every split position.
  Split find_sweep(uint32_t begin, uint32_t end) {
    Split best;
    const uint32_t n = end - begin;
    std::vector<uint32_t> order(prims.begin() + begin, prims.begin() + end);
    std::vector<float> right_area(n);
    for (int axis = 0; axis < 3; ++axis) {
      std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
        return centroids[a][axis] < centroids[b][axis] || (centroids[a][axis] == centroids[b][axis] && a < b);
      });
      AABB acc;
      for (uint32_t i = n - 1; i > 0; --i) {
        acc.grow(bounds[order[i]]);
        right_area[i] = acc.half_area();
      }
      acc = AABB{};
      for (uint32_t i = 0; i + 1 < n; ++i) {
        acc.grow(bounds[order[i]]);
        float cost = acc.half_area() * blocks(i + 1) + right_area[i + 1] * blocks(n - i - 1);
        if (cost < best.cost) best = {axis, 0.0f, i + 1, cost};
      }
    }
    if (best.axis >= 0) {
      std::sort(prims.begin() + begin, prims.begin() + end, [&](uint32_t a, uint32_t b) {
        int ax = best.axis;
        return centroids[a][ax] < centroids[b][ax] || (centroids[a][ax] == centroids[b][ax] && a < b);
      });
    }
    return best;
  }

  void make_leaf(BVHNode& node, uint32_t begin, uint32_t end) {
    node.first = begin;
    node.count = end - begin;
  }

  // Below this depth the tree is split by count, so that pathological input
  // (e.g. thousands of nested boxes) cannot grow it past the traversal stack.
  static constexpr int kMaxSAHDepth = 32;

  void build(uint32_t node_index, uint32_t begin, uint32_t end, int depth = 0) {
    AABB cbox;
    AABB box = range_bounds(begin, end, &cbox);
    BVHNode& node = nodes[node_index];
    node.lo = box.lo;
    node.hi = box.hi;
    const uint32_t n = end - begin;
    if (n <= 1) return make_leaf(node, begin, end);

    uint32_t mid = begin;
    if (depth >= kMaxSAHDepth) {
      if (n <= uint32_t(opt.max_leaf_size)) return make_leaf(node, begin, end);
    } else if (opt.method == SplitMethod::Midpoint) {
      if (n <= uint32_t(std::max(1, opt.max_leaf_size / 2))) return make_leaf(node, begin, end);
      int axis = max_dimension(cbox.extent());
      float pos = cbox.center()[axis];
      mid = uint32_t(std::partition(prims.begin() + begin, prims.begin() + end,
                                    [&](uint32_t p) { return centroids[p][axis] < pos; }) -
                     prims.begin());
    } else {
      Split split = opt.method == SplitMethod::SweepSAH ? find_sweep(begin, end) : find_binned(begin, end, cbox);
      const float leaf_cost = opt.intersection_cost * blocks(n);
      const float split_cost =
          split.axis < 0 ? kInf : opt.traversal_cost + opt.intersection_cost * split.cost / box.half_area();
      if (n <= uint32_t(opt.max_leaf_size) && (leaf_cost <= split_cost || split.axis < 0))
        return make_leaf(node, begin, end);
      if (split.axis >= 0) {
        if (opt.method == SplitMethod::SweepSAH) {
          mid = begin + split.index;
        } else {
          mid = uint32_t(std::partition(prims.begin() + begin, prims.begin() + end,
                                        [&](uint32_t p) { return centroids[p][split.axis] < split.pos; }) -
                         prims.begin());
        }
      }
    }
    // Inseparable centroids (all equal) or a failed partition: split by count.
    if (mid == begin || mid == end) mid = begin + n / 2;

    const uint32_t left = node_count.fetch_add(2);
    node.first = left;
    node.count = 0;
    if (opt.parallel && n > 4096) {
      tbb::parallel_invoke([&] { build(left, begin, mid, depth + 1); }, [&] { build(left + 1, mid, end, depth + 1); });
    } else {
      build(left, begin, mid, depth + 1);
      build(left + 1, mid, end, depth + 1);
    }
  }
};


// Binned SAH builder on a contiguous array of primitive references (Wald
// 2007): one pass bins all three axes at once with SSE boxes, node bounds come
// from the parent's split, and the partition computes the children's bounds
// and centroid bounds on the way. Large ranges bin in parallel (TBB) and
// subtrees build as parallel tasks.
struct alignas(32) PrimRef {
  __m128 lo;  // w: primitive index (bits; small indices are denormals, so the
  __m128 hi;  // w lane is masked off before any arithmetic); hi.w = 0
};

inline __m128 xyz(__m128 v) { return _mm_and_ps(v, _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0))); }
inline __m128 lo_of(const PrimRef& r) { return xyz(r.lo); }
inline __m128 centroid2(const PrimRef& r) { return _mm_add_ps(xyz(r.lo), r.hi); }  // 2 x centroid

struct SSEBox {
  __m128 lo = _mm_set1_ps(kInf), hi = _mm_set1_ps(-kInf);
  void grow(__m128 l, __m128 h) { lo = _mm_min_ps(lo, l); hi = _mm_max_ps(hi, h); }
  void grow(const SSEBox& b) { grow(b.lo, b.hi); }
  float half_area() const {
    alignas(16) float e[4];
    _mm_store_ps(e, _mm_sub_ps(hi, lo));
    if (!(e[0] >= 0.0f)) return 0.0f;
    return e[0] * e[1] + e[1] * e[2] + e[2] * e[0];
  }
  AABB aabb() const {
    alignas(16) float l[4], h[4];
    _mm_store_ps(l, lo);
    _mm_store_ps(h, hi);
    return AABB{vec3(l[0], l[1], l[2]), vec3(h[0], h[1], h[2])};
  }
};

constexpr int kMaxFastBins = 256;

// Bins stored axis-major, one cache line per bin and axis holding its box
// and count: a reference's three updates touch three lines, each addressed
// by one shift of the bin index (bin-major boxes with a separate count array
// took nine address operations and up to nine lines per reference).
struct Bins {
  struct alignas(64) Bin {
    __m128 lo, hi;
    uint32_t count;
  };
  int n = 0;
  Bin bin[3][kMaxFastBins];  // only the first n per axis are initialised
  explicit Bins(int nb) : n(nb) {
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < n; ++b) bin[a][b].lo = _mm_set1_ps(kInf), bin[a][b].hi = _mm_set1_ps(-kInf), bin[a][b].count = 0;
  }
  void grow(int a, uint32_t b, __m128 l, __m128 h) {
    Bin& x = bin[a][b];
    x.lo = _mm_min_ps(x.lo, l);
    x.hi = _mm_max_ps(x.hi, h);
    x.count++;
  }
  __m128i counts(int b) const { return _mm_setr_epi32(int(bin[0][b].count), int(bin[1][b].count), int(bin[2][b].count), 0); }
  void merge(const Bins& o) {
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < n; ++b) {
        Bin& x = bin[a][b];
        x.lo = _mm_min_ps(x.lo, o.bin[a][b].lo), x.hi = _mm_max_ps(x.hi, o.bin[a][b].hi), x.count += o.bin[a][b].count;
      }
  }
};

// Half areas of three boxes (one per axis sweep) as one vector: the boxes'
// extents transposed, then e.x*e.y + e.y*e.z + e.z*e.x per lane (the order
// of AABB::half_area, so the costs are those of the scalar sweep).
inline __m128 half_areas3(const SSEBox* b) {
  __m128 e0 = _mm_sub_ps(b[0].hi, b[0].lo), e1 = _mm_sub_ps(b[1].hi, b[1].lo), e2 = _mm_sub_ps(b[2].hi, b[2].lo);
  __m128 e3 = _mm_setzero_ps();
  _MM_TRANSPOSE4_PS(e0, e1, e2, e3);  // e0 = x extents of the three boxes, e1 = y, e2 = z
  return _mm_add_ps(_mm_add_ps(_mm_mul_ps(e0, e1), _mm_mul_ps(e1, e2)), _mm_mul_ps(e2, e0));
}

struct FastBuilder {
  const BuildOptions& opt;
  BVHArray<PrimRef> refs;  // unwritten by resize: every one is written before it is read
  uint32_t num_refs = 0;
  // The other buffer of the parallel partitions, allocated once per build
  // (uninitialised): a parallel partition scatters a range from one buffer
  // into the other (no copy back), so a subtree's range lives in buf[side];
  // concurrent partitions work on disjoint [begin, end).
  BVHArray<PrimRef> scratch;
  PrimRef* buf[2] = {nullptr, nullptr};
  uint32_t* prim_order = nullptr;  // written by the leaves, from their references
  BVHArray<BVHNode> nodes;
  uint32_t block;
  int nb;

  FastBuilder(const BuildOptions& o)
      : opt(o), block(uint32_t(std::max(1, o.sah_block_size))), nb(std::clamp(o.bins, 2, kMaxFastBins)) {}

  float blocks(uint32_t n) const { return float((n + block - 1) / block); }
  // blocks() of four counts: exact for power-of-two blocks (1/block is exact) below 2^24 references.
  __m128 blocks4(__m128i n) const {
    const __m128 x = _mm_cvtepi32_ps(_mm_add_epi32(n, _mm_set1_epi32(int(block - 1))));
    return _mm_cvtepi32_ps(_mm_cvttps_epi32(_mm_mul_ps(x, _mm_set1_ps(1.0f / float(block)))));
  }

  // Bin indices of a reference on the three axes (centroids are handled
  // doubled, lo + hi, throughout), clamped to [0, maxb].
  // The clamp is on the float (two operations instead of SSE2's six for
  // integers); the bin counts and boxes are the same.
  static __m128i bin_of(const PrimRef& r, __m128 cmin, __m128 scale, __m128 maxb) {
    const __m128 x = _mm_mul_ps(_mm_sub_ps(centroid2(r), cmin), scale);
    return _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(x, _mm_setzero_ps()), maxb));
  }

  static void bin_one(Bins& bins, const PrimRef& r, __m128 cmin, __m128 scale, __m128 maxb) {
    const __m128i b = bin_of(r, cmin, scale, maxb);
    const __m128 l = lo_of(r);
    bins.grow(0, uint32_t(_mm_cvtsi128_si32(b)), l, r.hi);
    bins.grow(1, uint32_t(_mm_cvtsi128_si32(_mm_shuffle_epi32(b, 1))), l, r.hi);
    bins.grow(2, uint32_t(_mm_cvtsi128_si32(_mm_shuffle_epi32(b, 2))), l, r.hi);
  }
  // Neighbouring references mostly fall into the same bin, so every update
  // waits for the previous one's store; large ranges alternate between two
  // bin sets to halve that chain, then merge them.
  void bin_range(Bins& bins, const PrimRef* refs, uint32_t begin, uint32_t end, __m128 cmin, __m128 scale) const {
    const __m128 maxb = _mm_set1_ps(float(bins.n - 1));
    uint32_t i = begin;
    if (end - begin >= 256) {
      Bins odd(bins.n);
      for (; i + 1 < end; i += 2) {
        bin_one(bins, refs[i], cmin, scale, maxb);
        bin_one(odd, refs[i + 1], cmin, scale, maxb);
      }
      bins.merge(odd);
    }
    for (; i < end; ++i) bin_one(bins, refs[i], cmin, scale, maxb);
  }

  // Large ranges (those partitioned in parallel) bin in blocks of
  // kPartitionBlock references, and each block's bin counts go to
  // block_counts (per block, axis-major, nb per axis): the parallel partition
  // takes its blocks' left counts from them instead of a counting pass.
  Split find_split(const PrimRef* refs, uint32_t begin, uint32_t end, const SSEBox& cbox, __m128& cmin_out,
                   __m128& scale_out, std::vector<uint32_t>& block_counts, int& nb_out) const {
    Split best;
    const __m128 cmin = cbox.lo;  // centroid boxes are doubled (centroid2) throughout
    const __m128 ext = _mm_sub_ps(cbox.hi, cmin);
    const uint32_t n = end - begin;
    // Bins grow with the range (Embree's BinMapping: 4 + n / 20, at most the
    // option's count): the many small ranges near the leaves bin and sweep
    // a handful of bins, the large ones keep the full resolution.
    const int nb = int(std::min<uint32_t>(uint32_t(this->nb), std::min<uint32_t>(n, 4 + n / 20)));
    // nb * 0.99999 / extent on the axes with extent, else 0 (one division
    // for all three; the same values as per axis).
    const __m128 with_extent = xyz(_mm_cmpgt_ps(ext, _mm_setzero_ps()));
    const __m128 scale = _mm_and_ps(_mm_div_ps(_mm_set1_ps(float(nb) * 0.99999f), ext), with_extent);
    cmin_out = cmin;
    scale_out = scale;
    nb_out = nb;
    Bins bins(nb);
    if (opt.parallel && n > kParallelPartition) {
      const uint32_t nblocks = (n + kPartitionBlock - 1) / kPartitionBlock;
      block_counts.resize(size_t(nblocks) * 3 * nb);
      tbb::combinable<Bins> local([&] { return Bins(nb); });
      tbb::parallel_for(uint32_t(0), nblocks, [&](uint32_t k) {
        Bins& bl = local.local();
        uint32_t* counts = block_counts.data() + size_t(k) * 3 * nb;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < nb; ++b) counts[a * nb + b] = bl.bin[a][b].count;
        const uint32_t b0 = begin + k * kPartitionBlock, b1 = std::min(end, b0 + kPartitionBlock);
        bin_range(bl, refs, b0, b1, cmin, scale);
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < nb; ++b) counts[a * nb + b] = bl.bin[a][b].count - counts[a * nb + b];
      });
      local.combine_each([&](const Bins& b) { bins.merge(b); });
    } else {
      bin_range(bins, refs, begin, end, cmin, scale);
    }
    // Sweep all three axes at once: right-to-left areas and block counts,
    // then left to right; per axis the first bin of least cost wins (strict <,
    // as a scalar sweep axis by axis), then the lowest axis on equal cost.
    alignas(16) __m128 right_area[kMaxFastBins], right_blocks[kMaxFastBins];
    __m128i right_nonempty[kMaxFastBins];
    SSEBox acc[3];
    __m128i cnt = _mm_setzero_si128();
    for (int b = nb - 1; b > 0; --b) {
      for (int a = 0; a < 3; ++a) acc[a].grow(bins.bin[a][b].lo, bins.bin[a][b].hi);
      cnt = _mm_add_epi32(cnt, bins.counts(b));
      right_area[b] = half_areas3(acc);
      right_blocks[b] = blocks4(cnt);
      right_nonempty[b] = _mm_cmpgt_epi32(cnt, _mm_setzero_si128());
    }
    for (SSEBox& x : acc) x = SSEBox{};
    cnt = _mm_setzero_si128();
    // Axes without extent are never split (cost stays inf).
    const __m128i axis_ok = _mm_castps_si128(_mm_cmpgt_ps(ext, _mm_setzero_ps()));
    __m128 best_cost = _mm_set1_ps(kInf);
    __m128i best_bin = _mm_setzero_si128();
    for (int b = 0; b < nb - 1; ++b) {
      for (int a = 0; a < 3; ++a) acc[a].grow(bins.bin[a][b].lo, bins.bin[a][b].hi);
      cnt = _mm_add_epi32(cnt, bins.counts(b));
      const __m128 cost = _mm_add_ps(_mm_mul_ps(half_areas3(acc), blocks4(cnt)),
                                     _mm_mul_ps(right_area[b + 1], right_blocks[b + 1]));
      const __m128i ok = _mm_and_si128(_mm_and_si128(_mm_cmpgt_epi32(cnt, _mm_setzero_si128()), right_nonempty[b + 1]), axis_ok);
      const __m128 better = _mm_and_ps(_mm_castsi128_ps(ok), _mm_cmplt_ps(cost, best_cost));
      best_cost = _mm_or_ps(_mm_and_ps(better, cost), _mm_andnot_ps(better, best_cost));
      const __m128i bb = _mm_castps_si128(better);
      best_bin = _mm_or_si128(_mm_and_si128(bb, _mm_set1_epi32(b + 1)), _mm_andnot_si128(bb, best_bin));
    }
    alignas(16) float bc[4];
    alignas(16) int bi[4];
    _mm_store_ps(bc, best_cost);
    _mm_store_si128(reinterpret_cast<__m128i*>(bi), best_bin);
    for (int axis = 0; axis < 3; ++axis)
      if (bc[axis] < best.cost) best = {axis, 0.0f, uint32_t(bi[axis]), bc[axis]};  // index: first bin on the right
    return best;
  }

  void make_leaf(BVHNode& node, const PrimRef* refs, uint32_t begin, uint32_t end) {
    node.first = begin;
    node.count = end - begin;
    for (uint32_t i = begin; i < end; ++i) {
      const float w = _mm_cvtss_f32(_mm_shuffle_ps(refs[i].lo, refs[i].lo, _MM_SHUFFLE(3, 3, 3, 3)));
      std::memcpy(&prim_order[i], &w, 4);
    }
  }

  static constexpr int kMaxSAHDepth = 32;
  // Ranges over kParallelPartition references bin and partition in parallel,
  // in blocks of kPartitionBlock. From 16,384 (was 65,536, blocks of 16,384)
  // the root of a small mesh is split in parallel too: modern_hall's 31,247
  // triangles were binned and partitioned at the root on one thread, and
  // its two-thread build scaled 1.75x where Embree's scales 2x.
  static constexpr uint32_t kParallelPartition = 16384;
  static constexpr uint32_t kPartitionBlock = 4096;

  // Stable partition of a large range in parallel (the top levels, where the
  // serial in-place partition would leave the other threads idle) in one
  // pass: each block's left count is the sum of its bin counts below the
  // split (`left`, from the binning: left_of is the binning's arithmetic, so
  // the two agree), a prefix sum gives each block its output offsets, and the
  // references scatter from `refs` to `out` (the other buffer; the children
  // continue there) while the blocks bound their left and right references.
  // The block size does not depend on the thread count, so the result is the
  // same however many threads run.
  template <typename LeftOf>
  uint32_t parallel_partition(const PrimRef* refs, PrimRef* out, uint32_t begin, uint32_t end, const LeftOf& left_of,
                              const std::vector<uint32_t>& left, SSEBox& lbox, SSEBox& rbox, SSEBox& lcbox,
                              SSEBox& rcbox) {
    const uint32_t n = end - begin;
    const uint32_t nblocks = (n + kPartitionBlock - 1) / kPartitionBlock;
    struct Part {
      SSEBox lb, rb, lcb, rcb;
    };
    std::vector<Part> parts(nblocks);
    std::vector<uint32_t> loff(nblocks), roff(nblocks);
    uint32_t total_left = 0;
    for (uint32_t k = 0; k < nblocks; ++k) loff[k] = total_left, total_left += left[k];
    uint32_t r = total_left;
    for (uint32_t k = 0; k < nblocks; ++k) {
      roff[k] = r;
      r += std::min(end, begin + (k + 1) * kPartitionBlock) - (begin + k * kPartitionBlock) - left[k];
    }
    PrimRef* tmp = out + begin;
    tbb::parallel_for(uint32_t(0), nblocks, [&](uint32_t k) {
      uint32_t l = loff[k], rr = roff[k];
      const uint32_t b0 = begin + k * kPartitionBlock, b1 = std::min(end, b0 + kPartitionBlock);
      SSEBox lb, rb, lcb, rcb;  // locals: kept in registers
      for (uint32_t i = b0; i < b1; ++i) {
        const __m128 lo = refs[i].lo, hi = refs[i].hi;
        const __m128 c = centroid2(refs[i]);
        if (left_of(refs[i])) {
          lb.grow(xyz(lo), hi);
          lcb.grow(c, c);
          tmp[l++] = refs[i];
        } else {
          rb.grow(xyz(lo), hi);
          rcb.grow(c, c);
          tmp[rr++] = refs[i];
        }
      }
      if (l != loff[k] + left[k]) throw std::logic_error("BVH build: partition disagrees with the binning");
      Part& p = parts[k];
      p.lb = lb, p.rb = rb, p.lcb = lcb, p.rcb = rcb;
    });
    for (uint32_t k = 0; k < nblocks; ++k)
      lbox.grow(parts[k].lb), rbox.grow(parts[k].rb), lcbox.grow(parts[k].lcb), rcbox.grow(parts[k].rcb);
    return begin + total_left;
  }

  // In-place partition (Hoare), growing the children's boxes and centroid
  // boxes on the way. They are kept in local vectors whose address is never
  // taken, so they stay in registers (growing the SSEBox out-parameters
  // directly went through memory, a store-to-load chain per reference).
  template <typename LeftOf>
  uint32_t serial_partition(PrimRef* r, uint32_t begin, uint32_t end, const LeftOf& left_of, SSEBox& lbox, SSEBox& rbox,
                            SSEBox& lcbox, SSEBox& rcbox) {
    __m128 llo = _mm_set1_ps(kInf), lhi = _mm_set1_ps(-kInf), lclo = llo, lchi = lhi;
    __m128 rlo = llo, rhi = lhi, rclo = llo, rchi = lhi;
    uint32_t i = begin, j = end;
    for (;;) {
      for (; i < j; ++i) {
        const __m128 lo = r[i].lo, hi = r[i].hi;
        if (!left_of(r[i])) break;
        const __m128 l = xyz(lo), c = _mm_add_ps(l, hi);
        llo = _mm_min_ps(llo, l), lhi = _mm_max_ps(lhi, hi);
        lclo = _mm_min_ps(lclo, c), lchi = _mm_max_ps(lchi, c);
      }
      for (; i < j; --j) {
        const __m128 lo = r[j - 1].lo, hi = r[j - 1].hi;
        if (left_of(r[j - 1])) break;
        const __m128 l = xyz(lo), c = _mm_add_ps(l, hi);
        rlo = _mm_min_ps(rlo, l), rhi = _mm_max_ps(rhi, hi);
        rclo = _mm_min_ps(rclo, c), rchi = _mm_max_ps(rchi, c);
      }
      if (i >= j) break;
      std::swap(r[i], r[j - 1]);
    }
    lbox.grow(llo, lhi), lcbox.grow(lclo, lchi), rbox.grow(rlo, rhi), rcbox.grow(rclo, rchi);
    return i;
  }

  // Node pairs come from chunks of kNodeChunk slots taken from the shared
  // counter: an atomic for every pair (as before) moved its cache line between
  // the cores on nearly every node of a two-thread build, and its lock prefix
  // made each allocation wait for the stores before it. A task that runs in
  // parallel with its sibling (the right child of a parallel split) starts
  // its own chunk; the left one continues its parent's. The unused rest of a
  // task's last chunk stays a gap in the array (never touched or read: the
  // tree is reached from nodes[0]). The layout depends on the schedule (as
  // it did); the tree (reached from the root), prim_order and the SAH sums
  // do not.
  static constexpr uint32_t kParallelSubtree = 4096;
  static constexpr uint32_t kNodeChunk = 64;
  std::atomic<uint32_t> node_count{1};
  struct NodeAlloc {
    uint32_t next = 0, end = 0;
  };
  uint32_t alloc_pair(NodeAlloc& a) {
    if (a.next == a.end) {
      a.next = node_count.fetch_add(kNodeChunk, std::memory_order_relaxed);
      a.end = a.next + kNodeChunk;
    }
    const uint32_t r = a.next;
    a.next += 2;
    return r;
  }
  // Slots for n references: at most 2n - 1 nodes, and each of the (fewer
  // than 2n / kParallelSubtree + 1) chunk sequences wastes less than a chunk.
  static size_t node_capacity(size_t n) { return 2 * n + (2 * n / kParallelSubtree + 2) * kNodeChunk; }
  struct Result {
    double inner_area;    // sum of the half areas of the subtree's interior nodes
    double leaf_area;     // sum over its leaves of count x half area
  };

  Result build(uint32_t node_index, NodeAlloc& alloc, int side, uint32_t begin, uint32_t end, const SSEBox& box,
               const SSEBox& cbox, int depth) {
    PrimRef* const refs = buf[side];
    BVHNode& node = nodes[node_index];
    const AABB b = box.aabb();
    node.lo = b.lo;
    node.hi = b.hi;
    const uint32_t n = end - begin;
    const double area = b.half_area();
    const Result leaf{0.0, area * n};
    if (n <= 1) return make_leaf(node, refs, begin, end), leaf;
    uint32_t mid = begin;
    SSEBox lbox, rbox, lcbox, rcbox;
    bool have_boxes = false;
    int child_side = side;
    // At most one block that fits a leaf: a split costs the traversal step
    // plus at least the children's triangles, never less than the leaf, so
    // the SAH would make it a leaf anyway; skip the binning.
    if (n <= block && n <= uint32_t(opt.max_leaf_size) && opt.traversal_cost >= opt.intersection_cost)
      return make_leaf(node, refs, begin, end), leaf;
    if (depth >= kMaxSAHDepth) {
      if (n <= uint32_t(opt.max_leaf_size)) return make_leaf(node, refs, begin, end), leaf;
    } else {
      __m128 cmin, scale;
      std::vector<uint32_t> block_counts;  // filled for ranges partitioned in parallel
      int nbins = 0;
      Split split = find_split(refs, begin, end, cbox, cmin, scale, block_counts, nbins);
      const float leaf_cost = opt.intersection_cost * blocks(n);
      const float split_cost =
          split.axis < 0 ? kInf : opt.traversal_cost + opt.intersection_cost * split.cost / box.half_area();
      if (n <= uint32_t(opt.max_leaf_size) && (leaf_cost <= split_cost || split.axis < 0))
        return make_leaf(node, refs, begin, end), leaf;
      if (split.axis >= 0) {
        // The binning's own arithmetic, on the split axis only.
        const __m128i pivot = _mm_set1_epi32(int(split.index));
        const int axis_bit = 1 << split.axis;
        auto left_of = [cmin, scale, pivot, axis_bit](const PrimRef& r) {
          const __m128i bi = _mm_cvttps_epi32(_mm_mul_ps(_mm_sub_ps(centroid2(r), cmin), scale));
          return (_mm_movemask_ps(_mm_castsi128_ps(_mm_cmplt_epi32(bi, pivot))) & axis_bit) != 0;
        };
        if (opt.parallel && n > kParallelPartition) {
          // Each block's references left of the split: its counts in the bins before it.
          const size_t nblocks = block_counts.size() / (3 * size_t(nbins));
          std::vector<uint32_t> left(nblocks, 0);
          for (size_t k = 0; k < nblocks; ++k)
            for (uint32_t b = 0; b < split.index; ++b) left[k] += block_counts[(k * 3 + split.axis) * nbins + b];
          mid = parallel_partition(refs, buf[side ^ 1], begin, end, left_of, left, lbox, rbox, lcbox, rcbox);
          child_side = side ^ 1;
        } else {
          mid = serial_partition(refs, begin, end, left_of, lbox, rbox, lcbox, rcbox);
        }
        have_boxes = true;
      }
    }
    if (mid == begin || mid == end) {  // inseparable centroids or no split: by count
      mid = begin + n / 2;
      have_boxes = false;
    }
    if (!have_boxes) {
      const PrimRef* in = buf[child_side];  // a parallel partition to one side moved them all there
      lbox = rbox = lcbox = rcbox = SSEBox{};
      for (uint32_t i = begin; i < end; ++i) {
        const __m128 c = centroid2(in[i]);
        if (i < mid) lbox.grow(lo_of(in[i]), in[i].hi), lcbox.grow(c, c);
        else rbox.grow(lo_of(in[i]), in[i].hi), rcbox.grow(c, c);
      }
    }
    const uint32_t left = alloc_pair(alloc);
    node.first = left;
    node.count = 0;
    Result l, r;
    if (opt.parallel && n > kParallelSubtree) {
      tbb::parallel_invoke([&] { l = build(left, alloc, child_side, begin, mid, lbox, lcbox, depth + 1); },
                           [&] {
                             NodeAlloc own;
                             r = build(left + 1, own, child_side, mid, end, rbox, rcbox, depth + 1);
                           });
    } else {
      l = build(left, alloc, child_side, begin, mid, lbox, lcbox, depth + 1);
      r = build(left + 1, alloc, child_side, mid, end, rbox, rcbox, depth + 1);
    }
    return {area + l.inner_area + r.inner_area, l.leaf_area + r.leaf_area};
  }
};

BVH build_binned_fast(const AABB* prim_bounds, size_t num_prims, const BuildOptions& options) {
  FastBuilder b(options);
  // References of the valid boxes, in input order, in one pass over the
  // boxes (as Embree's primref creation): each block writes its valid ones
  // from its own start, as if all were valid, and bounds them; when some
  // were not, the blocks move down to the offsets a prefix sum gives (in
  // parallel through the scratch buffer when there is one). Same result with
  // or without tasks.
  constexpr size_t kRefBlock = 16384;
  const size_t nblocks = (num_prims + kRefBlock - 1) / kRefBlock;
  struct RefBlock {
    uint32_t count = 0, offset = 0;
    SSEBox box, cbox;
  };
  std::vector<RefBlock> blocks(nblocks);
  auto for_blocks = [&](const auto& body) {
    if (options.parallel && nblocks > 1) tbb::parallel_for(size_t(0), nblocks, body);
    else for (size_t k = 0; k < nblocks; ++k) body(k);
  };
  BVH bvh;
  if (num_prims == 0) return bvh;
  b.refs.resize(num_prims);
  for_blocks([&](size_t k) {
    RefBlock& blk = blocks[k];
    PrimRef* const start = b.refs.data() + k * kRefBlock;
    PrimRef* out = start;
    SSEBox bx, cb;  // locals: kept in registers
    const __m128 zero = _mm_setzero_ps();
    for (size_t i = k * kRefBlock, e = std::min(num_prims, i + kRefBlock); i < e; ++i) {
      // lo.x lo.y lo.z hi.x and lo.z hi.x hi.y hi.z: both loads inside the box.
      const float* f = &prim_bounds[i].lo.x;
      const __m128 l = _mm_loadu_ps(f), h4 = _mm_loadu_ps(f + 2);
      // Valid: every coordinate finite (x - x is 0 only then) and not empty
      // (AABB::empty: lo.x > hi.x).
      const __m128 fin = _mm_and_ps(_mm_cmpeq_ps(_mm_sub_ps(l, l), zero), _mm_cmpeq_ps(_mm_sub_ps(h4, h4), zero));
      if (_mm_movemask_ps(fin) != 0xF || _mm_comigt_ss(l, _mm_shuffle_ps(l, l, _MM_SHUFFLE(3, 3, 3, 3)))) continue;
      const __m128 h = xyz(_mm_shuffle_ps(h4, h4, _MM_SHUFFLE(0, 3, 2, 1)));
      const __m128 lo = _mm_or_ps(xyz(l), _mm_castsi128_ps(_mm_setr_epi32(0, 0, 0, int(uint32_t(i)))));
      *out++ = PrimRef{lo, h};
      const __m128 c = _mm_add_ps(xyz(l), h);
      bx.grow(xyz(l), h);
      cb.grow(c, c);
    }
    blk.count = uint32_t(out - start);
    blk.box = bx, blk.cbox = cb;
  });
  uint32_t total = 0;
  for (RefBlock& blk : blocks) blk.offset = total, total += blk.count;
  if (total == 0) return bvh;
  b.num_refs = total;
  if (options.parallel && total > FastBuilder::kParallelPartition) b.scratch.resize(total);
  if (total != num_prims) {
    if (!b.scratch.empty()) {
      for_blocks([&](size_t k) {
        std::memcpy(b.scratch.data() + blocks[k].offset, b.refs.data() + k * kRefBlock, blocks[k].count * sizeof(PrimRef));
      });
      std::swap(b.refs, b.scratch);
    } else {
      for (size_t k = 0; k < nblocks; ++k)  // offsets never pass their block's start: in order, in place
        std::memmove(b.refs.data() + blocks[k].offset, b.refs.data() + k * kRefBlock, blocks[k].count * sizeof(PrimRef));
    }
  }
  SSEBox box, cbox;
  for (const RefBlock& blk : blocks) box.grow(blk.box), cbox.grow(blk.cbox);
  b.buf[0] = b.refs.data();
  b.buf[1] = b.scratch.data();
  b.nodes.resize(FastBuilder::node_capacity(total));
  bvh.prim_order.resize(total);
  b.prim_order = bvh.prim_order.data();
  FastBuilder::NodeAlloc alloc;
  const FastBuilder::Result res = b.build(0, alloc, 0, 0, total, box, cbox, 0);
  b.nodes.resize(b.node_count.load());  // no shrink-to-fit copy: the rest was never touched
  bvh.nodes = std::move(b.nodes);
  bvh.sah_inner_area = res.inner_area;
  bvh.sah_leaf_area = res.leaf_area;
  return bvh;
}

}  // namespace

BVH build_bvh(const AABB* prim_bounds, size_t count, const BuildOptions& options) {
  if (options.method == SplitMethod::BinnedSAH) return build_binned_fast(prim_bounds, count, options);
  return build_bvh(std::vector<AABB>(prim_bounds, prim_bounds + count), options);
}

BVH build_bvh(const std::vector<AABB>& prim_bounds, const BuildOptions& options) {
  if (options.method == SplitMethod::BinnedSAH) return build_binned_fast(prim_bounds.data(), prim_bounds.size(), options);
  Builder b(prim_bounds, options);
  b.centroids.resize(prim_bounds.size());
  b.prims.reserve(prim_bounds.size());
  for (uint32_t i = 0; i < prim_bounds.size(); ++i) {
    const AABB& box = prim_bounds[i];
    if (box.empty() || !is_finite(box.lo) || !is_finite(box.hi)) continue;
    b.centroids[i] = box.center();
    b.prims.push_back(i);
  }
  BVH bvh;
  if (b.prims.empty()) return bvh;
  b.nodes.resize(2 * b.prims.size());
  b.build(0, 0, uint32_t(b.prims.size()));
  b.nodes.resize(b.node_count.load());
  b.nodes.shrink_to_fit();
  bvh.nodes = std::move(b.nodes);
  bvh.prim_order = std::move(b.prims);
  return bvh;
}

float sah_cost(const BVH& bvh, const BuildOptions& options) {
  if (bvh.nodes.empty()) return 0.0f;
  const float root_area = AABB{bvh.nodes[0].lo, bvh.nodes[0].hi}.half_area();
  if (root_area <= 0.0f) return 0.0f;
  if (bvh.sah_inner_area >= 0.0)  // summed by the build
    return float((options.traversal_cost * bvh.sah_inner_area + options.intersection_cost * bvh.sah_leaf_area) /
                 root_area);
  // The nodes reached from the root (the node array may have unused slots),
  // in a fixed order.
  double cost = 0.0;
  std::vector<uint32_t> stack{0u};
  while (!stack.empty()) {
    const BVHNode& n = bvh.nodes[stack.back()];
    stack.pop_back();
    const float area = AABB{n.lo, n.hi}.half_area() / root_area;
    if (n.is_leaf()) {
      cost += options.intersection_cost * n.count * area;
    } else {
      cost += options.traversal_cost * area;
      stack.push_back(n.first + 1);
      stack.push_back(n.first);
    }
  }
  return float(cost);
}

int BVH::depth() const {
  if (nodes.empty()) return 0;
  int best = 0;
  std::vector<std::pair<uint32_t, int>> stack{{0u, 1}};
  while (!stack.empty()) {
    auto [i, d] = stack.back();
    stack.pop_back();
    best = std::max(best, d);
    if (!nodes[i].is_leaf()) {
      stack.push_back({nodes[i].first, d + 1});
      stack.push_back({nodes[i].first + 1, d + 1});
    }
  }
  return best;
}

}  // namespace tessera
