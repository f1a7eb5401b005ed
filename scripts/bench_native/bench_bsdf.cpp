// BSDF cost per path vertex, one thread, as the integrator spends it: the
// constructor, one eval (f and pdf for next-event estimation) and one
// sample_f, for 400,000 random (wo, wi, u) on one material; the fastest of
// 9 passes, in ns per vertex. Materials: 0, Principled (Cycles 3.x: Burley
// diffuse + GGX specular, roughness 0.5); 1, Principled 4.x (Multiscatter
// GGX); 2, Glass (Cycles 3.x, roughness 0.3). Usage: bench_bsdf MATERIAL.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "core/bsdf.h"

using namespace tessera;

int main(int argc, char** argv) {
  const int which = argc > 1 ? std::atoi(argv[1]) : 0;
  Closure c;
  c.color = vec3(0.8f, 0.5f, 0.3f);
  if (which == 1) {
    c.model = ShadingModel::Cycles4_3;
    c.multiscatter = true;
  } else if (which == 2) {
    c.kind = ClosureKind::Glass;
    c.roughness = 0.3f;
  }
  Material m;
  m.set_first_closure(c);

  struct Vertex { vec3 wo, wi; float u_lobe; vec2 u; };
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  std::vector<Vertex> vs(400000);
  for (Vertex& v : vs) {
    v.wo = sample_cosine_hemisphere(vec2(U(rng), U(rng)));
    v.wi = sample_uniform_sphere(vec2(U(rng), U(rng)));
    v.u_lobe = U(rng);
    v.u = vec2(U(rng), U(rng));
  }
  const vec3 n(0, 0, 1);
  double best = 1e30, checksum = 0.0;
  for (int pass = 0; pass < 9; ++pass) {
    const auto t0 = std::chrono::steady_clock::now();
    double sum = 0.0;
    for (const Vertex& v : vs) {
      const BSDF bsdf(n, n, m, false, v.wo);
      float pdf;
      const vec3 f = bsdf.eval(v.wi, &pdf);
      BSDFSample s;
      sum += f.x + pdf;
      if (bsdf.sample_f(v.u_lobe, v.u, s)) sum += s.f.y + s.pdf;
    }
    const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
    best = std::min(best, ns / double(vs.size()));
    checksum = sum;
  }
  std::printf("material %d: %.1f ns per vertex (checksum %.6g)\n", which, best, checksum);
  return 0;
}
