#include "light_bvh.h"

#include <algorithm>
#include <numeric>

namespace tessera {

namespace {

float safe_acos(float c) { return std::acos(std::clamp(c, -1.0f, 1.0f)); }

// cos(max(0, a - b)) and sin(max(0, a - b)) from the sines and cosines of a and b.
float cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  return cos_a > cos_b ? 1.0f : cos_a * cos_b + sin_a * sin_b;
}
float sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  return cos_a > cos_b ? 0.0f : sin_a * cos_b - cos_a * sin_b;
}

// Rotation of v by angle theta about the unit axis k (Rodrigues).
vec3 rotate(const vec3& v, const vec3& k, float theta) {
  const float c = std::cos(theta), s = std::sin(theta);
  return v * c + glm::cross(k, v) * s + k * (glm::dot(k, v) * (1.0f - c));
}

// Solid-angle measure of the directions a cone of normals (theta_o) with
// emission spread theta_e can emit into (Conty Estevez and Kulla 2018, eq. 1).
float m_omega(const LightBounds& lb) {
  const float theta_o = safe_acos(lb.cos_theta_o), theta_e = safe_acos(lb.cos_theta_e);
  const float theta_w = std::min(theta_o + theta_e, kPi);
  const float sin_o = std::sin(theta_o);
  return 2.0f * kPi * (1.0f - lb.cos_theta_o) +
         0.5f * kPi * (2.0f * theta_w * sin_o - std::cos(theta_o - 2.0f * theta_w) - 2.0f * theta_o * sin_o + lb.cos_theta_o);
}

// Cost of a node for the split heuristic (SAOH): power x orientation
// measure x surface area, stretched along the split axis (pbrt-v4 EvaluateCost).
float saoh_cost(const LightBounds& lb, const AABB& parent, int axis) {
  const vec3 e = parent.extent();
  const float kr = max_component(e) / std::max(e[axis], 1e-30f);
  const vec3 be = lb.bounds.extent();
  const float area = 2.0f * (be.x * be.y + be.y * be.z + be.z * be.x);
  return lb.phi * m_omega(lb) * kr * area;
}

constexpr int kMaxDepth = 60;  // the bit trail has 64 bits

// Bucket of a centroid coordinate c in [lo, lo + ext), clamped in float before
// the conversion: with extents near the float range (or NaN from inf - inf)
// the quotient is not a valid int (a fuzzer found the out-of-range bucket).
int bucket_index(float c, float lo, float ext, int buckets) {
  const float f = float(buckets) * (c - lo) / ext;
  return f >= float(buckets - 1) ? buckets - 1 : f > 0.0f ? int(f) : 0;
}

}  // namespace

ImportanceBounds::ImportanceBounds(const LightBounds& lb)
    : centre(lb.bounds.center()), phi(lb.phi), w(lb.w), cos_theta_o(lb.cos_theta_o),
      sin_theta_o(safe_sqrt(1.0f - lb.cos_theta_o * lb.cos_theta_o)), cos_theta_e(lb.cos_theta_e),
      radius2(0.25f * glm::dot(lb.bounds.extent(), lb.bounds.extent())),
      min_dist2(0.5f * glm::length(lb.bounds.extent())), two_sided(lb.two_sided) {}

float ImportanceBounds::importance(const vec3& p, const vec3& n) const {
  if (phi <= 0.0f) return 0.0f;
  const vec3 to_p = p - centre;
  const float dist2 = glm::dot(to_p, to_p);
  // Distance clamped to half the box diagonal: inside or close to the box the
  // 1/d^2 would blow up on a bound, not on a light.
  const float d2 = std::max(dist2, min_dist2);
  const float inv_len = dist2 > 0.0f ? 1.0f / std::sqrt(dist2) : 0.0f;
  const vec3 wi = dist2 > 0.0f ? to_p * inv_len : vec3(0.0f, 0.0f, 1.0f);
  // Angle between the cone's axis and the direction to p, less the cone's
  // spread theta_o and the box's own spread theta_b as seen from p (the
  // half-angle of the cone from p that holds the bounding sphere; all
  // directions from inside it).
  float cos_w = glm::dot(w, wi);
  if (two_sided) cos_w = std::abs(cos_w);
  const float sin_w = safe_sqrt(1.0f - cos_w * cos_w);
  const bool inside = dist2 < radius2;
  const float sin2_b = inside ? 0.0f : radius2 * (inv_len * inv_len);
  const float cos_b = inside ? -1.0f : safe_sqrt(1.0f - sin2_b), sin_b = std::sqrt(sin2_b);
  const float cos_x = cos_sub_clamped(sin_w, cos_w, sin_theta_o, cos_theta_o);
  const float sin_x = sin_sub_clamped(sin_w, cos_w, sin_theta_o, cos_theta_o);
  const float cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
  if (cos_p <= cos_theta_e) return 0.0f;
  float imp = phi * cos_p / d2;
  // The receiver's cosine, bounded the same way (either side: BSDFs may transmit).
  if (n != vec3(0.0f)) {
    const float cos_i = std::abs(glm::dot(wi, n)), sin_i = safe_sqrt(1.0f - cos_i * cos_i);
    imp *= cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
  }
  return std::max(imp, 0.0f);
}

