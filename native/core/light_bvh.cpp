#include "light_bvh.h"

#include <algorithm>
#include <numeric>

#include <emmintrin.h>
#include <tbb/parallel_invoke.h>

#include "light_importance_simd.h"
#include "simd.h"

namespace tessera {

namespace {

float safe_acos(float c) { return std::acos(std::clamp(c, -1.0f, 1.0f)); }

// Rotation of v by angle theta about the unit axis k (Rodrigues).
vec3 rotate(const vec3& v, const vec3& k, float theta) {
  const float c = std::cos(theta), s = std::sin(theta);
  return v * c + glm::cross(k, v) * s + k * (glm::dot(k, v) * (1.0f - c));
}

// A LightBounds with its cone angles themselves: the build unions bounds
// hundreds of thousands of times, and the arc cosines were most of its time.
struct BuildBounds {
  LightBounds lb;
  float theta_o = 0.0f, theta_e = kPi / 2;  // acos of lb.cos_theta_o, lb.cos_theta_e
  float sin_theta_o = 0.0f;

  BuildBounds() = default;
  explicit BuildBounds(const LightBounds& b)
      : lb(b), theta_o(safe_acos(b.cos_theta_o)), theta_e(safe_acos(b.cos_theta_e)),
        sin_theta_o(safe_sqrt(1.0f - b.cos_theta_o * b.cos_theta_o)) {}
};

// cos(a.theta_o - b.theta_o), for a.theta_o >= b.theta_o.
inline float cos_difference(const BuildBounds& a, const BuildBounds& b) {
  return a.lb.cos_theta_o * b.lb.cos_theta_o + a.sin_theta_o * b.sin_theta_o;
}

// Smallest bounds holding a and b: box, power, and the smallest cone holding
// both cones of normals (pbrt-v4 DirectionCone Union).
BuildBounds union_bounds(const BuildBounds& a, const BuildBounds& b) {
  if (a.lb.phi <= 0.0f) return b;
  if (b.lb.phi <= 0.0f) return a;
  BuildBounds u;
  u.lb.bounds = a.lb.bounds;
  u.lb.bounds.grow(b.lb.bounds);
  u.lb.phi = a.lb.phi + b.lb.phi;
  u.lb.two_sided = a.lb.two_sided || b.lb.two_sided;
  u.lb.cos_theta_e = std::min(a.lb.cos_theta_e, b.lb.cos_theta_e);
  u.theta_e = std::max(a.theta_e, b.theta_e);
  const float theta_a = a.theta_o, theta_b = b.theta_o;
  const vec3 &wa = a.lb.w, &wb = b.lb.w;
  // Cheap answers first (the build's buckets soon hold wide cones, which
  // most further lights fall inside): a whole-sphere cone holds anything,
  // and the wider cone holds the other when the angle between the axes is at
  // most the difference of their angles, compared by cosines (a margin
  // leaves the close cases to the exact test below).
  const float cos_d = glm::dot(wa, wb);
  if (theta_a >= kPi || (theta_a >= theta_b && cos_d >= cos_difference(a, b) + 1e-5f)) {
    u.lb.w = wa, u.lb.cos_theta_o = a.lb.cos_theta_o, u.theta_o = theta_a, u.sin_theta_o = a.sin_theta_o;
    return u;
  }
  if (theta_b >= kPi || (theta_b >= theta_a && cos_d >= cos_difference(b, a) + 1e-5f)) {
    u.lb.w = wb, u.lb.cos_theta_o = b.lb.cos_theta_o, u.theta_o = theta_b, u.sin_theta_o = b.sin_theta_o;
    return u;
  }
  const float theta_d = cos_d < 0.0f ? kPi - 2.0f * std::asin(std::min(1.0f, glm::length(wa + wb) / 2.0f))
                                                : 2.0f * std::asin(std::min(1.0f, glm::length(wb - wa) / 2.0f));
  if (std::min(theta_d + theta_b, kPi) <= theta_a) {
    u.lb.w = wa, u.lb.cos_theta_o = a.lb.cos_theta_o, u.theta_o = theta_a, u.sin_theta_o = a.sin_theta_o;
  } else if (std::min(theta_d + theta_a, kPi) <= theta_b) {
    u.lb.w = wb, u.lb.cos_theta_o = b.lb.cos_theta_o, u.theta_o = theta_b, u.sin_theta_o = b.sin_theta_o;
  } else {
    const float theta_o = 0.5f * (theta_a + theta_d + theta_b);
    const vec3 axis = glm::cross(wa, wb);
    if (theta_o >= kPi || glm::dot(axis, axis) == 0.0f) {
      u.lb.w = wa, u.lb.cos_theta_o = -1.0f, u.theta_o = kPi, u.sin_theta_o = 0.0f;  // the whole sphere
    } else {
      u.lb.w = glm::normalize(rotate(wa, glm::normalize(axis), theta_o - theta_a));
      u.lb.cos_theta_o = std::cos(theta_o);
      u.sin_theta_o = std::sin(theta_o);
      u.theta_o = theta_o;
    }
  }
  return u;
}

// Solid-angle measure of the directions a cone of normals (theta_o) with
// emission spread theta_e can emit into (Conty Estevez and Kulla 2018,
// eq. 1), with theta_w = min(theta_o + theta_e, pi). While theta_o + theta_e
// <= pi, cos(theta_o - 2 theta_w) = cos(theta_o + 2 theta_e) and
// 2 (theta_w - theta_o) sin theta_o = 2 theta_e sin theta_o: no angle of the
// cone itself is needed, only its cosine and sine.
float m_omega(float cos_o, float sin_o, float cos_e, float theta_e) {
  if (cos_o >= -cos_e) {  // theta_o + theta_e <= pi
    const float sin_e = safe_sqrt(1.0f - cos_e * cos_e);
    const float cos_2e = 2.0f * cos_e * cos_e - 1.0f, sin_2e = 2.0f * sin_e * cos_e;
    return 2.0f * kPi * (1.0f - cos_o) +
           0.5f * kPi * (2.0f * theta_e * sin_o - (cos_o * cos_2e - sin_o * sin_2e) + cos_o);
  }
  // theta_w = pi: cos(theta_o - 2 pi) = cos theta_o.
  return 2.0f * kPi * (1.0f - cos_o) + kPi * sin_o * (kPi - safe_acos(cos_o));
}

// Buckets per axis for the SAOH (pbrt-v4's 12).
constexpr int kMaxBuckets = 12;

// Below this depth the SAOH gives way to splits by count (log2 of the rest).
constexpr int kMaxDepth = 40;

// Bucket of a centroid coordinate c in [lo, lo + ext), scale = buckets / ext,
// clamped in float before the conversion: with extents near the float range
// (or NaN from inf - inf) the product is not a valid int (a fuzzer found the
// out-of-range bucket).
int bucket_index(float c, float lo, float scale, int buckets) {
  const float f = (c - lo) * scale;
  return f >= float(buckets - 1) ? buckets - 1 : f > 0.0f ? int(f) : 0;
}

}  // namespace

ImportanceBounds::ImportanceBounds(const LightBounds& lb)
    : centre(lb.bounds.center()), phi(lb.phi), w(lb.w), cos_theta_o(lb.cos_theta_o),
      sin_theta_o(safe_sqrt(1.0f - lb.cos_theta_o * lb.cos_theta_o)), cos_theta_e(lb.cos_theta_e),
      radius(0.5f * glm::length(lb.bounds.extent())), inv_min_dist2(1.0f / radius), two_sided(lb.two_sided) {}

// pbrt-v4's LightBounds::Importance with every cosine and sine of an angle
// at p kept multiplied by the distance D = |p - centre| (or by D^2 after
// one product of two), so that no unit vector and no D are needed: for the
// cone's axis cos_w D = w.(p - c), sin_w D = sqrt(D^2 - (cos_w D)^2); for
// the bounding sphere sin_b D = r, cos_b D = sqrt(D^2 - r^2); one division
// by D^2 at the end. Three square roots and one division where the unit
// vector form took five and two. The clamped differences cos(max(0, a - b))
// are 1 where a < b, tested on the scaled cosines (or, for theta_w < theta_o,
// by the signed squares of w.(p - c) and cos_o D, which need no D).
float ImportanceBounds::importance(const vec3& p, const vec3& n) const {
  if (phi <= 0.0f) return 0.0f;
  const vec3 t = p - centre;
  const float dist2 = glm::dot(t, t);
  const float inv_dist2 = 1.0f / dist2;
  // 1 / d^2 with d^2 clamped to half the box diagonal: inside or close to
  // the box the 1/d^2 would blow up on a bound, not on a light.
  const float inv_d2 = std::min(inv_dist2, inv_min_dist2);
  float cw = glm::dot(w, t);  // cos_w D
  if (two_sided) cw = std::abs(cw);
  const float sw = safe_sqrt(dist2 - cw * cw);  // sin_w D
  // Directions from p into the cone of normals (theta_w < theta_o), or p
  // inside the bounding sphere (every direction): cos theta' = 1.
  const bool in_cone = cw * std::abs(cw) > cos_theta_o * std::abs(cos_theta_o) * dist2;
  const bool inside = dist2 < radius * radius;
  const float cb = safe_sqrt(dist2 - radius * radius);  // cos_b D outside
  // theta_x = theta_w - theta_o, then theta' = theta_x - theta_b.
  const float cx = cw * cos_theta_o + sw * sin_theta_o, sx = sw * cos_theta_o - cw * sin_theta_o;
  const float cos_p = in_cone || inside || cx > cb ? 1.0f : (cx * cb + sx * radius) * inv_dist2;
  if (!(cos_p > cos_theta_e)) return 0.0f;
  float imp = phi * cos_p * inv_d2;
  // The receiver's cosine, bounded the same way (either side: BSDFs may transmit).
  if (n != vec3(0.0f)) {
    const float ci = std::abs(glm::dot(n, t)), si = safe_sqrt(dist2 - ci * ci);  // cos_i D, sin_i D
    imp *= inside || ci > cb ? 1.0f : (ci * cb + si * radius) * inv_dist2;
  }
  return std::max(imp, 0.0f);
}

void ImportanceBounds8::set(int k, const ImportanceBounds& b) {
  cx[k] = b.centre.x, cy[k] = b.centre.y, cz[k] = b.centre.z;
  wx[k] = b.w.x, wy[k] = b.w.y, wz[k] = b.w.z;
  phi[k] = b.phi, cos_o[k] = b.cos_theta_o, sin_o[k] = b.sin_theta_o, cos_e[k] = b.cos_theta_e;
  radius[k] = b.radius, inv_min_dist2[k] = b.inv_min_dist2;
  two_sided[k] = b.two_sided ? ~0u : 0u;
}

namespace {
struct Sse2Ops {  // every x86-64 CPU
  using T = __m128;
  static T load(const float* x) { return _mm_load_ps(x); }
  static T bits(const uint32_t* x) { return _mm_castsi128_ps(_mm_load_si128(reinterpret_cast<const __m128i*>(x))); }
  static void store(float* x, T v) { _mm_storeu_ps(x, v); }
  static T set1(float x) { return _mm_set1_ps(x); }
  static T abs_mask() { return _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff)); }
  static T add(T a, T b) { return _mm_add_ps(a, b); }
  static T sub(T a, T b) { return _mm_sub_ps(a, b); }
  static T mul(T a, T b) { return _mm_mul_ps(a, b); }
  static T div(T a, T b) { return _mm_div_ps(a, b); }
  static T sqrt(T a) { return _mm_sqrt_ps(a); }
  static T max(T a, T b) { return _mm_max_ps(a, b); }
  static T min(T a, T b) { return _mm_min_ps(a, b); }
  static T and_(T a, T b) { return _mm_and_ps(a, b); }
  static T andnot(T a, T b) { return _mm_andnot_ps(a, b); }
  static T or_(T a, T b) { return _mm_or_ps(a, b); }
  static T cmpgt(T a, T b) { return _mm_cmpgt_ps(a, b); }
  static T cmplt(T a, T b) { return _mm_cmplt_ps(a, b); }
};
}  // namespace

