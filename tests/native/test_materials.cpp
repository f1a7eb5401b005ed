// Closure-list materials (material.h, bsdf.cpp): Diffuse, Glossy, Glass,
// Transparent and Principled closures summed with Mix/Add Shader weights;
// Principled Alpha and transparent paths and shadows (integrator.cpp); depth
// of field (camera.h).
#include <gtest/gtest.h>

#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <random>

#include "core/bsdf.h"
#include "core/ggx_energy.h"
#include "core/integrator.h"
#include "core/render.h"
#include "scene_fixtures.h"

using namespace tessera;

namespace {

Closure closure(ClosureKind kind, float weight, vec3 color, float roughness = 0.5f, float ior = 1.45f) {
  Closure c;
  c.kind = kind;
  c.weight = weight;
  c.color = color;
  c.roughness = roughness;
  c.ior = ior;
  return c;
}

// A material whose closures are the given ones (closure 0 in the fields).
Material with_closures(std::initializer_list<Closure> cs) {
  Material m;
  bool first = true;
  for (const Closure& c : cs) {
    if (first) {
      m.set_first_closure(c);
      first = false;
    } else {
      EXPECT_TRUE(m.add_closure(c));
    }
  }
  return m;
}

vec3 random_dir(std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  return sample_uniform_sphere(vec2(u(rng), u(rng)));
}

// Directional albedo rho(wo) = integral of f |cos| over the sphere, two ways:
// by sampling the BSDF (delta lobes included) and by quadrature over a fine
// equal-area grid (smooth lobes only; midpoints of 1000 x 2000 cells in
// (z, phi)). They agree only if sample_f draws directions with the density
// pdf() reports. Also the integral of pdf over the sphere.
struct Albedo {
  double sampled = 0, uniform = 0, pdf_integral = 0, delta = 0;
};
Albedo albedo(const Material& m, const vec3& wo, int n = 400000, bool back_face = false) {
  const vec3 normal(0, 0, 1);
  const BSDF bsdf(normal, normal, m, back_face, wo);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Albedo a;
  for (int i = 0; i < n; ++i) {
    BSDFSample s;
    if (!bsdf.sample_f(u(rng), vec2(u(rng), u(rng)), s)) continue;
    const double w = double(luminance(s.f)) * std::abs(s.wi.z) / s.pdf;
    a.sampled += w;
    if (s.delta) {
      a.delta += w;
    } else {
      // What sample_f returned is what f and pdf say for that direction.
      EXPECT_EQ(s.f, bsdf.f(s.wi));
      EXPECT_EQ(s.pdf, bsdf.pdf(s.wi));
    }
  }
  a.sampled /= n, a.delta /= n;
  const int nz = 1000, nphi = 2000;
  for (int iz = 0; iz < nz; ++iz) {
    for (int ip = 0; ip < nphi; ++ip) {
      const vec3 wi = sample_uniform_sphere(vec2((iz + 0.5f) / nz, (ip + 0.5f) / nphi));
      a.uniform += double(luminance(bsdf.f(wi))) * std::abs(wi.z) / kUniformSpherePdf;
      a.pdf_integral += bsdf.pdf(wi) / kUniformSpherePdf;
    }
  }
  a.uniform /= double(nz) * nphi, a.pdf_integral /= double(nz) * nphi;
  return a;
}

const vec3 kWo = glm::normalize(vec3(0.3f, -0.2f, 0.8f));

}  // namespace

// ------------------------------------------------------------------ BSDF

// Energy, and sampling consistent with f and pdf, for each closure kind and
// for mixes: white closures reflect at most what arrives (Lambert, smooth
// glass and transparency exactly all of it); the BSDF-sampled estimate of the
// albedo equals the uniform one; the pdf integrates to at most 1.
TEST(Materials, ClosuresConserveEnergyAndSampleWhatPdfSays) {
  struct Case { const char* name; Material m; double lo, hi; bool smooth; };
  const vec3 white(1.0f);
  const Case cases[] = {
      {"diffuse (Lambert)", with_closures({closure(ClosureKind::Diffuse, 1, white, 0.0f)}), 0.99, 1.01, true},
      {"diffuse (Oren-Nayar r=1)", with_closures({closure(ClosureKind::Diffuse, 1, white, 1.0f)}), 0.70, 1.01, true},
      {"glossy r=0.2", with_closures({closure(ClosureKind::Glossy, 1, white, 0.2f)}), 0.90, 1.01, true},
      {"glossy r=0.6", with_closures({closure(ClosureKind::Glossy, 1, white, 0.6f)}), 0.60, 1.01, true},
      {"glossy r=1", with_closures({closure(ClosureKind::Glossy, 1, white, 1.0f)}), 0.25, 1.01, true},
      {"glossy r=0 (mirror)", with_closures({closure(ClosureKind::Glossy, 1, white, 0.0f)}), 0.999, 1.001, false},
      {"glass r=0 ior 1.5", with_closures({closure(ClosureKind::Glass, 1, white, 0.0f, 1.5f)}), 0.999, 1.001, false},
      {"glass r=0.4 ior 1.5", with_closures({closure(ClosureKind::Glass, 1, white, 0.4f, 1.5f)}), 0.80, 1.01, true},
      {"transparent", with_closures({closure(ClosureKind::Transparent, 1, white)}), 0.999, 1.001, false},
      {"mix diffuse 0.7 + glossy 0.3",
       with_closures({closure(ClosureKind::Diffuse, 0.7f, white, 0.0f), closure(ClosureKind::Glossy, 0.3f, white, 0.3f)}),
       0.95, 1.01, true},
      {"mix diffuse 0.5 + transparent 0.5",
       with_closures({closure(ClosureKind::Diffuse, 0.5f, white, 0.0f), closure(ClosureKind::Transparent, 0.5f, white)}),
       0.99, 1.01, false},
      {"principled + glass + glossy (1/3 each)",
       with_closures({closure(ClosureKind::Principled, 1 / 3.0f, white, 0.3f),
                      closure(ClosureKind::Glass, 1 / 3.0f, white, 0.3f, 1.33f),
                      closure(ClosureKind::Glossy, 1 / 3.0f, white, 0.7f)}),
       0.5, 1.05, true},
  };
  for (const Case& c : cases) {
    const Albedo a = albedo(c.m, kWo);
    std::printf("%-40s albedo sampled %.4f uniform %.4f (delta %.4f), pdf integral %.4f\n", c.name, a.sampled,
                a.uniform, a.delta, a.pdf_integral);
    EXPECT_GE(a.sampled, c.lo) << c.name;
    EXPECT_LE(a.sampled, c.hi) << c.name;
    EXPECT_LE(a.pdf_integral, 1.01) << c.name;
    // Smooth lobes: both estimates of the same integral agree (the uniform
    // one sees no delta lobe, so compare it with the sampled smooth part).
    EXPECT_NEAR(a.sampled - a.delta, a.uniform, 0.01) << c.name;
    if (c.smooth) EXPECT_GT(a.uniform, 0.3) << c.name;
  }
}

// ------------------------------------------------------------------ Cycles 4.x closures

namespace {

// A closure as Blender 4.x sets it up (Cycles4_3: Blender 4.3 on).
Closure closure4(ClosureKind kind, vec3 color, float roughness, bool multiscatter, float ior = 1.5f) {
  Closure c = closure(kind, 1.0f, color, roughness, ior);
  c.model = ShadingModel::Cycles4_3;
  c.multiscatter = multiscatter;
  return c;
}

vec3 view_at(float mu) { return vec3(std::sqrt(1.0f - mu * mu), 0.0f, mu); }

}  // namespace

// The energy tables against a direct quadrature of the single-scattering GGX
// lobe with height-correlated masking (no visible-normal sampling involved):
// E at grid points, E_avg as the cosine-weighted mean of E, and the glass
// table (reflection F + refraction 1 - F) entering and leaving the medium.
TEST(GGXEnergy, TablesMatchDirectIntegration) {
  auto quadrature = [](float roughness, float mu, float eta, bool glass) {
    const GGX ggx{roughness * roughness};
    const vec3 wo = view_at(mu);
    const int nz = 1000, nphi = 1000;
    double sum = 0.0;
    for (int iz = 0; iz < nz; ++iz)
      for (int ip = 0; ip < nphi; ++ip) {
        const vec3 wi = sample_uniform_sphere(vec2((iz + 0.5f) / nz, (ip + 0.5f) / nphi));
        float f = 0.0f;
        if (wi.z > 0.0f) {
          const vec3 wm = glm::normalize(wi + wo);
          const float F = glass ? fresnel_dielectric(glm::dot(wo, wm), eta) : 1.0f;
          f = F * ggx.D(wm) * ggx.G_correlated(wo, wi) / (4.0f * wi.z * wo.z);
        } else if (glass && wi.z < 0.0f) {
          vec3 wm = glm::normalize(wi * eta + wo);
          if (wm.z < 0.0f) wm = -wm;
          const float di = glm::dot(wi, wm), d_o = glm::dot(wo, wm);
          if (di < 0.0f && d_o > 0.0f)
            f = (1.0f - fresnel_dielectric(d_o, eta)) * ggx.D(wm) * ggx.G_correlated(wo, wi) *
                std::abs(di * d_o / (wi.z * wo.z * sqr(di + d_o / eta)));
        }
        sum += double(f) * std::abs(wi.z) / kUniformSpherePdf;
      }
    return sum / (double(nz) * nphi);
  };
  // (The quadrature resolves lobes of roughness 0.5 and up; narrower ones are
  // checked through the BSDF's sampled albedo below.)
  for (int x : {16, 24, 31})
    for (int y : {6, 16, 28}) {
      const float r = x / 31.0f, mu = y / 31.0f;
      const double direct = quadrature(r, mu, 1.0f, false);
      EXPECT_NEAR(ggx_energy::E(r, mu), direct, 4e-3) << "r " << r << " mu " << mu;
    }
  for (float r : {10 / 31.0f, 1.0f}) {
    double avg = 0.0;
    for (int k = 0; k < 64; ++k) avg += 2.0 * ((k + 0.5) / 64) * ggx_energy::E(r, (k + 0.5f) / 64) / 64;
    EXPECT_NEAR(ggx_energy::E_avg(r), avg, 4e-3) << r;
  }
  // Glass grid points: roughness 8/15, 1; mu 8/15, 13/15; z = 9/15 (IOR 1.39).
  const float z = 9.0f / 15.0f, ior = ggx_energy::ior_from_F0(z * z * z * z);
  for (float r : {8 / 15.0f, 1.0f})
    for (float mu : {8 / 15.0f, 13 / 15.0f})
      for (float eta : {ior, 1.0f / ior}) {
        const double direct = quadrature(r, mu, eta, true);
        EXPECT_NEAR(ggx_energy::glass_E(r, mu, eta), direct, 6e-3) << "r " << r << " mu " << mu << " eta " << eta;
      }
  // Smooth surfaces lose nothing; rough ones up to a third at grazing views.
  EXPECT_NEAR(ggx_energy::E(0.0f, 0.5f), 1.0f, 1e-3);
  EXPECT_LT(ggx_energy::E(1.0f, 0.2f), 0.7f);
}

