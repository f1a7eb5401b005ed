// Rays leaving a surface never re-hit it, whatever the scale or position.
#include <gtest/gtest.h>

#include <random>

#include "core/scene.h"
#include "scene_fixtures.h"

using namespace tessera;

namespace {
// A flat quad z = 0 of half-size `size`, centred at `center`.
Scene floor_scene(float size, vec3 center = vec3(0.0f)) {
  Scene s;
  fixtures::add_quad(s, center + vec3(-size, -size, 0), center + vec3(size, -size, 0),
                     center + vec3(size, size, 0), center + vec3(-size, size, 0), 0);
  s.commit();
  return s;
}

// Fraction of shadow rays from random floor points towards a point above
// the floor that are (wrongly) blocked by the floor itself.
double self_occlusion(const Scene& s, float size, vec3 center, vec3 light) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.9f, 0.9f);
  int blocked = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    Ray cam{center + vec3(u(rng) * size, u(rng) * size, 3.0f * size), vec3(0, 0, -1), kInf};
    cam.d = glm::normalize(vec3(u(rng) * 0.1f, u(rng) * 0.1f, -1.0f));
    Hit h;
    if (!s.intersect(cam, h)) continue;
    SurfaceInteraction si = s.interaction(cam, h);
    vec3 d = light - si.p;
    float dist = glm::length(d);
    d /= dist;
    vec3 o = offset_ray_origin(si.p, si.p_error, si.ng, d);
    if (s.occluded(o, d, dist * (1.0f - 1e-4f))) ++blocked;
  }
  return double(blocked) / n;
}
}  // namespace

// Regression: an exactly planar floor has zero position error across its
// plane, so the ray origin is not moved; the triangle test must then reject
// the rounding-error hit at t ~ 1e-7 (it did not, and half a floor lit by a
// point light came out dark).
TEST(Robustness, ShadowRaysDoNotHitTheFloorTheyLeave) {
  for (float size : {1e-3f, 1.0f, 10.0f, 1e3f}) {
    Scene s = floor_scene(size);
    EXPECT_EQ(self_occlusion(s, size, vec3(0.0f), vec3(0.07f, -0.04f, 0.2f) * size), 0.0) << "size " << size;
    // Grazing: the light barely above the floor, far away.
    EXPECT_EQ(self_occlusion(s, size, vec3(0.0f), vec3(5.0f, 0.0f, 0.05f) * size), 0.0) << "size " << size;
  }
}

TEST(Robustness, FarFromTheOrigin) {
  for (float offset : {1e3f, 1e5f}) {
    const vec3 c(offset, -offset, 0.5f * offset);
    Scene s = floor_scene(2.0f, c);
    EXPECT_EQ(self_occlusion(s, 2.0f, c, c + vec3(0.3f, 0.2f, 1.0f)), 0.0) << "offset " << offset;
  }
}

// Regression (found by the fuzzer, tests/fuzz/crashes): an instance whose
// finite transform has a non-finite inverse made the local ray NaN and the
// AVX2 traversal read out of bounds; NaN rays did the same.
TEST(Robustness, NonFiniteRaysAndInverseTransformsHitNothing) {
  Scene s;
  fixtures::add_quad(s, vec3(-1, -1, 0), vec3(1, -1, 0), vec3(1, 1, 0), vec3(-1, 1, 0), 0);
  mat4 degenerate(1.0f);
  degenerate[0][0] = 1e-30f;  // finite, its inverse overflows
  degenerate[1][1] = 1e38f;
  s.add_instance(0, degenerate, {0});
  s.commit();
  Hit h;
  const float nan = std::nanf("");
  for (const Ray& r : {Ray{vec3(0.1f, 0.2f, 5.0f), vec3(0, 0, -1), kInf}, Ray{vec3(nan, 0, 5), vec3(0, 0, -1), kInf},
                       Ray{vec3(0, 0, 5), vec3(nan, 0, -1), kInf}, Ray{vec3(0, 0, kInf), vec3(0, 0, -1), kInf}}) {
    bool hit = s.intersect(r, h);
    if (hit) {
      EXPECT_TRUE(std::isfinite(h.t));
      EXPECT_EQ(h.instance, 0u);  // only the well-formed quad can be hit
    }
    s.occluded(r.o, r.d, 10.0f);
  }
  EXPECT_FALSE(s.intersect(Ray{vec3(nan, 0, 5), vec3(0, 0, -1), kInf}, h));
}
