#include "bvh.h"

#include <tbb/parallel_invoke.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <atomic>
#include <numeric>

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
  std::vector<BVHNode> nodes;
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

}  // namespace

BVH build_bvh(const std::vector<AABB>& prim_bounds, const BuildOptions& options) {
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
  double cost = 0.0;
  for (const BVHNode& n : bvh.nodes) {
    float area = AABB{n.lo, n.hi}.half_area() / root_area;
    cost += n.is_leaf() ? options.intersection_cost * n.count * area : options.traversal_cost * area;
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