// eval returns f and pdf from one pass over the lobes, with Smith's Lambda(wo)
// and the specular F0 computed by the constructor. Pinned to the values of
// the separate f and pdf passes it replaced (commit ac193dd) for every
// closure type and shading model, front and back faces, directions of
// reflection, grazing reflection and transmission: the same BSDF to float
// rounding.
TEST(Materials, EvalKeepsTheValuesOfTheSeparatePasses) {
  struct Case { Closure c; bool back_face; };
  std::vector<Case> cases;
  Closure c = closure(ClosureKind::Principled, 1.0f, vec3(0.8f, 0.5f, 0.3f));
  cases.push_back({c, false});  // 0: Principled v1, diffuse + specular
  {
    Closure d = c;
    d.metallic = 0.6f, d.roughness = 0.2f;
    cases.push_back({d, false});  // 1
    d = c;
    d.transmission = 1.0f, d.roughness = 0.3f;
    cases.push_back({d, false}), cases.push_back({d, true});  // 2, 3: Principled glass
  }
  {
    Closure d = closure(ClosureKind::Diffuse, 1.0f, c.color, 0.0f);
    cases.push_back({d, false});  // 4: Lambert
    d.roughness = 0.7f;
    cases.push_back({d, false});  // 5: Oren-Nayar
  }
  cases.push_back({closure(ClosureKind::Glossy, 1.0f, c.color, 0.4f), false});  // 6
  cases.push_back({closure(ClosureKind::Glass, 1.0f, c.color, 0.3f), false});   // 7
  cases.push_back({closure(ClosureKind::Glass, 1.0f, c.color, 0.3f), true});    // 8
  {
    Closure d = c;  // Principled v2: coat, metal, specular, diffuse; then glass
    d.model = ShadingModel::Cycles4_3, d.multiscatter = true;
    d.metallic = 0.5f, d.coat = 0.5f, d.diffuse_roughness = 0.6f;
    cases.push_back({d, false});  // 9
    d.metallic = 0.0f, d.transmission = 0.5f;
    cases.push_back({d, false}), cases.push_back({d, true});  // 10, 11
  }
  auto v4 = [&](ClosureKind kind, float roughness, bool back_face) {
    Closure d = closure(kind, 1.0f, c.color, roughness);
    d.model = ShadingModel::Cycles4_3, d.multiscatter = true;
    cases.push_back({d, back_face});
  };
  v4(ClosureKind::Glossy, 0.4f, false);  // 12
  v4(ClosureKind::Glass, 0.3f, false);   // 13
  v4(ClosureKind::Glass, 0.3f, true);    // 14
  v4(ClosureKind::Diffuse, 0.7f, false); // 15
  const vec3 wis[3] = {glm::normalize(vec3(-0.4f, 0.1f, 0.7f)), glm::normalize(vec3(0.5f, 0.6f, 0.2f)),
                       glm::normalize(vec3(-0.2f, 0.3f, -0.9f))};
  struct Expected { size_t c; int wi; vec3 f; float pdf; };
  const Expected expected[] = {
      {0, 0, {0.303666055f, 0.208171502f, 0.144508481f}, 0.326034367f},
      {0, 1, {0.266052783f, 0.167477399f, 0.101760484f}, 0.075061962f},
      {0, 2, {0.0f, 0.0f, 0.0f}, 0.0f},
      {1, 0, {0.64547199f, 0.410389304f, 0.253667563f}, 0.683407187f},
      {1, 1, {0.0970868245f, 0.0606983602f, 0.036439389f}, 0.0310763791f},
      {1, 2, {0.0f, 0.0f, 0.0f}, 0.0f},
      {2, 0, {0.08127065f, 0.08127065f, 0.08127065f}, 0.124072224f},
      {2, 1, {0.000421886827f, 0.000421886827f, 0.000421886827f}, 0.00019085742f},
      {2, 2, {0.364002973f, 0.227501854f, 0.136501119f}, 0.410947025f},
      {3, 0, {0.0882035494f, 0.0882035494f, 0.0882035494f}, 0.134342805f},
      {3, 1, {0.000457876478f, 0.000457876478f, 0.000457876478f}, 0.00020665639f},
      {3, 2, {0.0640921816f, 0.0400576107f, 0.0240345672f}, 0.0721893981f},
      {4, 0, {0.254647911f, 0.159154937f, 0.0954929665f}, 0.274268657f},
      {4, 1, {0.254647911f, 0.159154937f, 0.0954929665f}, 0.0789629668f},
      {4, 2, {0.0f, 0.0f, 0.0f}, 0.0f},
      {5, 0, {0.182812795f, 0.114257991f, 0.0685547963f}, 0.274268657f},
      {5, 1, {0.218850419f, 0.136781514f, 0.0820689127f}, 0.0789629668f},
      {5, 2, {0.0f, 0.0f, 0.0f}, 0.0f},
      {6, 0, {1.60307312f, 1.0019207f, 0.60115242f}, 1.73041618f},
      {6, 1, {0.0282622613f, 0.0176639128f, 0.0105983485f}, 0.00954877771f},
      {6, 2, {0.0f, 0.0f, 0.0f}, 0.0f},
      {7, 0, {0.065016523f, 0.040635325f, 0.0243811961f}, 0.0700752437f},
      {7, 1, {0.000337509467f, 0.000210943414f, 0.000126566054f}, 0.000107795109f},
      {7, 2, {0.364002973f, 0.227501854f, 0.136501119f}, 0.422507733f},
      {8, 0, {0.0705628395f, 0.0441017747f, 0.0264610667f}, 0.0760531053f},
      {8, 1, {0.000366301188f, 0.000228938239f, 0.000137362949f}, 0.000116990719f},
      {8, 2, {0.0640921816f, 0.0400576107f, 0.0240345672f}, 0.0743934587f},
      {9, 0, {0.631399155f, 0.388174772f, 0.236519605f}, 0.654376626f},
      {9, 1, {0.141959637f, 0.0870390907f, 0.052172631f}, 0.0467874259f},
      {9, 2, {0.0f, 0.0f, 0.0f}, 0.0f},
      {10, 0, {0.14526999f, 0.100810096f, 0.0755636841f}, 0.163519084f},
      {10, 1, {0.112689324f, 0.0697740689f, 0.0425426066f}, 0.0324540697f},
      {10, 2, {1.07672298f, 0.849697113f, 0.657176197f}, 1.22169828f},
      {11, 0, {0.149974674f, 0.105129465f, 0.0795730799f}, 0.164435133f},
      {11, 1, {0.114677399f, 0.0717087463f, 0.0444342308f}, 0.0323744528f},
      {11, 2, {0.241322488f, 0.187583178f, 0.143299773f}, 0.26206407f},
      {12, 0, {1.65048265f, 1.02009881f, 0.607617617f}, 1.73041618f},
      {12, 1, {0.029101111f, 0.0179862585f, 0.0107134404f}, 0.00954877771f},
      {12, 2, {0.0f, 0.0f, 0.0f}, 0.0f},
      {13, 0, {0.0656666681f, 0.041031871f, 0.0246152226f}, 0.0707310662f},
      {13, 1, {0.000369467452f, 0.000230862046f, 0.000138495263f}, 0.000117925745f},
      {13, 2, {0.364050061f, 0.227476954f, 0.136464551f}, 0.422294378f},
      {14, 0, {0.076040335f, 0.0473971404f, 0.0283877924f}, 0.0813762024f},
      {14, 1, {0.000863921712f, 0.00053849601f, 0.000322523963f}, 0.00027396495f},
      {14, 2, {0.0647128597f, 0.0403365418f, 0.0241589583f}, 0.0745818168f},
      {15, 0, {0.215355873f, 0.121884078f, 0.0701590925f}, 0.274268657f},
      {15, 1, {0.229050681f, 0.139171824f, 0.0825717524f}, 0.0789629668f},
      {15, 2, {0.0f, 0.0f, 0.0f}, 0.0f},
  };
  const vec3 n(0, 0, 1);
  for (const Expected& e : expected) {
    const BSDF bsdf(n, n, with_closures({cases[e.c].c}), cases[e.c].back_face, kWo);
    float pdf;
    const vec3 f = bsdf.eval(wis[e.wi], &pdf);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(f[k], e.f[k], 1e-6f * e.f[k]) << "case " << e.c << " wi " << e.wi;
    EXPECT_NEAR(pdf, e.pdf, 1e-6f * e.pdf) << "case " << e.c << " wi " << e.wi;
  }
}