void ImportanceBounds8::importance_sse2(const vec3& p, const vec3& n, float out[8]) const {
  ImportanceLanes<Sse2Ops>::eval(*this, 0, p, n, out);
  ImportanceLanes<Sse2Ops>::eval(*this, 4, p, n, out);
}

void ImportanceBounds8::importance(const vec3& p, const vec3& n, float out[8]) const {
  static const bool avx2 = cpu_simd_level() == SimdLevel::AVX2;
  if (avx2)
    importance_avx2(p, n, out);
  else
    importance_sse2(p, n, out);
}

// Builds the binary SAOH tree over the lights, then collapses it into the
// kLightBVHWidth-wide nodes of `bvh`.
struct LightBVH::Builder {
  struct BinaryNode {
    BuildBounds bounds;
    uint32_t left = 0, right = 0;  // children; a leaf's light id in `left`
    bool leaf = false;
  };
  std::vector<BuildBounds> lights;
  std::vector<vec3> centroid;  // of each light's box
  std::vector<BinaryNode> binary;
  LightBVH& bvh;

  // Builds the subtree over ids[begin, end) at binary[node]. A subtree of m
  // lights has 2m - 1 nodes, so the left child is node + 1 and the right one
  // node + 2 (mid - begin): both halves build as parallel tasks into their
  // own ranges, and the tree does not depend on the thread count.
  void build_binary(std::vector<uint32_t>& ids, size_t begin, size_t end, int depth, uint32_t node);
  void price_splits(const std::vector<uint32_t>& ids, size_t begin, size_t end, const AABB& bounds,
                    const AABB& centroids, int buckets, float cost[3], int bucket[3]) const;
  uint32_t collapse(uint32_t b, uint32_t parent, int parent_lane);
};

