#include "ggx_energy.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <array>
#include <vector>

#include "microfacet.h"

namespace tessera::ggx_energy {

float F0_from_ior(float ior) { return sqr((ior - 1.0f) / (ior + 1.0f)); }

float ior_from_F0(float f0) {
  const float s = std::sqrt(std::clamp(f0, 0.0f, 0.99f));
  return (1.0f + s) / (1.0f - s);
}

// The tables are built inside function-local statics, typically from a
// render task: the loop is isolated, so that while this thread waits for it
// TBB does not hand it another render task, which could reach the same static
// and wait for its own initialisation forever (it did: a render of a 4.x
// Cornell box hung).
std::vector<float> tabulate(int n, const std::function<float(int)>& entry) {
  std::vector<float> data(size_t(std::max(n, 0)));
  tbb::this_task_arena::isolate([&] { tbb::parallel_for(0, n, [&](int i) { data[i] = entry(i); }); });
  return data;
}

namespace {

// Stratified samples per entry: a grid of kRadial x kAngular cells of the
// unit square that sample_visible maps to the projected disk (u.x the squared
// radius, u.y the angle). The light a lobe loses is in the thin ring of the
// steepest microfacets (reflections below the horizon), so the radius gets
// the finer steps: 64 x 16 is within 5e-4 of 512 x 512 for every roughness
// (24 x 24 was 1.5% off at roughness 0.4). The Eavg tables integrate over
// kMuSteps view cosines.
struct Strata {
  int radial, angular;
};
constexpr Strata kStrata{64, 16};
constexpr Strata kFineStrata{128, 32};  // the 32 x 32 E table: cheap enough for more
constexpr int kMuSteps = 32;

// Grid point i of n on an axis, as Cycles places them.
float axis(int i, int n, float hi = 1.0f) { return std::clamp(float(i) / float(n - 1), 1e-4f, hi); }
// IOR of the z axis: F0 = z^4.
float ior_from_z(float z) { return ior_from_F0(sqr(sqr(z))); }

// E_{wm ~ D_wo}[g(wo, wm)] for the view direction at cosine mu, over visible
// normals of GGX with alpha = roughness^2: the mean of what one sample of
// Cycles' bsdf_microfacet_sample returns as eval / pdf when g is that.
template <class G>
double visible_normal_mean(float roughness, float mu, Strata strata, const G& g) {
  const GGX ggx{sqr(roughness)};
  const vec3 wo(safe_sqrt(1.0f - mu * mu), 0.0f, mu);
  double sum = 0.0;
  for (int i = 0; i < strata.radial; ++i)
    for (int j = 0; j < strata.angular; ++j) {
      const vec2 u((i + 0.5f) / strata.radial, (j + 0.5f) / strata.angular);
      sum += g(ggx, wo, ggx.sample_visible(wo, u));
    }
  return sum / double(strata.radial * strata.angular);
}

// The VNDF estimator of a lobe: f cos / pdf = G2(wo, wi) / G1(wo).
float masking_ratio(const GGX& ggx, const vec3& wo, const vec3& wi) {
  return (1.0f + ggx.lambda(wo)) / (1.0f + ggx.lambda(wo) + ggx.lambda(wi));
}

// Reflection with Fresnel 1: the energy the single-scattering lobe keeps.
float reflection_estimate(const GGX& ggx, const vec3& wo, const vec3& wm) {
  const vec3 wi = reflect(wo, wm);
  return wi.z > 0.0f ? masking_ratio(ggx, wo, wi) : 0.0f;
}

// Glass: reflection weighted F, refraction 1 - F (both continuations of one
// sample, which has the same mean as Cycles' choice between them by F).
float glass_estimate(float eta, const GGX& ggx, const vec3& wo, const vec3& wm) {
  const float F = fresnel_dielectric(glm::dot(wo, wm), eta);
  float e = 0.0f;
  const vec3 wr = reflect(wo, wm);
  if (wr.z > 0.0f) e += F * masking_ratio(ggx, wo, wr);
  vec3 wt;
  if (F < 1.0f && refract(wo, wm, eta, &wt) && wt.z < 0.0f) e += (1.0f - F) * masking_ratio(ggx, wo, wt);
  return e;
}

// Table of nz slices of ny x nx entries, data[(z * ny + y) * nx + x].
struct Table {
  int nx, ny, nz;
  std::vector<float> data;

  template <class F>
  Table(int nx_, int ny_, int nz_, const F& entry)
      : nx(nx_), ny(ny_), nz(nz_), data(tabulate(nx_ * ny_ * nz_, [&](int i) {
          return std::clamp(entry(i % nx_, (i / nx_) % ny_, i / (nx_ * ny_)), 0.0f, 1.0f);
        })) {}