// White furnace (the view-dependent albedo of a white closure): Cycles 4.x's
// Multiscatter GGX gives back what single scattering loses, for reflection
// and glass, entering and leaving; Principled v2 (a white dielectric specular
// layer over white Lambert, and white metal) and the 4.3 Oren-Nayar keep all
// of it too. The single-scattering versions lose up to a third (so the test
// can tell them apart).
TEST(Materials, Cycles4ClosuresPreserveEnergy) {
  const vec3 white(1.0f);
  struct Case { const char* name; Closure c; bool back_face; double lo, hi; };
  Closure dielectric = closure4(ClosureKind::Principled, white, 0.0f, true);
  Closure metal = dielectric;
  metal.metallic = 1.0f;
  Closure glassy = dielectric;
  glassy.transmission = 1.0f;
  std::vector<Case> cases;
  for (float r : {0.3f, 0.6f, 1.0f}) {
    cases.push_back({"glossy multiscatter", closure4(ClosureKind::Glossy, white, r, true), false, 0.985, 1.01});
    cases.push_back({"glass multiscatter ior 1.5", closure4(ClosureKind::Glass, white, r, true), false, 0.98, 1.02});
    cases.push_back({"glass multiscatter, leaving", closure4(ClosureKind::Glass, white, r, true), true, 0.97, 1.02});
    dielectric.roughness = metal.roughness = glassy.roughness = r;
    cases.push_back({"principled v2 dielectric", dielectric, false, 0.98, 1.01});
    cases.push_back({"principled v2 metal", metal, false, 0.985, 1.01});
    cases.push_back({"principled v2 transmission", glassy, false, 0.97, 1.02});
    cases.push_back({"oren-nayar 4.3", closure4(ClosureKind::Diffuse, white, r, false), false, 0.99, 1.01});
  }
  cases.push_back({"glossy single scattering r=1", closure4(ClosureKind::Glossy, white, 1.0f, false), false, 0.25, 0.85});
  // (Not at normal incidence: there the refracted lobe sits at the pole,
  // where the quadrature of albedo() has too few cells to follow it.)
  for (const Case& c : cases)
    for (float mu : {0.2f, 0.6f, 0.9f}) {
      const Albedo a = albedo(with_closures({c.c}), view_at(mu), 200000, c.back_face);
      std::printf("%-32s r %.1f mu %.1f: albedo sampled %.4f uniform %.4f (delta %.4f), pdf integral %.4f\n", c.name,
                  c.c.roughness, mu, a.sampled, a.uniform, a.delta, a.pdf_integral);
      EXPECT_GE(a.sampled, c.lo) << c.name << " r " << c.c.roughness << " mu " << mu;
      EXPECT_LE(a.sampled, c.hi) << c.name << " r " << c.c.roughness << " mu " << mu;
      EXPECT_NEAR(a.sampled - a.delta, a.uniform, 0.015) << c.name << " r " << c.c.roughness << " mu " << mu;
      EXPECT_LE(a.pdf_integral, 1.01) << c.name;
    }
}

// Cycles 4.x's lobes without energy compensation are the single-scattering
// GGX lobe with height-correlated masking: a white Glossy BSDF reflects E(mu)
// of the tables, which is more than Cycles 3.x's separable masking gives; a
// coloured Multiscatter GGX is darker than its colour x 1 by Kulla-Conty's
// factor (1 + Fms (1 - E) / E) E.
TEST(Materials, Cycles4GlossyReflectsTheTableAlbedo) {
  for (float r : {0.4f, 0.8f})
    for (float mu : {0.3f, 0.9f}) {
      // (The sampled estimates: f / pdf over visible normals resolves narrow lobes.)
      const double v4 = albedo(with_closures({closure4(ClosureKind::Glossy, vec3(1.0f), r, false)}), view_at(mu)).sampled;
      const double v3 = albedo(with_closures({closure(ClosureKind::Glossy, 1, vec3(1.0f), r)}), view_at(mu)).sampled;
      EXPECT_NEAR(v4, ggx_energy::E(r, mu), 0.01) << r << " " << mu;
      std::printf("glossy r %.1f mu %.1f: albedo separable masking %.4f, height-correlated %.4f\n", r, mu, v3, v4);
      // 1 / (1 + L(wo) + L(wi)) >= 1 / ((1 + L(wo)) (1 + L(wi))); far apart for rough lobes seen at an angle.
      EXPECT_GE(v4, v3) << r << " " << mu;
      if (r > 0.5f && mu < 0.5f) EXPECT_GT(v4, v3 + 0.02) << r << " " << mu;
      const float Fss = 0.5f, E = ggx_energy::E(r, mu), E_avg = ggx_energy::E_avg(r);
      const float Fms = Fss * E_avg / (1.0f - Fss * (1.0f - E_avg));
      const double coloured =
          albedo(with_closures({closure4(ClosureKind::Glossy, vec3(Fss), r, true)}), view_at(mu)).sampled;
      EXPECT_NEAR(coloured, Fss * (1.0f + Fms * (1.0f - E) / E) * E, 0.01) << r << " " << mu;
    }
}

// Cycles 3.x bends an interpolated shading normal so that the mirror
// reflection of wo stays above the geometric surface; Cycles 4.x leaves it as
// it is (it bends only normals from bump and normal maps), so there the
// mirror direction below the surface is lost. (Tessera bent it for 4.x too:
// a glass bunny of smooth-shaded triangles rendered 3.2% brighter than
// Cycles 4.5, 2.2% after.)
TEST(Materials, Cycles4BendsOnlyMappedNormals) {
  const vec3 ng(0, 0, 1);
  const vec3 ns = glm::normalize(vec3(0.5f, 0.0f, 1.0f));  // tilted towards +x
  const vec3 wo = glm::normalize(vec3(-0.9f, 0.0f, 0.2f));  // its mirror about ns points below ng
  ASSERT_LT(glm::dot(reflect(wo, ns), ng), 0.0f);
  Closure mirror = closure(ClosureKind::Glossy, 1, vec3(1.0f), 0.0f);
  BSDFSample s3, s4;
  EXPECT_TRUE(BSDF(ns, ng, with_closures({mirror}), false, wo).sample_f(0.5f, vec2(0.5f), s3));
  EXPECT_GT(glm::dot(s3.wi, ng), 0.0f);
  mirror.model = ShadingModel::Cycles4_3;
  EXPECT_FALSE(BSDF(ns, ng, with_closures({mirror}), false, wo).sample_f(0.5f, vec2(0.5f), s4));
  Material mapped = with_closures({mirror});
  mapped.normal_tex = TextureRef{0, 0};  // a normal map made ns: bent as in Cycles 4.x's bump correction
  EXPECT_TRUE(BSDF(ns, ng, mapped, false, wo).sample_f(0.5f, vec2(0.5f), s4));
  EXPECT_GT(glm::dot(s4.wi, ng), 0.0f);
}

// Lambert, Oren-Nayar and GGX reflection are reciprocal: f(wo, wi) = f(wi, wo).
TEST(Materials, ReflectionClosuresAreReciprocal) {
  const Material ms[] = {
      with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.8f, 0.5f, 0.2f), 0.0f)}),
      with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.8f), 0.7f)}),
      with_closures({closure(ClosureKind::Glossy, 1, vec3(0.9f, 0.7f, 0.5f), 0.35f)}),
      with_closures({closure(ClosureKind::Diffuse, 0.6f, vec3(0.8f), 0.3f), closure(ClosureKind::Glossy, 0.4f, vec3(1.0f), 0.5f)}),
      with_closures({closure4(ClosureKind::Glossy, vec3(0.9f, 0.7f, 0.5f), 0.35f, false)}),
  };
  std::mt19937 rng(3);
  const vec3 n(0, 0, 1);
  for (const Material& m : ms) {
    for (int i = 0; i < 2000; ++i) {
      vec3 a = random_dir(rng), b = random_dir(rng);
      a.z = std::abs(a.z) + 0.05f, b.z = std::abs(b.z) + 0.05f;
      a = glm::normalize(a), b = glm::normalize(b);
      const vec3 fab = BSDF(n, n, m, false, a).f(b), fba = BSDF(n, n, m, false, b).f(a);
      for (int k = 0; k < 3; ++k) ASSERT_NEAR(fab[k], fba[k], 1e-4f * std::max(1.0f, fab[k])) << i;
    }
  }
}

// Mix and Add Shader are sums: f is linear in the closure weights, and a
// Principled BSDF split into two closures of the same parameters is the same BSDF.
TEST(Materials, ClosureWeightsAreLinear) {
  std::mt19937 rng(5);
  const vec3 n(0, 0, 1);
  const Closure d = closure(ClosureKind::Diffuse, 1, vec3(0.8f, 0.3f, 0.1f), 0.4f);
  const Closure g = closure(ClosureKind::Glossy, 1, vec3(0.9f), 0.3f);
  Closure dm = d, gm = g;
  dm.weight = 0.7f, gm.weight = 0.3f;
  const Material mix = with_closures({dm, gm}), only_d = with_closures({d}), only_g = with_closures({g});
  Closure p = closure(ClosureKind::Principled, 1, vec3(0.6f, 0.5f, 0.4f), 0.35f);
  p.transmission = 0.4f;
  Closure p1 = p, p2 = p;
  p1.weight = 0.25f, p2.weight = 0.75f;
  const Material whole = with_closures({p}), split = with_closures({p1, p2});
  for (int i = 0; i < 2000; ++i) {
    vec3 wo = random_dir(rng);
    wo.z = std::abs(wo.z) + 0.05f;
    wo = glm::normalize(wo);
    const vec3 wi = random_dir(rng);
    const vec3 expect = 0.7f * BSDF(n, n, only_d, false, wo).f(wi) + 0.3f * BSDF(n, n, only_g, false, wo).f(wi);
    const vec3 got = BSDF(n, n, mix, false, wo).f(wi);
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(got[k], expect[k], 1e-5f + 1e-5f * expect[k]);
    const BSDF a(n, n, whole, false, wo), b(n, n, split, false, wo);
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(a.f(wi)[k], b.f(wi)[k], 1e-5f + 1e-5f * a.f(wi)[k]);
    ASSERT_NEAR(a.pdf(wi), b.pdf(wi), 1e-5f + 1e-5f * a.pdf(wi));
  }
}