void LightBVH::build(const std::vector<LightBounds>& lights) {
  nodes_.clear();
  single_ = false;
  place_.assign(lights.size(), ~0u);
  std::vector<uint32_t> ids;
  for (uint32_t i = 0; i < lights.size(); ++i)
    if (lights[i].phi > 0.0f) ids.push_back(i);
  if (ids.empty()) return;
  if (ids.size() == 1) single_ = true, single_light_ = ids[0];
  Builder builder{std::vector<BuildBounds>(lights.size()), std::vector<vec3>(lights.size()), {}, *this};
  for (uint32_t i : ids) builder.lights[i] = BuildBounds(lights[i]), builder.centroid[i] = lights[i].bounds.center();
  builder.binary.resize(2 * ids.size() - 1);
  builder.build_binary(ids, 0, ids.size(), 0, 0);
  nodes_.reserve(ids.size() / 2 + 1);
  builder.collapse(0, ~0u, 0);
}

// Prices the SAOH splits of ids[begin, end) between `buckets` buckets of
// centroids along each axis: cost[k] and bucket[k] (the last bucket of the
// lower side) of the cheapest split on axis k, bucket -1 if none. pbrt-v4
// unions the buckets' bounds light by light, cones included, and prices
// each candidate with cosines of its cone's angles; with the arc sines,
// rotations and cosines that takes, 10,000 emissive triangles built in
// 40 ms. Here a cone is a mean axis (the normalised sum of the lights'
// axes) and the widest angle from it to any light's cone, in cosines:
// cos(a + theta_o) = cos a cos theta_o - sin a sin theta_o while
// a + theta_o <= pi, else the whole sphere. It holds every cone it bounds,
// and is as tight as the union for the clusters of normals emitters have.
// Two passes over the lights (sums, then angles; the three axes share each
// pass), then each run of buckets from below and from above bounds its
// buckets' cones the same way. These cones only price splits: the tree's
// own bounds are unions of its lights' (build_binary).
void LightBVH::Builder::price_splits(const std::vector<uint32_t>& ids, size_t begin, size_t end, const AABB& bounds,
                                     const AABB& centroids, int buckets, float cost[3], int bucket[3]) const {
  struct Cone {  // of a bucket or a run of buckets
    AABB box;
    vec3 sum, axis;  // sum of the lights' axes, and the unit mean axis
    float phi, cos_e, theta_e, cos_o;
  };
  auto empty = [] { return Cone{AABB(), vec3(0.0f), vec3(0.0f, 0.0f, 1.0f), 0.0f, 1.0f, 0.0f, 1.0f}; };
  auto set_axis = [](Cone& c) {
    const float len2 = glm::dot(c.sum, c.sum);
    c.axis = len2 > 0.0f ? c.sum / std::sqrt(len2) : vec3(0.0f, 0.0f, 1.0f);
  };
  // Cosine of the angle from axis to the far edge of a cone (w, cos_o, sin_o).
  auto cos_reach = [](const vec3& axis, const vec3& w, float cos_o, float sin_o) {
    const float cos_a = std::clamp(glm::dot(axis, w), -1.0f, 1.0f);
    // a + theta_o > pi: cos a < cos(pi - theta_o) = -cos theta_o.
    return cos_a < -cos_o ? -1.0f : cos_a * cos_o - safe_sqrt(1.0f - cos_a * cos_a) * sin_o;
  };
  Cone acc[3][kMaxBuckets];
  float lo[3], scale[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = centroids.lo[k];
    const float ext = centroids.hi[k] - lo[k];
    scale[k] = ext > 0.0f ? float(buckets) / ext : 0.0f;
    for (int b = 0; b < buckets; ++b) acc[k][b] = empty();
  }
  for (size_t i = begin; i < end; ++i) {
    const BuildBounds& l = lights[ids[i]];
    const vec3& c = centroid[ids[i]];
    for (int k = 0; k < 3; ++k) {
      Cone& u = acc[k][bucket_index(c[k], lo[k], scale[k], buckets)];
      u.box.grow(l.lb.bounds);
      u.phi += l.lb.phi;
      u.cos_e = std::min(u.cos_e, l.lb.cos_theta_e);
      u.theta_e = std::max(u.theta_e, l.theta_e);
      u.sum += l.lb.w;
    }
  }
  for (int k = 0; k < 3; ++k)
    for (int b = 0; b < buckets; ++b) set_axis(acc[k][b]);
  for (size_t i = begin; i < end; ++i) {
    const BuildBounds& l = lights[ids[i]];
    const vec3& c = centroid[ids[i]];
    for (int k = 0; k < 3; ++k) {
      Cone& u = acc[k][bucket_index(c[k], lo[k], scale[k], buckets)];
      u.cos_o = std::min(u.cos_o, cos_reach(u.axis, l.lb.w, l.lb.cos_theta_o, l.sin_theta_o));
    }
  }
  // Rounding may leave a cone a hair narrower than its lights': widen it by
  // a little more than that (it only prices a split).
  auto widen = [](float c) { return std::max(-1.0f, c - 1e-6f); };
  // Runs of buckets from below and from above, one bucket at a time: the
  // run's axis moves to the new sum, and its cone holds the old run's cone
  // and the new bucket's around it (cos_reach of each, so no angle is
  // taken). The SAOH cost of a run: power x orientation measure x surface
  // area, stretched along the split axis (pbrt-v4 EvaluateCost).
  const vec3 e = bounds.extent();
  auto grow = [&](Cone& r, const Cone& in) {
    if (in.phi <= 0.0f) return;
    const float in_cos = widen(in.cos_o), old_cos = r.cos_o;
    const vec3 old_axis = r.axis;
    const bool first = r.phi <= 0.0f;
    r.box.grow(in.box);
    r.phi += in.phi;
    r.cos_e = std::min(r.cos_e, in.cos_e);
    r.theta_e = std::max(r.theta_e, in.theta_e);
    r.sum += in.sum;
    set_axis(r);
    float reach = cos_reach(r.axis, in.axis, in_cos, safe_sqrt(1.0f - in_cos * in_cos));
    if (!first) reach = std::min(reach, cos_reach(r.axis, old_axis, old_cos, safe_sqrt(1.0f - old_cos * old_cos)));
    r.cos_o = widen(reach);
  };
  auto run_cost = [&](const Cone& r, int axis) {
    const float sin_o = safe_sqrt(1.0f - r.cos_o * r.cos_o);
    const float kr = max_component(e) / std::max(e[axis], 1e-30f);
    const vec3 be = r.box.extent();
    const float area = 2.0f * (be.x * be.y + be.y * be.z + be.z * be.x);
    return r.phi * m_omega(r.cos_o, sin_o, r.cos_e, r.theta_e) * kr * area;
  };
  for (int k = 0; k < 3; ++k) {
    cost[k] = kInf, bucket[k] = -1;
    if (!(scale[k] > 0.0f)) continue;
    float above_cost[kMaxBuckets];
    Cone above = empty();
    for (int b = buckets - 1; b > 0; --b) {
      grow(above, acc[k][b]);
      above_cost[b] = above.phi > 0.0f ? run_cost(above, k) : -1.0f;
    }
    Cone below = empty();
    for (int b = 0; b < buckets - 1; ++b) {
      grow(below, acc[k][b]);
      if (below.phi <= 0.0f || above_cost[b + 1] < 0.0f) continue;
      const float c = run_cost(below, k) + above_cost[b + 1];
      if (c < cost[k]) cost[k] = c, bucket[k] = b;
    }
  }
}