LightBounds union_bounds(const LightBounds& a, const LightBounds& b) {
  if (a.phi <= 0.0f) return b;
  if (b.phi <= 0.0f) return a;
  LightBounds u;
  u.bounds = a.bounds;
  u.bounds.grow(b.bounds);
  u.phi = a.phi + b.phi;
  u.two_sided = a.two_sided || b.two_sided;
  u.cos_theta_e = std::min(a.cos_theta_e, b.cos_theta_e);
  // Smallest cone holding both cones of normals (pbrt-v4 DirectionCone Union).
  const float theta_a = safe_acos(a.cos_theta_o), theta_b = safe_acos(b.cos_theta_o);
  const float dot = glm::dot(a.w, b.w);
  const float theta_d = dot < 0.0f ? kPi - 2.0f * std::asin(std::min(1.0f, glm::length(a.w + b.w) / 2.0f))
                                   : 2.0f * std::asin(std::min(1.0f, glm::length(b.w - a.w) / 2.0f));
  if (std::min(theta_d + theta_b, kPi) <= theta_a) {
    u.w = a.w, u.cos_theta_o = a.cos_theta_o;
  } else if (std::min(theta_d + theta_a, kPi) <= theta_b) {
    u.w = b.w, u.cos_theta_o = b.cos_theta_o;
  } else {
    const float theta_o = 0.5f * (theta_a + theta_d + theta_b);
    const vec3 axis = glm::cross(a.w, b.w);
    if (theta_o >= kPi || glm::dot(axis, axis) == 0.0f) {
      u.w = a.w, u.cos_theta_o = -1.0f;  // the whole sphere
    } else {
      u.w = glm::normalize(rotate(a.w, glm::normalize(axis), theta_o - theta_a));
      u.cos_theta_o = std::cos(theta_o);
    }
  }
  return u;
}

void LightBVH::build(const std::vector<LightBounds>& lights) {
  nodes_.clear();
  trail_.assign(lights.size(), ~uint64_t(0));
  std::vector<uint32_t> ids;
  for (uint32_t i = 0; i < lights.size(); ++i)
    if (lights[i].phi > 0.0f) ids.push_back(i);
  if (ids.empty()) return;
  nodes_.reserve(2 * ids.size());
  std::vector<LightBounds> node_bounds;
  node_bounds.reserve(2 * ids.size());
  build_node(ids, 0, ids.size(), lights, 0, 0, node_bounds);
  for (size_t i = 0; i < nodes_.size(); ++i) nodes_[i].ib = ImportanceBounds(node_bounds[i]);
}