// A Cycles 3.x Principled BSDF with no metallic, specular or transmission is
// built without its closure list (bsdf.cpp): the BSDF must be the one the
// closure list gives. A second closure of weight 0 (dropped, as Cycles drops
// it) sends the same material down the closure list; f, pdf and samples must
// match bit for bit, with bent shading normals and on back faces, for black
// and out-of-range inputs too.
TEST(Materials, DiffusePrincipledShortcutIsTheClosureListsBSDF) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const Closure dropped = closure(ClosureKind::Glossy, 0.0f, vec3(0.9f), 0.2f);
  for (int i = 0; i < 400; ++i) {
    Closure p = closure(ClosureKind::Principled, i % 7 == 0 ? 1.0f : 0.2f + u(rng), vec3(u(rng), u(rng), u(rng)),
                        1.2f * u(rng) - 0.1f);
    p.specular = i % 5 == 0 ? -0.1f : 0.0f;
    p.metallic = i % 3 == 0 ? -0.2f : 0.0f;
    p.transmission = i % 4 == 0 ? -0.5f : 0.0f;
    if (i % 11 == 0) p.color = vec3(0.0f);
    if (i % 13 == 0) p.color = vec3(1.5f, -0.2f, 0.4f);
    const Material shortcut = with_closures({p}), list = with_closures({p, dropped});
    const vec3 ng(0, 0, 1);
    const vec3 ns = glm::normalize(vec3(0.4f * u(rng) - 0.2f, 0.4f * u(rng) - 0.2f, 1.0f));
    vec3 wo = random_dir(rng);
    wo.z = std::abs(wo.z) + 0.02f;
    wo = glm::normalize(wo);
    const bool back_face = i % 2 == 1;
    const BSDF a(ns, ng, shortcut, back_face, wo), b(ns, ng, list, back_face, wo);
    ASSERT_EQ(a.num_lobes(), b.num_lobes()) << i;
    ASSERT_EQ(a.has_smooth_lobes(), b.has_smooth_lobes()) << i;
    for (int j = 0; j < 8; ++j) {
      const vec3 wi = random_dir(rng);
      float pa, pb;
      ASSERT_EQ(a.eval(wi, &pa), b.eval(wi, &pb)) << i;
      ASSERT_EQ(pa, pb) << i;
      ASSERT_EQ(a.eval(wi, &pa, kRayGlossy), b.eval(wi, &pb, kRayGlossy)) << i;
      ASSERT_EQ(pa, pb) << i;
      const float u_lobe = u(rng);
      const vec2 u2(u(rng), u(rng));
      BSDFSample sa, sb;
      const bool ok = a.sample_f(u_lobe, u2, sa);
      ASSERT_EQ(ok, b.sample_f(u_lobe, u2, sb)) << i;
      if (!ok) continue;
      ASSERT_EQ(sa.wi, sb.wi) << i;
      ASSERT_EQ(sa.f, sb.f) << i;
      ASSERT_EQ(sa.pdf, sb.pdf) << i;
      ASSERT_EQ(sa.delta, sb.delta) << i;
      ASSERT_EQ(sa.kind, sb.kind) << i;
    }
  }
}

// Principled Alpha a: a white transparent closure of weight 1 - a, the rest
// scaled by a (Cycles). Transparent samples continue exactly along -wo.
// Light sampling skips emitters wholly behind a receiver whose BSDF
// reflects only (LightSampler::sample's `above`): that is the same image
// only if such a BSDF is 0 for every direction behind the normal it names,
// bent shading normals, back faces and Cycles 4.x closures included. A BSDF
// with a smooth transmitting lobe names none (a delta one, which eval()
// never gives, does not count).
TEST(Materials, ReflectingBSDFsGiveNothingBehindTheNormalTheyName) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  int checked = 0;
  for (int i = 0; i < 300; ++i) {
    const vec3 color(u(rng), u(rng), u(rng));
    const float rough = u(rng);
    Closure principled = closure(ClosureKind::Principled, 1.0f, color, rough);
    principled.metallic = u(rng), principled.specular = u(rng);
    Closure transmissive = principled;
    transmissive.transmission = 0.5f + 0.5f * u(rng);
    const float rough_glass = 0.2f + 0.8f * u(rng);
    const Closure opaque[] = {principled, closure(ClosureKind::Diffuse, 1.0f, color, rough),
                              closure(ClosureKind::Glossy, 1.0f, color, rough),
                              closure4(ClosureKind::Principled, color, rough, i % 2 == 0)};
    const Closure through[] = {transmissive, closure(ClosureKind::Glass, 1.0f, color, rough),
                               closure(ClosureKind::Glass, 1.0f, color, rough_glass)};
    const vec3 ng = random_dir(rng);
    const vec3 ns = glm::normalize(ng + 0.3f * random_dir(rng));
    vec3 wo = random_dir(rng);
    if (glm::dot(wo, ng) < 0.0f) wo = -wo;
    const bool back_face = i % 3 == 0;
    auto check = [&](const Closure& c) {
      const BSDF bsdf(ns, ng, with_closures({c}), back_face, wo);
      const vec3* above = bsdf.reflects_only_above();
      if (above)
        for (int j = 0; j < 16; ++j) {
          vec3 wi = random_dir(rng);
          if (glm::dot(wi, *above) > 0.0f) wi = -wi;
          float pdf;
          EXPECT_EQ(bsdf.eval(wi, &pdf), vec3(0.0f)) << i << " closure " << int(c.kind);
          ++checked;
        }
      return above != nullptr;
    };
    for (const Closure& c : opaque) EXPECT_TRUE(check(c)) << i << " closure " << int(c.kind);
    for (const Closure& c : through) check(c);
    // Rough glass seen from outside refracts (from inside, past the critical
    // angle, Cycles 3.x's glass only reflects: then it names its normal).
    if (!back_face) EXPECT_FALSE(check(through[2])) << i << " rough glass";
  }
  EXPECT_GE(checked, 300 * 4 * 16);
}

TEST(Materials, AlphaIsATransparentClosure) {
  Material m;
  m.base_color = vec3(0.7f, 0.5f, 0.3f);
  m.roughness = 0.4f;
  Material cut = m;
  cut.alpha = 0.3f;
  EXPECT_FALSE(m.may_be_transparent());
  EXPECT_TRUE(cut.may_be_transparent());
  EXPECT_NEAR(cut.transparency().x, 0.7f, 1e-6f);
  const vec3 n(0, 0, 1);
  const BSDF opaque(n, n, m, false, kWo), see_through(n, n, cut, false, kWo);
  std::mt19937 rng(9);
  for (int i = 0; i < 200; ++i) {
    vec3 wi = random_dir(rng);
    wi.z = std::abs(wi.z);
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(see_through.f(wi)[k], 0.3f * opaque.f(wi)[k], 1e-6f + 1e-5f * opaque.f(wi)[k]);
  }
  // Expected throughput of the transparent samples is 1 - alpha.
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  double through = 0;
  const int n_samples = 200000;
  for (int i = 0; i < n_samples; ++i) {
    BSDFSample s;
    if (!see_through.sample_f(u(rng), vec2(u(rng), u(rng)), s) || s.kind != BSDFSample::kTransparent) continue;
    ASSERT_EQ(s.wi, -kWo);
    ASSERT_TRUE(s.delta);
    through += luminance(s.f) * std::abs(s.wi.z) / s.pdf;
  }
  EXPECT_NEAR(through / n_samples, 0.7, 0.01);
}

// ------------------------------------------------------------------ integrator

namespace {
std::vector<float> render(const Scene& s, RenderOptions opt) {
  RenderSession session(s, opt);
  session.render();
  return session.pixels();
}
vec3 mean_rgb(const std::vector<float>& px) {
  double r = 0, g = 0, b = 0;
  for (size_t i = 0; i < px.size(); i += 4) r += px[i], g += px[i + 1], b += px[i + 2];
  const double n = double(px.size() / 4);
  return vec3(float(r / n), float(g / n), float(b / n));
}
// An orthographic camera at height h looking down -z onto [-e,e]^2.
void look_down(Scene& s, float h, float e, int size = 16) {
  Camera& c = s.camera;
  c.type = Camera::Type::Orthographic;
  c.to_world = glm::translate(mat4(1.0f), vec3(0, 0, h));
  c.left = c.bottom = -e;
  c.right = c.top = e;
  c.clip_start = 0.01f;
  c.clip_end = 100.0f;
  c.width = c.height = size;
}
uint32_t add_material(Scene& s, const Material& m) {
  s.materials.push_back(m);
  return uint32_t(s.materials.size() - 1);
}
void add_square(Scene& s, float z, float half, uint32_t material) {
  fixtures::add_quad(s, {-half, -half, z}, {half, -half, z}, {half, half, z}, {-half, half, z}, material);
}
// Renders one sample per pixel: each pixel's red channel is one path's value,
// and every one must be `expected`.
void expect_every_sample(const Scene& s, float expected, float tolerance) {
  RenderOptions opt;
  opt.samples = 1;
  const std::vector<float> px = render(s, opt);
  float lo = 1e30f, hi = -1e30f;
  for (size_t i = 0; i < px.size(); i += 4) lo = std::min(lo, px[i]), hi = std::max(hi, px[i]);
  std::printf("samples from %.6f to %.6f (expected %.6f)\n", lo, hi, expected);
  EXPECT_NEAR(lo, expected, tolerance);
  EXPECT_NEAR(hi, expected, tolerance);
}
}  // namespace

// Camera -> transparent plane -> world: every sample is the world times the
// plane's colour (one delta lobe, nothing random).
TEST(Materials, TransparentPlaneTintsWhatIsBehind) {
  Scene s;
  add_square(s, 0.0f, 5.0f, add_material(s, with_closures({closure(ClosureKind::Transparent, 1, vec3(0.5f, 0.25f, 1.0f))})));
  s.background.set_color(vec3(0.8f, 0.6f, 0.4f));
  look_down(s, 2.0f, 1.0f);
  s.commit();
  EXPECT_TRUE(scene_features(s).transparent);
  RenderOptions opt;
  opt.samples = 4;
  const vec3 m = mean_rgb(render(s, opt));
  EXPECT_NEAR(m.x, 0.4f, 1e-5f);
  EXPECT_NEAR(m.y, 0.15f, 1e-5f);
  EXPECT_NEAR(m.z, 0.4f, 1e-5f);
}

// White furnace through lossless glass whose shading normals lean 56 degrees
// off the geometric one, seen from straight above: Cycles 3.x bends such a
// normal (ensure_valid_reflection) so that the mirror direction stays above
// the surface, and both lobes then reflect and refract about the bent normal.
// Reflection and refraction are picked with probabilities F and 1 - F, so
// every path's weight is exactly 1 and every sample sees the world's 1 -
// unless the integrator's cosine is taken against another normal than the
// lobes' frame: with the unbent one, f |cos| / pdf was |wi.ns| / |wi.n_bent|,
// 0.87 to 1.18 here, and hundreds near the critical angle (the
// glass bunny's fireflies: pixels of 156 where Cycles' brightest was 70).
// (Cycles 4.x bends only mapped normals: there the mirror direction is lost.)
TEST(Materials, BentShadingNormalsKeepPathWeightsWhole) {
  {
    Scene s;
    const float h = 50.0f;
    const std::vector<float> pos = {-h, -h, 0, h, -h, 0, h, h, 0, -h, h, 0};
    const std::vector<uint32_t> idx = {0, 1, 2, 0, 2, 3};
    const vec3 lean = glm::normalize(vec3(1.5f, 0.0f, 1.0f));
    std::vector<float> normals;
    for (int k = 0; k < 6; ++k) normals.insert(normals.end(), {lean.x, lean.y, lean.z});
    MeshInput in = fixtures::mesh_input(pos, idx);
    in.corner_normals = normals.data();
    s.meshes.push_back(build_mesh(in));
    const Closure glass = closure(ClosureKind::Glass, 1, vec3(1.0f), 0.0f, 1.5f);  // Cycles 3.x
    s.add_instance(0, mat4(1.0f), {add_material(s, with_closures({glass}))});
    s.background.set_color(vec3(1.0f));
    look_down(s, 2.0f, 1.0f, 24);
    s.commit();
    expect_every_sample(s, 1.0f, 1e-4f);
  }
}