void LightBVH::Builder::build_binary(std::vector<uint32_t>& ids, size_t begin, size_t end, int depth, uint32_t node) {
  if (end - begin == 1) {
    binary[node].bounds = lights[ids[begin]];
    binary[node].leaf = true;
    binary[node].left = ids[begin];
    return;
  }
  // Large ranges: the two halves build as parallel tasks.
  constexpr size_t kParallelLights = 1024;
  const bool parallel = end - begin >= kParallelLights;
  auto centre = [&](uint32_t id) { return centroid[id]; };
  AABB bounds, centroids;
  for (size_t i = begin; i < end; ++i) {
    bounds.grow(lights[ids[i]].lb.bounds);
    centroids.grow(centre(ids[i]));
  }
  // Split by the SAOH over 12 buckets per axis (pbrt-v4 BVHLightSampler::
  // buildBVH); by count at the middle of the widest axis when the centroids
  // coincide or the tree gets deep.
  size_t mid = begin + (end - begin) / 2;
  const int widest = max_dimension(centroids.extent());
  bool split = false;
  if (end - begin == 2) {
    split = true;  // one light each side, whatever the costs
  } else if (depth < kMaxDepth && max_component(centroids.extent()) > 0.0f) {
    // No more buckets than lights: most nodes hold a few lights, and sweeping
    // 12 mostly empty buckets on each axis was most of the build.
    const int buckets = int(std::min<size_t>(kMaxBuckets, end - begin));
    float axis_cost[3];
    int axis_bucket[3];
    price_splits(ids, begin, end, bounds, centroids, buckets, axis_cost, axis_bucket);
    // The first axis with the lowest cost, as a serial sweep over the axes picks.
    int best_axis = -1;
    for (int axis = 0; axis < 3; ++axis)
      if (axis_bucket[axis] >= 0 && (best_axis < 0 || axis_cost[axis] < axis_cost[best_axis])) best_axis = axis;
    if (best_axis >= 0) {
      const int best_bucket = axis_bucket[best_axis];
      const float lo = centroids.lo[best_axis], ext = centroids.hi[best_axis] - lo;
      auto it = std::partition(ids.begin() + begin, ids.begin() + end, [&](uint32_t id) {
        return bucket_index(centre(id)[best_axis], lo, float(buckets) / ext, buckets) <= best_bucket;
      });
      mid = size_t(it - ids.begin());
      split = mid > begin && mid < end;
    }
  }
  if (!split) {
    mid = begin + (end - begin) / 2;
    std::nth_element(ids.begin() + begin, ids.begin() + mid, ids.begin() + end, [&](uint32_t a, uint32_t b) {
      return centre(a)[widest] < centre(b)[widest];
    });
  }
  const uint32_t left = node + 1, right = node + uint32_t(2 * (mid - begin));
  if (parallel)
    tbb::parallel_invoke([&] { build_binary(ids, begin, mid, depth + 1, left); },
                         [&] { build_binary(ids, mid, end, depth + 1, right); });
  else
    build_binary(ids, begin, mid, depth + 1, left), build_binary(ids, mid, end, depth + 1, right);
  binary[node].left = left, binary[node].right = right;
  binary[node].bounds = union_bounds(binary[left].bounds, binary[right].bounds);
}

