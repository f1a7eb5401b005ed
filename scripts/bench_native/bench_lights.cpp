// Light sampling cost per shading point, one thread: LightSampler::sample()
// and one pdf_triangle() (the MIS density a BSDF-sampled hit asks for) from
// random points and normals, the fastest of 9 passes over 400,000 points.
// Scenes shaped like the shared ones: 0, 10,000 emissive triangles on five
// spheres (veach_mis); 1, one quad light 1 cm under the ceiling of a 2 m box
// (cornell_mcguire); 2, twelve 2 x 1 m wall panels in a 10 x 4 x 10 m hall,
// points near them (modern_hall). Usage: bench_lights SCENE (0, 1 or 2).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "core/lights.h"

using namespace tessera;

namespace {

EmissiveTriangle emissive(const vec3& p0, const vec3& p1, const vec3& p2, uint32_t prim) {
  EmissiveTriangle t;
  t.p0 = p0, t.e1 = p1 - p0, t.e2 = p2 - p0;
  const vec3 c = glm::cross(t.e1, t.e2);
  t.area = 0.5f * glm::length(c);
  t.n = glm::normalize(c);
  t.le_front = vec3(1.0f), t.le_back = vec3(0.0f);
  t.instance = 0, t.prim = prim;
  return t;
}

void add_quad(std::vector<EmissiveTriangle>& out, const vec3& o, const vec3& u, const vec3& v) {
  const uint32_t k = uint32_t(out.size());
  out.push_back(emissive(o, o + u, o + u + v, k));
  out.push_back(emissive(o, o + u + v, o + v, k + 1));
}

// The emitters of scene `which` and the box the shading points are drawn from.
std::vector<EmissiveTriangle> scene(int which, vec3* lo, vec3* hi) {
  std::vector<EmissiveTriangle> tris;
  if (which == 0) {
    for (int s = 0; s < 5; ++s) {
      const vec3 c(-2.0f + s, 1.0f, 0.0f);
      const float r = 0.01f * float(1 << s);
      auto at = [&](int i, int j) {
        const float theta = kPi * float(j) / 25.0f, phi = 2.0f * kPi * float(i) / 40.0f;
        return c + r * vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      };
      for (int i = 0; i < 40; ++i)
        for (int j = 0; j < 25; ++j) {
          const uint32_t k = uint32_t(tris.size());
          tris.push_back(emissive(at(i, j), at(i + 1, j), at(i + 1, j + 1), k));
          tris.push_back(emissive(at(i, j), at(i + 1, j + 1), at(i, j + 1), k + 1));
        }
    }
    *lo = vec3(-3.0f, -1.0f, -1.0f), *hi = vec3(3.0f, 0.5f, 1.0f);
  } else if (which == 1) {
    add_quad(tris, vec3(-0.25f, 1.99f, -0.25f), vec3(0.0f, 0.0f, 0.5f), vec3(0.5f, 0.0f, 0.0f));
    *lo = vec3(-1.0f, 0.0f, -1.0f), *hi = vec3(1.0f, 2.0f, 1.0f);
  } else {
    for (int i = 0; i < 6; ++i) {
      add_quad(tris, vec3(-5.0f, 1.0f, -4.5f + 1.5f * i), vec3(0.0f, 2.0f, 0.0f), vec3(0.0f, 0.0f, 1.0f));
      add_quad(tris, vec3(5.0f, 1.0f, -4.5f + 1.5f * i), vec3(0.0f, 0.0f, 1.0f), vec3(0.0f, 2.0f, 0.0f));
    }
    *lo = vec3(-5.0f, 0.0f, -5.0f), *hi = vec3(5.0f, 4.0f, 5.0f);
  }
  return tris;
}

}  // namespace

int main(int argc, char** argv) {
  const int which = argc > 1 ? std::atoi(argv[1]) : 0;
  vec3 lo, hi;
  const std::vector<EmissiveTriangle> tris = scene(which, &lo, &hi);
  LightSampler lights;
  lights.build({}, tris, nullptr, 10.0f);
  constexpr int kPoints = 400000;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  std::vector<vec3> p(kPoints), n(kPoints);
  std::vector<vec2> u(kPoints);
  for (int i = 0; i < kPoints; ++i) {
    p[i] = lo + (hi - lo) * vec3(U(rng), U(rng), U(rng));
    n[i] = glm::normalize(vec3(U(rng) - 0.5f, U(rng) - 0.5f, U(rng) - 0.5f));
    u[i] = vec2(U(rng), U(rng));
  }
  double best = 1e30, checksum = 0.0;
  for (int pass = 0; pass < 9; ++pass) {
    const auto t0 = std::chrono::steady_clock::now();
    double sum = 0.0;
    for (int i = 0; i < kPoints; ++i) {
      LightSample s;
      if (!lights.sample(p[i], n[i], u[i], s)) continue;
      sum += s.pdf + lights.pdf_triangle(p[i], n[i], 0, uint32_t(i % tris.size()), s.dist, 0.5f);
    }
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    checksum = sum;
  }
  std::printf("scene %d: %.1f ns per sample + pdf (fastest of 9 passes), checksum %.6g\n", which, best / kPoints * 1e9,
              checksum);
}