// A constant world is left to BSDF sampling, as Cycles disables its
// background light for a world without spatial variation: under a uniform
// sky a Lambert plane's cosine-sampled bounce always escapes and brings the
// albedo times the sky, so every sample is exactly that. With next-event
// estimation of the world (uniform over the sphere, MIS-weighted) samples
// ranged from 0.001 to 0.72 and half the light samples went below the plane.
TEST(Materials, ConstantWorldIsFoundByTheBSDFAlone) {
  Scene s;
  add_square(s, 0.0f, 50.0f, add_material(s, with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)})));
  s.background.set_color(vec3(1.0f));
  look_down(s, 2.0f, 1.0f, 24);
  s.commit();
  EXPECT_TRUE(s.light_sampler().empty());
  EXPECT_EQ(s.light_sampler().world_pmf(), 0.0f);
  expect_every_sample(s, 0.5f, 1e-5f);
}

// A sun with an angle is a disk that escaping rays see (Cycles'
// integrate_distant_lights), MIS-weighted against light sampling. Glass of
// IOR 1 (no bending, no reflection) over a Lambert floor blocks the floor's
// shadow rays, so only the BSDF rays that pass the glass and escape into the
// disk can light it: the floor must be as bright as without the glass. When
// the disk was for light sampling only, it was black there (the sun's
// caustics through glass were lost; a glass sphere on a sunlit floor was
// 1.5% darker than in Cycles).
TEST(Materials, SunDisksAreSeenThroughGlass) {
  float mean[2];
  for (int glass = 0; glass < 2; ++glass) {
    Scene s;
    add_square(s, 0.0f, 50.0f, add_material(s, with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)})));
    if (glass) add_square(s, 0.5f, 50.0f, add_material(s, with_closures({closure(ClosureKind::Glass, 1, vec3(1.0f), 0.0f, 1.0f)})));
    Light sun;
    sun.type = LightType::Sun;
    sun.direction = glm::normalize(vec3(0.2f, 0.1f, -1.0f));
    sun.radius = std::tan(0.5f);
    sun.radiance = vec3(1.0f);
    s.lights.push_back(sun);
    look_down(s, 2.0f, 1.0f, 16);
    s.commit();
    RenderOptions opt;
    opt.samples = 256;
    mean[glass] = mean_rgb(render(s, opt)).x;
  }
  std::printf("floor without glass %.4f, under IOR-1 glass %.4f\n", mean[0], mean[1]);
  EXPECT_GT(mean[0], 0.05f);
  EXPECT_NEAR(mean[1] / mean[0], 1.0f, 0.03f);
}

// Principled Alpha over the world: a black surface with alpha a shows (1 - a)
// of the world; a Lambert surface of albedo 0.5 with alpha 0.5 under a
// uniform world shows 0.5 (1 - a) + 0.5 a of it.
TEST(Materials, AlphaShowsTheWorldThroughTheSurface) {
  for (int variant = 0; variant < 2; ++variant) {
    Scene s;
    Material m;
    if (variant == 0) {
      m.base_color = vec3(0.0f);
      m.specular = 0.0f;
      m.alpha = 0.3f;
    } else {
      m = with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)});
      m.alpha = 0.5f;
    }
    add_square(s, 0.0f, 50.0f, add_material(s, m));
    s.background.set_color(vec3(1.0f, 0.5f, 0.25f));
    look_down(s, 2.0f, 1.0f);
    s.commit();
    RenderOptions opt;
    opt.samples = variant == 0 ? 4 : 256;
    const vec3 got = mean_rgb(render(s, opt));
    const float expect = variant == 0 ? 0.7f : 0.75f;
    std::printf("alpha variant %d: %.4f %.4f %.4f (expected %.4f x world)\n", variant, got.x, got.y, got.z, expect);
    EXPECT_NEAR(got.x, expect * 1.0f, variant == 0 ? 1e-5f : 0.01f);
    EXPECT_NEAR(got.y, expect * 0.5f, variant == 0 ? 1e-5f : 0.005f);
    EXPECT_NEAR(got.z, expect * 0.25f, variant == 0 ? 1e-5f : 0.003f);
  }
}

// Transparent bounces are counted apart and limited as in Cycles: after the
// last allowed one, the next surface ends the path (here: no emission, black).
TEST(Materials, TransparentBounceLimit) {
  Scene s;
  const uint32_t glass = add_material(s, with_closures({closure(ClosureKind::Transparent, 1, vec3(1.0f))}));
  for (int i = 0; i < 10; ++i) add_square(s, -0.1f * float(i), 5.0f, glass);
  s.background.set_color(vec3(1.0f));
  look_down(s, 2.0f, 1.0f, 8);
  s.commit();
  RenderOptions opt;
  opt.samples = 2;
  opt.max_bounces = 0;  // transparent bounces are not bounces
  for (int limit : {8, 9, 10, 12}) {
    opt.max_transparent_bounces = limit;
    const float v = mean_rgb(render(s, opt)).x;
    EXPECT_FLOAT_EQ(v, limit >= 10 ? 1.0f : 0.0f) << limit;
  }
}

// Transparent shadows: a sun over a white floor, seen from below a cover of
// alpha 0.4 (transparent weight 0.6): direct light only, the floor gets
// exactly 0.6 of the open floor's light. An opaque cover leaves it black,
// with occlusion rays (no transparent material in the scene) and with
// transparent shadow rays (another material is transparent).
TEST(Materials, ShadowRaysPassTransparentSurfaces) {
  auto floor_radiance = [](int cover) {
    Scene s;
    const uint32_t white = add_material(s, with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.8f), 0.0f)}));
    add_square(s, 0.0f, 50.0f, white);
    if (cover) {
      Material m;
      m.base_color = vec3(0.0f);
      m.specular = 0.0f;
      m.alpha = cover == 1 ? 0.4f : 1.0f;
      add_square(s, 1.0f, 50.0f, add_material(s, m));
    }
    if (cover == 3) {  // a transparent material elsewhere, out of the way
      Material t = with_closures({closure(ClosureKind::Transparent, 1, vec3(1.0f))});
      fixtures::add_quad(s, {100, 100, 0}, {101, 100, 0}, {101, 101, 0}, {100, 101, 0}, add_material(s, t));
    }
    Light sun;
    sun.type = LightType::Sun;
    sun.direction = glm::normalize(vec3(0.2f, 0.1f, -1.0f));
    sun.radiance = vec3(3.0f);
    s.lights.push_back(sun);
    look_down(s, 0.5f, 1.0f, 8);
    s.commit();
    EXPECT_EQ(scene_features(s).transparent, cover == 1 || cover == 3);
    RenderOptions opt;
    opt.samples = 16;
    opt.max_bounces = 0;
    return mean_rgb(render(s, opt)).x;
  };
  const float open = floor_radiance(0), through = floor_radiance(1);
  const float blocked = floor_radiance(2), blocked_transparent_path = floor_radiance(3);
  std::printf("floor: open %.5f, under alpha 0.4 %.5f (ratio %.5f), under opaque %.5f / %.5f\n", open, through,
              through / open, blocked, blocked_transparent_path);
  EXPECT_GT(open, 0.1f);
  EXPECT_NEAR(through / open, 0.6f, 1e-4f);
  EXPECT_EQ(blocked, 0.0f);
  EXPECT_EQ(blocked_transparent_path, 0.0f);
}

// MIS across transparent surfaces: a rough floor lit by a large emissive
// quad through a surface of alpha 0.5 that the camera does not see. The
// light reaching the floor is exactly halved, by light sampling and by BSDF
// sampling alike, only if the emitter's density for MIS is taken from the
// floor point (Cycles' mis_ray_t), not from the transparent surface.
TEST(Materials, EmittersBehindTransparentSurfacesKeepMisWeights) {
  auto floor_radiance = [](bool cover) {
    Scene s;
    const uint32_t floor = add_material(s, with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.8f), 0.0f)}));
    add_square(s, 0.0f, 50.0f, floor);
    Material lamp;
    lamp.base_color = vec3(0.0f);
    lamp.specular = 0.0f;
    lamp.emission_front = lamp.emission_back = vec3(1.0f);
    const uint32_t l = add_material(s, lamp);
    fixtures::add_quad(s, {-20, -20, 3}, {-20, 20, 3}, {20, 20, 3}, {20, -20, 3}, l);  // faces down
    if (cover) {
      Material m;
      m.base_color = vec3(0.0f);
      m.specular = 0.0f;
      m.alpha = 0.5f;
      const uint32_t c = add_material(s, m);
      fixtures::add_quad(s, {-20, -20, 1.5f}, {-20, 20, 1.5f}, {20, 20, 1.5f}, {20, -20, 1.5f}, c);
    }
    look_down(s, 1.0f, 0.5f, 8);  // below the cover
    s.commit();
    RenderOptions opt;
    opt.samples = 1024;
    opt.max_bounces = 0;
    return mean_rgb(render(s, opt)).x;
  };
  const float open = floor_radiance(false), covered = floor_radiance(true);
  std::printf("floor under a lamp: open %.5f, through alpha 0.5 %.5f (ratio %.5f)\n", open, covered, covered / open);
  EXPECT_NEAR(covered / open, 0.5f, 0.005f);
}

TEST(Materials, OpaqueScenesKeepOcclusionShadowRays) {
  Scene s;
  fixtures::build_cornell_box(s, 8, 8);
  EXPECT_FALSE(scene_features(s).transparent);
}

// ------------------------------------------------------------------ depth of field