// One wide node from binary node b: its two children, then the interior
// child with the largest box opened in its place while there is room
// (the usual BVH2 -> BVH8 collapse). A lone light makes a root of one lane.
// Eight lanes rather than four: log8 instead of log4 levels to walk per
// sample (10,000 emitters: 4.4 instead of 6.6), each weighed in one AVX2 pass.
uint32_t LightBVH::Builder::collapse(uint32_t b, uint32_t parent, int parent_lane) {
  std::vector<Node>& nodes = bvh.nodes_;
  const uint32_t node = uint32_t(nodes.size());
  nodes.emplace_back();
  nodes[node].parent = parent;
  nodes[node].parent_lane = uint8_t(parent_lane);
  uint32_t lanes[kLightBVHWidth] = {b};
  int count = 1;
  if (!binary[b].leaf) lanes[0] = binary[b].left, lanes[1] = binary[b].right, count = 2;
  while (count < kLightBVHWidth) {
    int open = -1;
    float best = -1.0f;
    for (int k = 0; k < count; ++k) {
      const BinaryNode& c = binary[lanes[k]];
      if (!c.leaf && c.bounds.lb.bounds.half_area() > best) best = c.bounds.lb.bounds.half_area(), open = k;
    }
    if (open < 0) break;
    const BinaryNode& c = binary[lanes[open]];
    lanes[open] = c.left;
    lanes[count++] = c.right;
  }
  for (int k = 0; k < count; ++k) {
    const BinaryNode& c = binary[lanes[k]];
    nodes[node].ib.set(k, ImportanceBounds(c.bounds.lb));
    if (c.leaf) {
      nodes[node].child[k] = c.left;
      nodes[node].leaf_mask |= uint8_t(1u << k);
      bvh.place_[c.left] = node * kLightBVHWidth + uint32_t(k);
    } else {
      const uint32_t child = collapse(lanes[k], node, k);
      nodes[node].child[k] = child;
    }
  }
  return node;
}