  // Cycles' lookup_table_read / _2D / _3D: linear interpolation between grid
  // points at saturate(t) * (n - 1) along each axis.
  static void locate(float t, int n, int& i0, int& i1, float& f) {
    t = std::clamp(t, 0.0f, 1.0f) * float(n - 1);
    i0 = std::min(int(t), n - 1);
    i1 = std::min(i0 + 1, n - 1);
    f = t - float(i0);
  }
  float row(float x, int y, int z) const {
    int x0, x1;
    float fx;
    locate(x, nx, x0, x1, fx);
    const float* r = &data[(size_t(z) * ny + y) * nx];
    return (1.0f - fx) * r[x0] + fx * r[x1];
  }
  float slice(float x, float y, int z) const {
    int y0, y1;
    float fy;
    locate(y, ny, y0, y1, fy);
    return (1.0f - fy) * row(x, y0, z) + fy * row(x, y1, z);
  }
  float lookup(float x, float y = 0.0f, float z = 0.0f) const {
    int z0, z1;
    float fz;
    locate(z, nz, z0, z1, fz);
    return (1.0f - fz) * slice(x, y, z0) + fz * slice(x, y, z1);
  }
};

// 2 int_0^1 E(mu) mu dmu by the midpoint rule.
template <class E>
float cosine_average(const E& E_of_mu) {
  double sum = 0.0;
  for (int k = 0; k < kMuSteps; ++k) {
    const float mu = (k + 0.5f) / kMuSteps;
    sum += 2.0 * mu * E_of_mu(mu);
  }
  return float(sum / kMuSteps);
}

const Table& E_table() {
  static const Table t(32, 32, 1, [](int x, int y, int) {
    return float(visible_normal_mean(axis(x, 32), axis(y, 32), kFineStrata, reflection_estimate));
  });
  return t;
}

const Table& E_avg_table() {
  static const Table t(32, 1, 1, [](int x, int, int) {
    const float r = axis(x, 32);
    return cosine_average([&](float mu) { return visible_normal_mean(r, mu, kStrata, reflection_estimate); });
  });
  return t;
}

// Glass tables for eta = ior(z) (inverse: 1 / ior(z)).
const Table& glass_E_table(bool inverse) {
  auto make = [](bool inv) {
    return Table(16, 16, 16, [inv](int x, int y, int z) {
      const float ior = ior_from_z(axis(z, 16, 0.99f));
      const float eta = inv ? 1.0f / ior : ior;
      return float(visible_normal_mean(axis(x, 16), axis(y, 16), kStrata, [eta](const GGX& g, const vec3& wo, const vec3& wm) {
        return glass_estimate(eta, g, wo, wm);
      }));
    });
  };
  static const Table entering = make(false), leaving = make(true);
  return inverse ? leaving : entering;
}

const Table& glass_E_avg_table(bool inverse) {
  auto make = [](bool inv) {
    return Table(16, 16, 1, [inv](int x, int z, int) {
      const float ior = ior_from_z(axis(z, 16, 0.99f));
      const float eta = inv ? 1.0f / ior : ior;
      const float r = axis(x, 16);
      return cosine_average([&](float mu) {
        return visible_normal_mean(r, mu, kStrata, [eta](const GGX& g, const vec3& wo, const vec3& wm) {
          return glass_estimate(eta, g, wo, wm);
        });
      });
    });
  };
  static const Table entering = make(false), leaving = make(true);
  return inverse ? leaving : entering;
}

const Table& gen_schlick_ior_s_table() {
  static const Table t(16, 16, 16, [](int x, int y, int z) {
    const float ior = ior_from_z(axis(z, 16, 0.99f));
    const float F0 = F0_from_ior(ior);
    return float(visible_normal_mean(axis(x, 16), axis(y, 16), kStrata, [&](const GGX&, const vec3& wo, const vec3& wm) {
      if (reflect(wo, wm).z <= 0.0f) return 0.0f;
      // s = inverse_lerp(F0, 1, F): where the real Fresnel lies between F0 and 1.
      return std::clamp((fresnel_dielectric(glm::dot(wo, wm), ior) - F0) / (1.0f - F0), 0.0f, 1.0f);
    }));
  });
  return t;
}

const Table& schlick_s_table() {
  // Cycles' ggx_gen_schlick_s has slices z = k / 15 of exponent 5 (1 - z) / z;
  // read at z = 0.5 it is the mean of slices 7 and 8.
  static const Table t(16, 16, 1, [](int x, int y, int) {
    auto s_mean = [&](float exponent) {
      return visible_normal_mean(axis(x, 16), axis(y, 16), kStrata, [exponent](const GGX&, const vec3& wo, const vec3& wm) {
        return reflect(wo, wm).z > 0.0f ? std::pow(std::max(1.0f - glm::dot(wo, wm), 0.0f), exponent) : 0.0f;
      });
    };
    return float(0.5 * (s_mean(40.0f / 7.0f) + s_mean(35.0f / 8.0f)));
  });
  return t;
}

float z_of_eta(float eta) { return std::sqrt(std::abs((eta - 1.0f) / (eta + 1.0f))); }

}  // namespace

float E(float roughness, float mu) { return E_table().lookup(roughness, mu); }
float E_avg(float roughness) { return E_avg_table().lookup(roughness); }

float glass_E(float roughness, float mu, float eta) {
  const bool inverse = eta < 1.0f;
  const float ior = inverse ? 1.0f / eta : eta;
  return glass_E_table(inverse).lookup(roughness, mu, z_of_eta(ior));
}

float glass_E_avg(float roughness, float eta) {
  const bool inverse = eta < 1.0f;
  const float ior = inverse ? 1.0f / eta : eta;
  return glass_E_avg_table(inverse).lookup(roughness, z_of_eta(ior));
}

float gen_schlick_ior_s(float roughness, float mu, float eta) {
  return gen_schlick_ior_s_table().lookup(roughness, mu, z_of_eta(eta));
}

float schlick_s(float roughness, float mu) { return schlick_s_table().lookup(roughness, mu); }

}  // namespace tessera::ggx_energy