uint32_t LightBVH::build_node(std::vector<uint32_t>& ids, size_t begin, size_t end,
                              const std::vector<LightBounds>& lights, uint64_t trail, int depth,
                              std::vector<LightBounds>& node_bounds) {
  const uint32_t node = uint32_t(nodes_.size());
  nodes_.emplace_back();
  node_bounds.emplace_back();
  if (end - begin == 1) {
    node_bounds[node] = lights[ids[begin]];
    nodes_[node].leaf = true;
    nodes_[node].index = ids[begin];
    trail_[ids[begin]] = trail;
    return node;
  }
  AABB bounds, centroids;
  for (size_t i = begin; i < end; ++i) {
    bounds.grow(lights[ids[i]].bounds);
    centroids.grow(lights[ids[i]].bounds.center());
  }
  // Split by the SAOH over 12 buckets per axis (pbrt-v4 BVHLightSampler::
  // buildBVH); by count at the middle of the widest axis when the centroids
  // coincide or the tree gets deep.
  size_t mid = begin + (end - begin) / 2;
  const int widest = max_dimension(centroids.extent());
  bool split = false;
  if (depth < kMaxDepth - 20 && max_component(centroids.extent()) > 0.0f) {
    constexpr int kBuckets = 12;
    float best_cost = kInf;
    int best_axis = -1, best_bucket = -1;
    for (int axis = 0; axis < 3; ++axis) {
      const float lo = centroids.lo[axis], ext = centroids.hi[axis] - lo;
      if (!(ext > 0.0f)) continue;
      LightBounds bucket[kBuckets];
      auto bucket_of = [&](uint32_t id) { return bucket_index(lights[id].bounds.center()[axis], lo, ext, kBuckets); };
      for (size_t i = begin; i < end; ++i) {
        const int b = bucket_of(ids[i]);
        bucket[b] = union_bounds(bucket[b], lights[ids[i]]);
      }
      for (int b = 0; b < kBuckets - 1; ++b) {
        LightBounds below, above;
        for (int k = 0; k <= b; ++k) below = union_bounds(below, bucket[k]);
        for (int k = b + 1; k < kBuckets; ++k) above = union_bounds(above, bucket[k]);
        if (below.phi <= 0.0f || above.phi <= 0.0f) continue;
        const float cost = saoh_cost(below, bounds, axis) + saoh_cost(above, bounds, axis);
        if (cost < best_cost) best_cost = cost, best_axis = axis, best_bucket = b;
      }
    }
    if (best_axis >= 0) {
      const float lo = centroids.lo[best_axis], ext = centroids.hi[best_axis] - lo;
      auto it = std::partition(ids.begin() + begin, ids.begin() + end, [&](uint32_t id) {
        return bucket_index(lights[id].bounds.center()[best_axis], lo, ext, kBuckets) <= best_bucket;
      });
      mid = size_t(it - ids.begin());
      split = mid > begin && mid < end;
    }
  }
  if (!split) {
    mid = begin + (end - begin) / 2;
    std::nth_element(ids.begin() + begin, ids.begin() + mid, ids.begin() + end, [&](uint32_t a, uint32_t b) {
      return lights[a].bounds.center()[widest] < lights[b].bounds.center()[widest];
    });
  }
  build_node(ids, begin, mid, lights, trail, depth + 1, node_bounds);
  const uint32_t second = build_node(ids, mid, end, lights, trail | (uint64_t(1) << depth), depth + 1, node_bounds);
  nodes_[node].index = second;
  node_bounds[node] = union_bounds(node_bounds[node + 1], node_bounds[second]);
  return node;
}

bool LightBVH::sample(const vec3& p, const vec3& n, float u, uint32_t* light, float* pmf, float* u_remapped) const {
  if (nodes_.empty()) return false;
  uint32_t node = 0;
  float prob = 1.0f;
  // A lone light is picked only where it can contribute; below an interior
  // root the children's importances decide (pbrt-v4), so the root's own
  // importance is not evaluated.
  if (nodes_[0].leaf && !(nodes_[0].ib.importance(p, n) > 0.0f)) return false;
  while (!nodes_[node].leaf) {
    const uint32_t c0 = node + 1, c1 = nodes_[node].index;
    const float i0 = nodes_[c0].ib.importance(p, n), i1 = nodes_[c1].ib.importance(p, n);
    if (!(i0 + i1 > 0.0f)) return false;
    const float p0 = i0 / (i0 + i1);
    // Reuse u for the next level, rescaled to [0,1) (pbrt-v4 SampleDiscrete).
    if (u < p0) {
      node = c0, prob *= p0, u = std::min(u / p0, 0x1.fffffep-1f);
    } else {
      node = c1, prob *= 1.0f - p0, u = std::min((u - p0) / (1.0f - p0), 0x1.fffffep-1f);
    }
  }
  *light = nodes_[node].index;
  *pmf = prob;
  if (u_remapped) *u_remapped = u;
  return prob > 0.0f;
}

float LightBVH::pmf(const vec3& p, const vec3& n, uint32_t light) const {
  if (light >= trail_.size() || trail_[light] == ~uint64_t(0)) return 0.0f;
  if (nodes_[0].leaf && !(nodes_[0].ib.importance(p, n) > 0.0f)) return 0.0f;
  uint64_t trail = trail_[light];
  uint32_t node = 0;
  float prob = 1.0f;
  while (!nodes_[node].leaf) {
    const uint32_t c0 = node + 1, c1 = nodes_[node].index;
    const float i0 = nodes_[c0].ib.importance(p, n), i1 = nodes_[c1].ib.importance(p, n);
    if (!(i0 + i1 > 0.0f)) return 0.0f;
    if (trail & 1) {
      prob *= i1 / (i0 + i1), node = c1;
    } else {
      prob *= i0 / (i0 + i1), node = c0;
    }
    trail >>= 1;
  }
  return prob;
}

}  // namespace tessera