// Every ray of a film point passes through the point the pinhole ray meets
// on the plane in focus, and starts within the aperture.
TEST(Materials, ThinLensRaysMeetOnThePlaneInFocus) {
  for (Camera::Type type : {Camera::Type::Perspective, Camera::Type::Orthographic}) {
    Camera c;
    c.type = type;
    c.to_world = glm::rotate(glm::translate(mat4(1.0f), vec3(1, 2, 3)), 0.4f, glm::normalize(vec3(1, 1, 0)));
    c.width = c.height = 100;
    c.clip_start = 0.0f;
    const Ray pin = c.generate_ray(vec2(31.0f, 77.0f));
    c.aperture_radius = 0.2f;
    c.focus_distance = 4.0f;
    c.blades = 5;
    c.blades_rotation = 0.3f;
    const vec3 axis = glm::normalize(vec3(c.to_world * vec4(0, 0, -1, 0)));
    const vec3 eye(c.to_world[3]);
    const float t_pin = (4.0f - glm::dot(pin.o - eye, axis)) / glm::dot(pin.d, axis);
    const vec3 focus = pin.o + pin.d * t_pin;
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    float spread = 0.0f;
    for (int i = 0; i < 1000; ++i) {
      const Ray r = c.generate_ray(vec2(31.0f, 77.0f), vec2(u(rng), u(rng)));
      const float t = (4.0f - glm::dot(r.o - eye, axis)) / glm::dot(r.d, axis);
      ASSERT_LT(glm::length(r.o + r.d * t - focus), 1e-4f);
      ASSERT_LE(glm::length(r.o - pin.o), 0.2f + 1e-5f);
      spread = std::max(spread, glm::length(r.o - pin.o));
    }
    EXPECT_GT(spread, 0.15f);  // the aperture is used
  }
}

// Blades: a uniform point in the regular polygon inscribed in the aperture
// circle, corners at rotation + (2k + 1) pi / n; the aperture ratio narrows x.
TEST(Materials, ApertureBladesSampleARegularPolygon) {
  Camera c;
  c.blades = 6;
  c.blades_rotation = 0.25f;
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const int n = 200000;
  const float apothem = std::cos(kPi / 6);
  double r2 = 0, mx = 0, my = 0;
  float far = 0.0f, far_angle = 0.0f;
  for (int i = 0; i < n; ++i) {
    const vec2 p = c.sample_aperture(vec2(u(rng), u(rng)));
    const float r = glm::length(p);
    ASSERT_LE(r, 1.0f + 1e-5f);
    // Inside every edge: the distance along each edge normal is at most the apothem.
    for (int k = 0; k < 6; ++k) {
      const float a = c.blades_rotation + 2.0f * kPi * k / 6;
      ASSERT_LE(p.x * std::cos(a) + p.y * std::sin(a), apothem + 1e-5f);
    }
    r2 += double(r) * r, mx += p.x, my += p.y;
    if (r > far) far = r, far_angle = std::atan2(p.y, p.x);
  }
  // Uniform over a regular hexagon of circumradius 1: E[r^2] = 5/12.
  EXPECT_NEAR(r2 / n, 5.0 / 12.0, 0.005);
  EXPECT_NEAR(mx / n, 0.0, 0.005);
  EXPECT_NEAR(my / n, 0.0, 0.005);
  // The farthest points are corners.
  const float corner = std::remainder(far_angle - c.blades_rotation - kPi / 6, 2.0f * kPi / 6);
  EXPECT_NEAR(corner, 0.0f, 0.02f);
  // Anamorphic ratio 2: half as wide.
  c.blades = 0;
  c.aperture_ratio = 2.0f;
  float max_x = 0, max_y = 0;
  for (int i = 0; i < 20000; ++i) {
    const vec2 p = c.sample_aperture(vec2(u(rng), u(rng)));
    max_x = std::max(max_x, std::abs(p.x)), max_y = std::max(max_y, std::abs(p.y));
  }
  EXPECT_NEAR(max_x, 0.5f, 0.01f);
  EXPECT_NEAR(max_y, 1.0f, 0.01f);
}

// Depth of field keeps images independent of the thread count and tiles.
TEST(Materials, DepthOfFieldIsDeterministic) {
  Scene s;
  fixtures::build_cornell_box(s, 24, 16, mat4(1.0f), 1.0f, false);
  s.camera.aperture_radius = 0.1f;
  s.camera.focus_distance = 3.0f;
  s.camera.blades = 5;
  s.commit();
  RenderOptions opt;
  opt.samples = 8;
  opt.threads = 1;
  const std::vector<float> one = render(s, opt);
  opt.threads = 0;
  opt.tile_size = 3;
  const std::vector<float> all = render(s, opt);
  ASSERT_EQ(one.size(), all.size());
  EXPECT_EQ(0, std::memcmp(one.data(), all.data(), one.size() * sizeof(float)));
}

// 8-bit images are kept as bytes and converted per texel: every byte value
// gives what the float path stores (sRGB's EOTF, or k / 255 for data and
// alpha), through every interpolation, and the average is the texels' mean.
TEST(Textures, ByteTexelsReadAsTheirLinearValues) {
  for (bool srgb : {true, false}) {
    std::vector<float> rgba(256 * 4);
    for (int k = 0; k < 256; ++k)
      for (int c = 0; c < 4; ++c) rgba[4 * k + c] = float(((k + 37 * c) % 256) / 255.0);
    Texture t;
    t.set_bytes(rgba.data(), 256, 1, srgb);
    t.interpolation = Texture::Interpolation::Closest;
    EXPECT_TRUE(t.texels.empty());
    EXPECT_EQ(t.bytes.size(), 256u);
    auto linear = [&](int k, int c) {
      const double x = ((k + 37 * c) % 256) / 255.0;
      return float(!srgb || c == 3 ? x : x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4));
    };
    glm::dvec4 mean(0.0);
    for (int k = 0; k < 256; ++k) {
      const vec4 v = t.eval(vec2((k + 0.5f) / 256.0f, 0.5f));
      for (int c = 0; c < 4; ++c) {
        EXPECT_FLOAT_EQ(v[c], linear(k, c)) << "byte " << k << " channel " << c << (srgb ? " sRGB" : " linear");
        mean[c] += linear(k, c) / 256.0;
      }
    }
    const vec4 avg = t.average();
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(avg[c], mean[c], 1e-6);
    // Bilinear between two texels interpolates the linear values.
    t.interpolation = Texture::Interpolation::Linear;
    t.extension = Texture::Extension::Extend;
    const vec4 mid = t.eval(vec2(11.0f / 256.0f, 0.5f));
    EXPECT_NEAR(mid.x, 0.5f * (linear(10, 0) + linear(11, 0)), 1e-6f);
  }
}

// Repeat wraps as a periodic image: a lookup at uv + (i, j) equals the one at
// uv, and bilinear and cubic lookups at the seams blend the texels across
// the opposite edge, against a direct periodic evaluation.
TEST(Textures, RepeatWrapsAcrossTheSeamsAndTiles) {
  const int w = 5, h = 3;
  Texture t;
  t.width = w, t.height = h;
  for (int i = 0; i < w * h; ++i) t.texels.push_back(vec4(float(i), float(i * i % 7), 1.0f + i % 3, 1.0f));
  auto at = [&](int x, int y) { return t.texels[size_t(((y % h) + h) % h) * w + ((x % w) + w) % w]; };
  for (auto interp : {Texture::Interpolation::Closest, Texture::Interpolation::Linear, Texture::Interpolation::Cubic}) {
    t.interpolation = interp;
    for (vec2 uv : {vec2(0.01f, 0.02f), vec2(0.99f, 0.97f), vec2(0.5f, 0.5f), vec2(0.31f, 0.9f)}) {
      const vec4 ref = t.eval(uv);
      for (vec2 shift : {vec2(1.0f, 0.0f), vec2(-3.0f, 2.0f), vec2(7.0f, -5.0f)})
        for (int c = 0; c < 4; ++c) EXPECT_NEAR(t.eval(uv + shift)[c], ref[c], 2e-3f) << "shift " << shift.x << "," << shift.y;
    }
  }
  // Bilinear at the bottom-left corner: the four corner texels of the image.
  t.interpolation = Texture::Interpolation::Linear;
  const vec2 uv(0.1f / w, 0.2f / h);  // 0.4 and 0.3 of a texel before the first texel centre
  const float tx = 0.6f, ty = 0.7f;
  const vec4 expect = (1 - ty) * ((1 - tx) * at(-1, -1) + tx * at(0, -1)) + ty * ((1 - tx) * at(-1, 0) + tx * at(0, 0));
  const vec4 got = t.eval(uv);
  for (int c = 0; c < 4; ++c) EXPECT_NEAR(got[c], expect[c], 1e-4f);
}

// Diffuse texture blur: the coarse level has ceil(1 / blur) texels across
// (where the image has more), each the mean of the image's texels under it
// (sizes that do not divide: [ceil(c W / cw), ceil((c + 1) W / cw))), for
// float and byte images; lookups after a diffuse bounce read it with the
// image's extension, and every other lookup is the image's own.
TEST(Textures, DiffuseBlurLevelIsTheImageBoxFiltered) {
  const int w = 10, h = 6;
  std::vector<float> rgba;
  for (int i = 0; i < w * h; ++i)
    for (float v : {float(i % 7) / 6.0f, float((3 * i) % 11) / 10.0f, float(i) / float(w * h), 1.0f}) rgba.push_back(v);
  for (bool bytes : {false, true}) {
    Texture t;
    if (bytes) {
      t.set_bytes(rgba.data(), w, h, true);
    } else {
      t.width = w, t.height = h;
      for (int i = 0; i < w * h; ++i) t.texels.emplace_back(rgba[4 * i], rgba[4 * i + 1], rgba[4 * i + 2], rgba[4 * i + 3]);
    }
    auto image = [&](int x, int y) { return t.eval(vec2((x + 0.5f) / w, (y + 0.5f) / h)); };
    t.interpolation = Texture::Interpolation::Closest;
    t.set_diffuse_blur(0.25f);  // 4 x 4
    ASSERT_EQ(t.coarse_width, 4);
    ASSERT_EQ(t.coarse_height, 4);
    auto first = [](int c, int n, int cn) { return (c * n + cn - 1) / cn; };
    for (int cy = 0; cy < 4; ++cy)
      for (int cx = 0; cx < 4; ++cx) {
        glm::dvec4 sum(0.0);
        int count = 0;
        for (int y = first(cy, h, 4); y < first(cy + 1, h, 4); ++y)
          for (int x = first(cx, w, 4); x < first(cx + 1, w, 4); ++x, ++count) sum += glm::dvec4(image(x, y));
        ASSERT_GT(count, 0);
        const vec2 centre((cx + 0.5f) / 4.0f, (cy + 0.5f) / 4.0f);
        for (auto interp : {Texture::Interpolation::Closest, Texture::Interpolation::Linear}) {
          t.interpolation = interp;
          const vec4 c = t.eval(centre, true);
          for (int k = 0; k < 4; ++k) EXPECT_NEAR(c[k], sum[k] / count, 1e-6) << cx << "," << cy << " channel " << k;
          // Repeat: the level tiles as the image does.
          const vec4 shifted = t.eval(centre + vec2(3.0f, -2.0f), true);
          for (int k = 0; k < 4; ++k) EXPECT_NEAR(shifted[k], c[k], 1e-6);
        }
        t.interpolation = Texture::Interpolation::Closest;
      }
    // Lookups that are not after a diffuse bounce read the image itself.
    for (vec2 uv : {vec2(0.13f, 0.71f), vec2(0.5f, 0.5f), vec2(0.97f, 0.02f)})
      for (int k = 0; k < 4; ++k) EXPECT_EQ(t.eval(uv, false)[k], t.eval(uv)[k]);
    // Clip: nothing outside, as the image.
    t.extension = Texture::Extension::Clip;
    EXPECT_EQ(t.eval(vec2(1.5f, 0.5f), true), vec4(0.0f));
    // No level where the blur asks for nothing coarser than the image, or for no blur.
    for (float blur : {0.0f, 1.0f / 16.0f}) {
      t.set_diffuse_blur(blur);
      EXPECT_TRUE(t.coarse.empty()) << blur;
      EXPECT_EQ(t.eval(vec2(0.37f, 0.61f), true), t.eval(vec2(0.37f, 0.61f))) << blur;
    }
    // Coarser in one direction only: 8 across the 10 columns, all 6 rows.
    t.set_diffuse_blur(1.0f / 8.0f);
    EXPECT_EQ(t.coarse_width, 8);
    EXPECT_EQ(t.coarse_height, 6);
  }
}