// The sum of a node's lane importances, pairwise (the same in sample and pmf).
static float lane_sum(const float imp[kLightBVHWidth]) {
  return ((imp[0] + imp[1]) + (imp[2] + imp[3])) + ((imp[4] + imp[5]) + (imp[6] + imp[7]));
}

bool LightBVH::sample(const vec3& p, const vec3& n, float u, uint32_t* light, float* pmf, float* u_remapped) const {
  if (nodes_.empty()) return false;
  if (single_) {
    *light = single_light_;
    *pmf = 1.0f;
    if (u_remapped) *u_remapped = u;
    return true;
  }
  uint32_t node = 0;
  float prob = 1.0f;
  for (;;) {
    const Node& nd = nodes_[node];
    alignas(32) float imp[kLightBVHWidth];
    nd.ib.importance(p, n, imp);
    const float sum = lane_sum(imp);
    if (!(sum > 0.0f)) return false;
    // The lane whose share of [0, sum) holds u * sum; u is rescaled to [0,1)
    // within it for the next level (pbrt-v4 SampleDiscrete). Without
    // branches on the data: k counts the running sums x has passed (a lane
    // without importance repeats the sum before it, so it is passed with
    // it); only x rounded up to the top can land on an empty lane.
    const float x = u * sum;
    float c[kLightBVHWidth - 1];
    c[0] = imp[0];
    for (int j = 1; j < kLightBVHWidth - 1; ++j) c[j] = c[j - 1] + imp[j];
    int k = 0;
    for (int j = 0; j < kLightBVHWidth - 1; ++j) k += int(x >= c[j]);
    while (imp[k] <= 0.0f) --k;
    const float below = k == 0 ? 0.0f : c[k - 1];
    prob *= imp[k] / sum;
    u = std::clamp((x - below) / imp[k], 0.0f, 0x1.fffffep-1f);
    if (nd.leaf_mask & (1u << k)) {
      *light = nd.child[k];
      break;
    }
    node = nd.child[k];
  }
  *pmf = prob;
  if (u_remapped) *u_remapped = u;
  return prob > 0.0f;
}

float LightBVH::pmf(const vec3& p, const vec3& n, uint32_t light) const {
  if (light >= place_.size() || place_[light] == ~0u) return 0.0f;
  if (single_) return 1.0f;
  uint32_t node = place_[light] / kLightBVHWidth, lane = place_[light] % kLightBVHWidth;
  float prob = 1.0f;
  for (;;) {
    alignas(32) float imp[kLightBVHWidth];
    nodes_[node].ib.importance(p, n, imp);
    if (!(imp[lane] > 0.0f)) return 0.0f;
    prob *= imp[lane] / lane_sum(imp);
    if (node == 0) return prob;
    lane = nodes_[node].parent_lane;
    node = nodes_[node].parent;
  }
}

}  // namespace tessera
