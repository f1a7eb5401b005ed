// Light BVH: picks one of many bounded emitters with a probability that
// follows its estimated contribution at the shading point (Conty Estevez and
// Kulla 2018, "Importance Sampling of Many Lights with Adaptive Tree
// Splitting"; pbrt-v4 BVHLightSampler). Each node bounds its emitters'
// positions (box), emission directions (a cone of normals, theta_o, widened
// by the emission spread theta_e) and total power; a traversal from the root
// chooses a child by the importance of its bounds at the point, so lights
// that are far, behind the point or facing away from it are rarely or never
// picked. pmf() multiplies the same choices' probabilities from the light up
// to the root, for MIS.
#pragma once
#include <cstdint>
#include <vector>
#include "aabb.h"

namespace tessera {

// What a node knows about the emitters below it.
struct LightBounds {
  AABB bounds;
  vec3 w{0.0f, 0.0f, 1.0f};  // axis of the cone of emission normals
  float phi = 0.0f;          // power (any common unit: only ratios matter)
  float cos_theta_o = 1.0f;  // the normals lie within theta_o of w
  float cos_theta_e = 0.0f;  // each point emits up to theta_e off its normal
  bool two_sided = false;    // emits on both sides of its normals
};

// What importance() needs of a LightBounds, precomputed once per node: the
// box's centre and bounding sphere, the cone's sine. Light sampling
// evaluates two of these per tree level, for every sample and for every MIS
// density (pmf): in a scene of 10,000 emissive triangles they were a third of
// the render's time.
struct ImportanceBounds {
  vec3 centre{0.0f};
  float phi = 0.0f;
  vec3 w{0.0f, 0.0f, 1.0f};
  float cos_theta_o = 1.0f, sin_theta_o = 0.0f, cos_theta_e = 0.0f;
  float radius = 0.0f;         // radius of the box's bounding sphere
  // 1 / the least squared distance: pbrt-v4 clamps d^2 to half the box's
  // diagonal, i.e. to the radius (a length, as pbrt-v4 has it)
  float inv_min_dist2 = kInf;
  bool two_sided = false;

  ImportanceBounds() = default;
  explicit ImportanceBounds(const LightBounds& lb);
  // Conservative estimate of the lights' contribution at p, for a receiver
  // with normal n (0: any direction): power times the largest cosines the
  // bounds allow at the emitter and the receiver, over the squared distance
  // (pbrt-v4 LightBounds::Importance). 0 only where they cannot contribute.
  float importance(const vec3& p, const vec3& n) const;
};

// The bounds of a light BVH node's children, one SIMD lane each (structure
// of arrays), so that they are weighed in one pass. Lanes without a child
// have phi 0 and importance 0.
constexpr int kLightBVHWidth = 8;
struct alignas(32) ImportanceBounds8 {
  float cx[8] = {}, cy[8] = {}, cz[8] = {}, wx[8] = {}, wy[8] = {}, wz[8] = {};
  float phi[8] = {}, cos_o[8] = {}, sin_o[8] = {}, cos_e[8] = {}, radius[8] = {}, inv_min_dist2[8] = {};
  uint32_t two_sided[8] = {};  // ~0u in a two-sided lane

  void set(int lane, const ImportanceBounds& b);
  // ImportanceBounds::importance of the eight lanes, evaluated together:
  // one AVX2 pass where the CPU has AVX2 (chosen at run time), else two
  // SSE2 passes of four lanes. Both give the scalar function's values.
  void importance(const vec3& p, const vec3& n, float out[8]) const;
  void importance_sse2(const vec3& p, const vec3& n, float out[8]) const;
  void importance_avx2(const vec3& p, const vec3& n, float out[8]) const;  // only on AVX2 CPUs
};

class LightBVH {
 public:
  // One bounds per light; ids are the lights' indices into `lights`. Lights
  // with zero power are left out (never sampled, pmf 0).
  void build(const std::vector<LightBounds>& lights);
  bool empty() const { return nodes_.empty(); }

  // Picks a light for point p with normal n from u in [0,1); false when no
  // light can contribute there (a tree of one light always picks it).
  // u_remapped (if given): u rescaled to [0,1) again within the choices made.
  bool sample(const vec3& p, const vec3& n, float u, uint32_t* light, float* pmf, float* u_remapped = nullptr) const;
  // Probability with which sample() picks `light` at (p, n).
  float pmf(const vec3& p, const vec3& n, uint32_t light) const;
  size_t node_count() const { return nodes_.size(); }

 private:
  struct Node {
    ImportanceBounds8 ib;
    uint32_t child[kLightBVHWidth] = {};  // a light id in leaf lanes, else a node index
    uint32_t parent = ~0u;     // the root has none
    uint8_t parent_lane = 0;   // this node's lane in its parent
    uint8_t leaf_mask = 0;     // bit k: lane k is a light
  };
  struct Builder;  // the binary SAOH tree and its collapse (light_bvh.cpp)
  std::vector<Node> nodes_;
  // A tree of one light (a scene's one lamp or quad light) is picked with
  // probability 1 wherever it is, without weighing the root's eight lanes (a
  // third of a light sample's instructions). Where its importance would be 0
  // it cannot contribute: its sample then carries no light (the light
  // rejects it: behind a one-sided emitter), and a BSDF-sampled ray that
  // hits it there finds no emission to weigh.
  bool single_ = false;
  uint32_t single_light_ = 0;
  // Per light: node * kLightBVHWidth + lane where it sits; ~0 for lights not in the tree.
  std::vector<uint32_t> place_;
};

}  // namespace tessera