namespace {
// A textured square (UVs over [0,1]^2) at height z, its base colour a
// checkerboard of n x n texels, 0.1 and 0.9.
void add_checker_square(Scene& s, float z, float half, int n, float blur) {
  std::vector<float> rgba;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      for (int c = 0; c < 4; ++c) rgba.push_back(c == 3 ? 1.0f : (x + y) % 2 ? 0.9f : 0.1f);
  Texture t;
  t.set_bytes(rgba.data(), n, n, false);
  t.set_diffuse_blur(blur);
  s.textures.push_back(std::move(t));
  Material m = with_closures({closure(ClosureKind::Diffuse, 1, vec3(1.0f), 0.0f)});
  m.base_color_tex = TextureRef{int32_t(s.textures.size()) - 1, 0};
  const float pos[12] = {-half, -half, z, half, -half, z, half, half, z, -half, half, z};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  MeshInput in;
  in.positions = pos;
  in.num_vertices = 4;
  in.indices = idx;
  in.num_triangles = 2;
  in.corner_uvs = uv;
  s.meshes.push_back(build_mesh(in));
  s.add_instance(uint32_t(s.meshes.size() - 1), mat4(1.0f), {add_material(s, m)});
}
}  // namespace

// What the camera sees keeps every texel with the blur on: a checkerboard
// under a white sky, seen from above (every path: camera, the square, the
// sky) renders bit for bit as without it. Seen only after a diffuse bounce
// (the camera looks at a white square, the checkerboard lies above it, facing
// it, under a sky that lights it from above), the board's fine checks are
// its blurred level: the image differs, its mean (board mean 0.5 either way)
// does not, beyond noise.
TEST(Textures, DiffuseBlurLeavesWhatTheCameraSeesAlone) {
  RenderOptions opt;
  opt.samples = 16;
  std::vector<float> direct[2], indirect[2];
  for (int blurred = 0; blurred < 2; ++blurred) {
    const float blur = blurred ? 1.0f / 4.0f : 0.0f;
    Scene a;
    add_checker_square(a, 0.0f, 1.0f, 64, blur);
    a.background.set_color(vec3(1.0f));
    look_down(a, 2.0f, 1.0f, 24);
    a.commit();
    direct[blurred] = render(a, opt);

    Scene b;
    const Material white = with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.8f), 0.0f)});
    add_square(b, 0.0f, 1.0f, add_material(b, white));
    add_checker_square(b, 0.05f, 0.5f, 64, blur);  // between the camera and the white square
    add_square(b, 0.3f, 0.5f, add_material(b, white));  // a white lid above it: the board is lit from below
    b.background.set_color(vec3(1.0f));
    look_down(b, 2.0f, 1.0f, 24);
    b.commit();
    indirect[blurred] = render(b, opt);
  }
  ASSERT_EQ(direct[0].size(), direct[1].size());
  EXPECT_EQ(0, std::memcmp(direct[0].data(), direct[1].data(), direct[0].size() * sizeof(float)));
  EXPECT_NE(0, std::memcmp(indirect[0].data(), indirect[1].data(), indirect[0].size() * sizeof(float)));
  const vec3 m0 = mean_rgb(indirect[0]), m1 = mean_rgb(indirect[1]);
  EXPECT_NEAR(m1.x, m0.x, 0.02f * m0.x);
}

// Film > Transparent (Cycles' PATH_RAY_TRANSPARENT_BACKGROUND): the world the
// camera sees directly or through transparent surfaces is left out of the
// image and lowers alpha by the path's weight there; the world still lights
// what the camera sees. A Lambert square under a white sky, seen from above
// filling the middle of the view, then the same square made 3/4 transparent.
TEST(Film, TransparentFilmLeavesTheWorldOutAndSetsAlpha) {
  const int size = 16;
  auto build = [&](Scene& s, const Material& m) {
    add_square(s, 0.0f, 0.5f, add_material(s, m));
    s.background.set_color(vec3(1.0f));
    look_down(s, 2.0f, 1.0f, size);
    s.commit();
  };
  auto at = [&](const std::vector<float>& px, int x, int y, int c) { return px[4 * (size_t(y) * size + x) + c]; };
  const Material lambert = with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)});
  Scene s;
  build(s, lambert);
  RenderOptions opt;
  opt.samples = 16;
  const std::vector<float> opaque = render(s, opt);
  opt.film_transparent = true;
  const std::vector<float> clear = render(s, opt);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const bool world = x < 3 || x > 12 || y < 3 || y > 12;   // at least 1 px off the square (filter 1.5 px)
      const bool square = x >= 5 && x <= 10 && y >= 5 && y <= 10;  // 1 px inside it
      EXPECT_EQ(at(opaque, x, y, 3), 1.0f);
      if (world) {
        EXPECT_EQ(at(opaque, x, y, 0), 1.0f) << x << "," << y;
        EXPECT_EQ(at(clear, x, y, 0), 0.0f) << x << "," << y;
        EXPECT_EQ(at(clear, x, y, 3), 0.0f) << x << "," << y;
      }
      if (square) {  // the same paths: lit by the world, as without the option
        EXPECT_EQ(at(clear, x, y, 3), 1.0f) << x << "," << y;
        EXPECT_EQ(at(clear, x, y, 0), at(opaque, x, y, 0)) << x << "," << y;
        EXPECT_NEAR(at(clear, x, y, 0), 0.5f, 1e-5f);
      }
    }
  // 3/4 transparent: the camera sees the world through it in 3/4 of its
  // paths, so the square's alpha is about 1/4 and its colour 1/4 of the Lambert's.
  Scene t;
  build(t, with_closures({closure(ClosureKind::Diffuse, 0.25f, vec3(0.5f), 0.0f), closure(ClosureKind::Transparent, 0.75f, vec3(1.0f))}));
  opt.samples = 64;
  const std::vector<float> half = render(t, opt);
  double alpha = 0.0, red = 0.0;
  for (int y = 5; y <= 10; ++y)
    for (int x = 5; x <= 10; ++x) alpha += at(half, x, y, 3) / 36.0, red += at(half, x, y, 0) / 36.0;
  std::printf("3/4 transparent square: alpha %.4f, red %.4f\n", alpha, red);
  EXPECT_NEAR(alpha, 0.25, 0.02);
  EXPECT_NEAR(red, 0.125, 0.01);
}

// Nothing emits, yet a transparent film still needs the camera's rays: alpha
// is 0 where the camera sees the (black) world and 1 on the geometry.
TEST(Film, TransparentFilmGivesAlphaEvenWhenNothingEmits) {
  Scene s;
  add_square(s, 0.0f, 0.5f, add_material(s, with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)})));
  look_down(s, 2.0f, 1.0f, 16);
  s.commit();
  RenderOptions opt;
  opt.samples = 4;
  opt.film_transparent = true;
  const std::vector<float> px = render(s, opt);
  EXPECT_EQ(px[4 * (0 * 16 + 0) + 3], 0.0f);
  EXPECT_EQ(px[4 * (8 * 16 + 8) + 3], 1.0f);
}

// Object Properties > Visibility > Camera off: camera rays pass the object,
// everything else sees it. A lamp (emissive quad, 0.6 wide) hung over a
// Lambert floor and seen from above: shown, the middle of the image is its
// radiance (4); hidden, it is the floor it lights (about 1). A blocker hidden from the camera still casts its shadow under a
// sun: the floor below it stays dark. Before Tessera modelled the setting,
// hidden objects were rendered as shown.
TEST(Visibility, ObjectHiddenFromTheCameraStillLightsAndCastsShadows) {
  auto middle = [](const std::vector<float>& px, int size) {
    double m = 0.0;
    for (int y = size / 2 - 1; y < size / 2 + 1; ++y)  // 2 x 2 pixels: their filters stay on the lamp
      for (int x = size / 2 - 1; x < size / 2 + 1; ++x) m += px[4 * (size_t(y) * size + x)] / 4.0;
    return m;
  };
  const int size = 16;
  const Material lambert = with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)});
  double lamp_middle[2], blocker_middle[2];
  for (int hidden = 0; hidden < 2; ++hidden) {
    Scene s;
    add_square(s, 0.0f, 50.0f, add_material(s, lambert));
    Material lamp = lambert;
    lamp.emission_front = lamp.emission_back = vec3(4.0f);
    add_square(s, 0.3f, 0.3f, add_material(s, lamp));
    if (hidden) s.instances.back().visibility &= ~kRayCamera;
    look_down(s, 2.0f, 1.0f, size);
    s.commit();
    RenderOptions opt;
    opt.samples = 64;
    lamp_middle[hidden] = middle(render(s, opt), size);

    Scene b;
    add_square(b, 0.0f, 50.0f, add_material(b, lambert));
    add_square(b, 0.5f, 0.4f, add_material(b, lambert));
    if (hidden) b.instances.back().visibility &= ~kRayCamera;
    Light sun;
    sun.type = LightType::Sun;
    sun.direction = vec3(0.0f, 0.0f, -1.0f);
    sun.radiance = vec3(1.0f);
    b.lights.push_back(sun);
    look_down(b, 2.0f, 1.0f, size);
    b.commit();
    opt.max_bounces = 0;
    blocker_middle[hidden] = middle(render(b, opt), size);
  }
  std::printf("lamp: shown %.4f, hidden %.4f; blocker under a sun: shown %.4f, hidden %.4f\n", lamp_middle[0],
              lamp_middle[1], blocker_middle[0], blocker_middle[1]);
  EXPECT_NEAR(lamp_middle[0], 4.0, 1e-4);
  EXPECT_GT(lamp_middle[1], 0.5);  // the lit floor, not black: the hidden lamp still emits
  EXPECT_LT(lamp_middle[1], 2.0);  // and not the lamp
  EXPECT_NEAR(blocker_middle[0], 0.5 / kPi, 1e-4);  // the blocker's top, lit by the sun
  EXPECT_EQ(blocker_middle[1], 0.0);                // the floor in its shadow
}

// The other ray kinds (visibility.h), each against the same scene without the
// setting, in closed form where there is one. Before Tessera modelled them,
// every setting below changed nothing.
namespace {
// The mean of the image's middle 4 x 4 pixels (red).
double middle4(const std::vector<float>& px, int size) {
  double m = 0.0;
  for (int y = size / 2 - 2; y < size / 2 + 2; ++y)
    for (int x = size / 2 - 2; x < size / 2 + 2; ++x) m += px[4 * (size_t(y) * size + x)] / 16.0;
  return m;
}
// A floor of material m under one light, seen from 2 above over [-e, e]^2:
// the middle 4 x 4 pixels.
double floor_middle(const Material& m, const Light& light, float e, RenderOptions opt) {
  Scene s;
  add_square(s, 0.0f, 50.0f, add_material(s, m));
  s.lights.push_back(light);
  look_down(s, 2.0f, e, 16);
  s.commit();
  return middle4(render(s, opt), 16);
}
Light overhead_sun() {
  Light sun;
  sun.type = LightType::Sun;
  sun.direction = vec3(0.0f, 0.0f, -1.0f);
  sun.radiance = vec3(1.0f);
  return sun;
}
}  // namespace

// A blocker with Shadow off, and a sun with Cast Shadow off: the floor under
// the blocker is lit as if it were not there, while the camera (looking
// along the sun from below the blocker's height) still sees the floor. A
// Lambert floor under a unit sun at normal incidence reads albedo / pi.
TEST(Visibility, ShadowOffOnTheBlockerOrTheLightLeavesTheFloorLit) {
  const Material lambert = with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)});
  double floor[3];
  for (int variant = 0; variant < 3; ++variant) {  // 0 shadowed, 1 blocker without Shadow, 2 sun without it
    Scene s;
    add_square(s, 0.0f, 50.0f, add_material(s, lambert));
    add_square(s, 3.0f, 0.6f, add_material(s, lambert));  // above the camera: only shadows
    if (variant == 1) s.instances.back().visibility &= ~kRayShadow;
    Light sun = overhead_sun();
    if (variant == 2) sun.visibility &= ~kRayShadow;
    s.lights.push_back(sun);
    look_down(s, 2.0f, 0.5f, 16);
    s.commit();
    RenderOptions opt;
    opt.samples = 4;
    opt.max_bounces = 0;
    floor[variant] = middle4(render(s, opt), 16);
  }
  std::printf("floor under the blocker: shadowed %.5f, blocker without Shadow %.5f, sun without it %.5f\n",
              floor[0], floor[1], floor[2]);
  EXPECT_EQ(floor[0], 0.0);
  EXPECT_NEAR(floor[1], 0.5 / kPi, 1e-5);
  EXPECT_NEAR(floor[2], 0.5 / kPi, 1e-5);
}

// A point light hidden from diffuse rays lights a Lambert floor not at all,
// and a glossy floor as before; hidden from glossy rays, the reverse. Light
// sampling leaves out the hidden kind's lobes (Cycles' _surface_shader_exclude).
TEST(Visibility, LightsHiddenFromARayKindLightOnlyTheOtherLobes) {
  const Material lambert = with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)});
  const Material glossy = with_closures({closure(ClosureKind::Glossy, 1, vec3(0.8f), 0.4f)});
  auto floor = [&](const Material& m, uint8_t light_visibility) {
    Light point;
    point.type = LightType::Point;
    point.position = vec3(0.0f, 0.0f, 1.0f);
    point.radiance = vec3(10.0f);
    point.visibility = light_visibility;
    RenderOptions opt;
    opt.samples = 16;
    opt.max_bounces = 0;
    return floor_middle(m, point, 0.5f, opt);
  };
  const uint8_t all = kLightDefaultVisibility;
  const double diffuse_lit = floor(lambert, all), diffuse_unseen = floor(lambert, all & ~kRayDiffuse);
  const double glossy_lit = floor(glossy, all), glossy_diffuse_off = floor(glossy, all & ~kRayDiffuse),
               glossy_unseen = floor(glossy, all & ~kRayGlossy);
  std::printf("Lambert floor: %.4f, light without Diffuse %.4f; glossy floor: %.4f, without Diffuse %.4f, "
              "without Glossy %.4f\n", diffuse_lit, diffuse_unseen, glossy_lit, glossy_diffuse_off, glossy_unseen);
  EXPECT_GT(diffuse_lit, 0.5);
  EXPECT_EQ(diffuse_unseen, 0.0);
  EXPECT_GT(glossy_lit, 0.1);
  EXPECT_EQ(glossy_diffuse_off, glossy_lit);
  EXPECT_EQ(glossy_unseen, 0.0);
}

// An emissive panel hidden from diffuse rays: the camera sees it, and a
// Lambert floor beside it gets none of its light (neither light sampling nor
// BSDF sampling finds it).
TEST(Visibility, EmitterHiddenFromDiffuseRaysLightsNoDiffuseSurface) {
  const Material lambert = with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)});
  Material lamp = lambert;
  lamp.emission_front = lamp.emission_back = vec3(4.0f);
  auto render_lamp = [&](uint8_t lamp_visibility) {
    Scene s;
    add_square(s, 0.0f, 50.0f, add_material(s, lambert));
    add_square(s, 0.5f, 0.45f, add_material(s, lamp));  // the middle 4 x 4 pixels (and filters) see only the lamp
    s.instances.back().visibility = lamp_visibility;
    look_down(s, 2.0f, 1.0f, 16);
    s.commit();
    RenderOptions opt;
    opt.samples = 64;
    opt.max_bounces = 1;
    return render(s, opt);
  };
  const std::vector<float> shown = render_lamp(kVisibleToAll);
  const std::vector<float> hidden = render_lamp(kVisibleToAll & ~kRayDiffuse);
  std::printf("lamp %.4f / %.4f, floor beside it %.5f / %.5f (shown / hidden from diffuse rays)\n",
              middle4(shown, 16), middle4(hidden, 16), shown[0], hidden[0]);
  EXPECT_NEAR(middle4(hidden, 16), 4.0, 1e-4);
  EXPECT_GT(shown[0], 0.001);
  EXPECT_EQ(hidden[0], 0.0);
}

// A Lambert floor (albedo 0.5) under a white sky, seen from above with the
// sky around it: the world hidden from the camera is black there and still
// lights the floor; a panel over the floor hidden from diffuse rays (and the
// camera) lets the floor under it see the whole sky (every sample exactly
// 0.5, as with no panel), where a panel seen by them shades it.
TEST(Visibility, WorldHiddenFromTheCameraAndPanelsHiddenFromDiffuseRays) {
  const Material lambert = with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)});
  auto render_sky = [&](uint8_t world_visibility, uint8_t panel_visibility) {
    Scene s;
    add_square(s, 0.0f, 0.5f, add_material(s, lambert));
    add_square(s, 0.3f, 0.3f, add_material(s, lambert));
    s.instances.back().visibility = panel_visibility;
    s.background.set_color(vec3(1.0f));
    s.background.set_visibility(world_visibility);
    look_down(s, 2.0f, 1.0f, 16);
    s.commit();
    RenderOptions opt;
    opt.samples = 16;
    opt.max_bounces = 1;
    return render(s, opt);
  };
  const uint8_t panel_shading = kVisibleToAll & ~kRayCamera, panel_unseen = kRayShadow;
  const std::vector<float> sky = render_sky(kRayCamera | kScatteredRays, panel_unseen);
  const std::vector<float> no_sky = render_sky(kScatteredRays, panel_unseen);
  const std::vector<float> shaded = render_sky(kRayCamera | kScatteredRays, panel_shading);
  std::printf("corner: world seen %.4f, unseen %.4f; floor under the panel: unseen %.4f, hidden from the camera "
              "only %.4f\n", sky[0], no_sky[0], middle4(no_sky, 16), middle4(shaded, 16));
  EXPECT_EQ(sky[0], 1.0f);
  EXPECT_EQ(no_sky[0], 0.0f);
  EXPECT_NEAR(middle4(sky, 16), 0.5, 1e-6);
  EXPECT_NEAR(middle4(no_sky, 16), 0.5, 1e-6);
  EXPECT_LT(middle4(shaded, 16), 0.4);
}

// An area light made visible to the camera is seen, with its radiance, by
// camera rays; by default (Blender's) it is not.
TEST(Visibility, AreaLightVisibleToTheCameraIsSeen) {
  auto middle_of = [](uint8_t visibility) {
    Light area;
    area.type = LightType::Area;
    area.position = vec3(0.0f, 0.0f, 1.0f);
    area.direction = vec3(0.0f, 0.0f, 1.0f);  // facing the camera above, away from the floor
    area.axis_u = vec3(0.5f, 0.0f, 0.0f);
    area.axis_v = vec3(0.0f, 0.5f, 0.0f);
    area.area = 1.0f;
    area.radiance = vec3(3.0f);
    area.visibility = visibility;
    RenderOptions opt;
    opt.samples = 4;
    return floor_middle(with_closures({closure(ClosureKind::Diffuse, 1, vec3(0.5f), 0.0f)}), area, 0.25f, opt);
  };
  const double unseen = middle_of(kLightDefaultVisibility), seen = middle_of(kLightDefaultVisibility | kRayCamera);
  std::printf("area light: default %.4f, visible to the camera %.4f\n", unseen, seen);
  EXPECT_EQ(unseen, 0.0);
  EXPECT_NEAR(seen, 3.0, 1e-5);
}
