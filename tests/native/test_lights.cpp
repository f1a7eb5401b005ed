// Light units and shapes that the add-on's Cycles conversions rely on
// (addon/tessera/export/lights.py): the sun disk carries its whole
// irradiance, the spot edge with and without Cycles 3.x's cosine, Cycles
// 4.x's sphere lights and elliptical spot cones.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/render.h"
#include "scene_fixtures.h"

using namespace tessera;

namespace {

// A white diffuse floor at z = 0 seen from (0, 0, 2) looking down -z
// (Lambertian if told: then the image is the irradiance x 0.8 / pi).
void floor_scene(Scene& s, const Light& light, bool lambert = false) {
  Material white;
  white.base_color = vec3(0.8f);
  white.roughness = 1.0f;
  white.specular = 0.0f;
  if (lambert) {
    white.kind = ClosureKind::Diffuse;
    white.roughness = 0.0f;
  }
  s.materials.push_back(white);
  fixtures::add_quad(s, {-20, -20, 0}, {20, -20, 0}, {20, 20, 0}, {-20, 20, 0}, 1);
  s.lights.push_back(light);
  s.camera.to_world = mat4(1.0f);
  s.camera.to_world[3] = vec4(0, 0, 2, 1);
  s.camera.width = s.camera.height = 16;
  s.commit();
}

std::vector<float> render(const Scene& s, int spp = 16) {
  RenderOptions opt;
  opt.samples = spp;
  opt.max_bounces = 0;
  opt.filter_width = 1e-3f;  // pixel centres only: values comparable per pixel
  RenderSession session(s, opt);
  session.render();
  return session.pixels();
}

double mean_rgb(const std::vector<float>& px) {
  double m = 0.0;
  for (size_t i = 0; i < px.size(); ++i)
    if (i % 4 != 3) m += px[i];
  return m / (px.size() / 4 * 3);
}

}  // namespace

// Regression: the sun disk was light-sampled with an MIS weight as if
// scattered rays could hit it, but they never do, so a wide sun lost part of
// its light (a 1.2 rad sun ~10% dark, Blender test_lights sun_wide).
TEST(Lights, SunDiskGivesTheIrradianceOfItsSolidAngle) {
  const float half = 0.6f;
  Light disk;
  disk.type = LightType::Sun;
  disk.direction = vec3(0, 0, -1);
  disk.radius = std::tan(half);
  disk.radiance = vec3(1.0f);
  Light delta = disk;
  delta.radius = 0.0f;
  // Irradiance of a uniform cone of half angle h at normal incidence: L pi sin^2 h.
  delta.radiance = vec3(kPi * std::sin(half) * std::sin(half));
  Scene a, b;
  floor_scene(a, disk);
  floor_scene(b, delta);
  const double m_disk = mean_rgb(render(a, 64)), m_delta = mean_rgb(render(b, 4));
  EXPECT_NEAR(m_disk / m_delta, 1.0, 0.01) << m_disk << " vs " << m_delta;
}

namespace {

// A spot 2 above the floor pointing straight down, with the given half angle.
Light spot_above_floor(float half_angle) {
  Light spot;
  spot.type = LightType::Spot;
  spot.position = vec3(0, 0, 2);
  spot.direction = vec3(0, 0, -1);
  spot.spot_cos = std::cos(half_angle);
  spot.radiance = vec3(10.0f);
  return spot;
}

}  // namespace

// Cycles 4.0+ drops the cosine to the axis from the spot attenuation: with
// the camera at the light, every pixel sees the floor point whose direction
// from the light is the pixel's own, so the ratio of the two images is that
// direction's cosine to the axis.
TEST(Lights, SpotCosineFactorIsOptional) {
  const Light spot = spot_above_floor(0.7f);
  Light flat = spot;
  flat.spot_cosine = false;
  Scene a, b;
  floor_scene(a, spot);
  floor_scene(b, flat);
  const std::vector<float> with = render(a, 1), without = render(b, 1);
  const Camera& c = a.camera;
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const Ray r = c.generate_ray(vec2(x + 0.5f, y + 0.5f));
      const size_t i = 4 * (size_t(y) * c.width + x);
      ASSERT_GT(without[i], 0.0f);
      EXPECT_NEAR(with[i] / without[i], -r.d.z, 1e-3) << x << "," << y;
    }
}

namespace {

Light sphere_light(vec3 position, float radius, float radiance) {
  Light l;
  l.type = LightType::Point;
  l.position = position;
  l.radius = radius;
  l.sphere = true;
  l.radiance = vec3(radiance);
  return l;
}

// Integral over all directions from p of the density intersect_lights gives
// for light `which` (0 where the ray misses it): 1 for a density, on a
// stratified grid uniform in (cos theta, phi).
double pdf_integral(const LightSampler& lights, int which, const vec3& p, const vec3& n, int k = 1024) {
  double sum = 0.0;
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j) {
      const vec3 d = sample_uniform_sphere(vec2((i + 0.5f) / k, (j + 0.5f) / k));
      float t, pdf;
      vec3 le;
      if (lights.intersect_lights(p, d, kInf, &t, &le, &pdf, p, n, kRayDiffuse) == which) sum += pdf;
    }
  return sum * 4.0 * kPi / (double(k) * k);
}

}  // namespace

// Cycles 4.x's sphere light (point/spot, Soft Falloff off) is sampled in the
// cone it subtends from outside, over all directions from inside: the
// density that scattered rays hitting it get for MIS integrates to 1 over
// the directions that reach it, near and far, inside and out. The disk of
// Cycles 3.x (and 4.x's Soft Falloff) likewise.
TEST(Lights, SphereLightPdfIntegratesToOne) {
  for (bool sphere : {true, false}) {
    Light l = sphere_light(vec3(0.3f, -0.2f, 1.0f), 0.5f, 1.0f);
    l.sphere = sphere;
    LightSampler lights;
    lights.build({l}, {}, nullptr, 10.0f);
    const vec3 n(0.0f, 0.0f, 1.0f);
    for (vec3 p : {vec3(0.0f), vec3(0.3f, 0.4f, 1.2f), vec3(2.0f, 1.0f, -3.0f), vec3(0.3f, -0.2f, 0.7f),
                   vec3(0.35f, -0.2f, 1.1f)}) {
      const bool inside = glm::length(p - l.position) < l.radius;
      if (inside && !sphere) continue;  // no disk from inside
      EXPECT_NEAR(pdf_integral(lights, 0, p, n), 1.0, 5e-3) << "sphere " << sphere << " p " << p.x << "," << p.y << "," << p.z;
    }
  }
}

// What sample() reports for a hittable point or spot light (direction,
// distance, radiance, density) is what a scattered ray in that direction
// finds through intersect_lights, so that light sampling and BSDF sampling
// weigh the same light alike in MIS. Several lights, so that the density
// includes the choice of light by the shading point and normal: the disk's
// density was computed with the disk's normal in place of the shading
// normal (a shadowed variable), which changes the choice's probability.
TEST(Lights, PointAndSpotSampleAndHitAgree) {
  Light sphere = sphere_light(vec3(0.0f, 0.0f, 1.0f), 0.4f, 2.0f);
  Light disk = sphere_light(vec3(3.0f, 0.0f, 1.5f), 0.3f, 3.0f);
  disk.sphere = false;
  Light spot = sphere_light(vec3(-2.0f, 1.0f, 2.0f), 0.5f, 4.0f);
  spot.type = LightType::Spot;
  spot.direction = glm::normalize(vec3(0.2f, -0.1f, -1.0f));
  spot.spot_cos = std::cos(0.8f);
  spot.spot_smooth = 0.1f;
  spot.spot_cosine = false;
  spot.spot_scaled = true;  // scaled 1.5 x 1 x 1 about its own axes
  const Frame f(-spot.direction);
  const glm::mat3 to_world(1.5f * f.t, f.b, f.n);  // columns: the object's x, y, z (it emits along -z)
  spot.spot_to_local = glm::inverse(to_world);
  Light spot_disk = spot;
  spot_disk.position = vec3(0.0f, -3.0f, 2.0f);
  spot_disk.sphere = false;
  LightSampler lights;
  lights.build({sphere, disk, spot, spot_disk}, {}, nullptr, 10.0f);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  int checked[4] = {0, 0, 0, 0};
  for (int i = 0; i < 20000; ++i) {
    const vec3 p(6.0f * U(rng) - 3.0f, 6.0f * U(rng) - 3.0f, 1.2f * U(rng));
    const vec3 n = glm::normalize(sample_uniform_sphere(vec2(U(rng), U(rng))) + vec3(0.0f, 0.0f, 0.7f));
    LightSample ls;
    if (!lights.sample(p, n, vec2(U(rng), U(rng)), ls)) continue;
    ASSERT_FALSE(ls.is_delta);
    float t, pdf;
    vec3 le;
    const int hit = lights.intersect_lights(p, ls.wi, kInf, &t, &le, &pdf, p, n, kRayDiffuse);
    ASSERT_GE(hit, 0) << p.x << "," << p.y << "," << p.z;
    if (t < 0.999f * ls.dist) continue;  // another light lies in front of the sampled one
    ++checked[hit];
    EXPECT_NEAR(t, ls.dist, 1e-4f * (1.0f + ls.dist)) << hit;
    EXPECT_NEAR(le.x, ls.li.x, 1e-4f * ls.li.x) << hit;
    EXPECT_NEAR(pdf, ls.pdf, 2e-3f * ls.pdf) << hit << " at " << p.x << "," << p.y << "," << p.z;
  }
  for (int k = 0; k < 4; ++k) EXPECT_GT(checked[k], 100) << k;
}

// A sphere light entirely above the floor gives every floor point exactly
// the irradiance of a point light of the same power (Cycles 4.x's sphere,
// unlike the disk facing the point, which gives d^2 / (d^2 + r^2) of it).
// The floor is Lambertian, so the images agree pixel by pixel.
TEST(Lights, SphereLightGivesAPointLightsIrradiance) {
  const float r = 0.6f, L = 5.0f;
  Light sphere = sphere_light(vec3(0.1f, 0.0f, 0.8f), r, L);
  Light point = sphere;
  point.radius = 0.0f;
  point.radiance = vec3(L * kPi * r * r);  // intensity: power / (4 pi) with power 4 pi^2 r^2 L
  Scene a, b;
  floor_scene(a, sphere, true);
  floor_scene(b, point, true);
  const std::vector<float> ia = render(a, 256), ib = render(b, 4);
  double worst = 0.0;
  for (size_t i = 0; i < ia.size(); i += 4) worst = std::max(worst, std::abs(double(ia[i]) / ib[i] - 1.0));
  EXPECT_LT(worst, 0.01);
  EXPECT_NEAR(mean_rgb(ia) / mean_rgb(ib), 1.0, 2e-3);
}

// Cycles 4.x measures a spot's angle in the light's own space: scaled 1.8
// times along its x axis, the cone reaches 1.8 times as far (in tangent)
// along x as along y. The camera sits at the light, so each pixel sees the
// floor point in the pixel's own direction from the light.
TEST(Lights, ScaledSpotConeIsElliptical) {
  Light spot = spot_above_floor(0.25f);
  spot.spot_cosine = false;
  spot.spot_scaled = true;
  spot.spot_to_local = glm::inverse(glm::mat3(vec3(1.8f, 0, 0), vec3(0, 1, 0), vec3(0, 0, 1)));
  Scene s;
  floor_scene(s, spot);
  const std::vector<float> px = render(s, 1);
  const Camera& c = s.camera;
  const float tan_edge = std::tan(0.25f);
  int lit_outside_round = 0;
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const Ray ray = c.generate_ray(vec2(x + 0.5f, y + 0.5f));
      const float tx = ray.d.x / -ray.d.z / 1.8f, ty = ray.d.y / -ray.d.z;  // tangents in the light's space
      const float e = std::sqrt(tx * tx + ty * ty) / tan_edge;              // 1 on the cone
      const float v = px[4 * (size_t(y) * c.width + x)];
      if (e < 0.97f) EXPECT_GT(v, 0.0f) << x << "," << y;
      if (e > 1.03f) EXPECT_EQ(v, 0.0f) << x << "," << y;
      const float t_round = std::hypot(ray.d.x, ray.d.y) / -ray.d.z / tan_edge;
      if (e < 0.97f && t_round > 1.1f) ++lit_outside_round;
    }
  EXPECT_GT(lit_outside_round, 4);
}

namespace {

// Area light over the floor z = 0: centre (0, 0, 1), tilted 20 degrees about
// x, half extents 0.5 x 0.3, radiance 1, with the spread given in degrees
// (Cycles' normalisation, as export/lights.py area_spread computes it).
Light spread_area_light(float spread_deg, bool ellipse) {
  Light l;
  l.type = LightType::Area;
  l.position = vec3(0.0f, 0.0f, 1.0f);
  const float tilt = 20.0f * kPi / 180.0f;
  l.direction = vec3(0.0f, std::sin(tilt), -std::cos(tilt));
  l.axis_u = vec3(0.5f, 0.0f, 0.0f);
  l.axis_v = 0.3f * vec3(0.0f, std::cos(tilt), std::sin(tilt));
  l.ellipse = ellipse;
  l.area = 4.0f * 0.5f * 0.3f * (ellipse ? kPi / 4.0f : 1.0f);
  l.radiance = vec3(1.0f);
  const double half = 0.5 * spread_deg * kPi / 180.0;
  l.spread_tan = float(std::tan(half));
  l.spread_norm = float(1.0 / (std::tan(half) - half));
  return l;
}

// Irradiance at p (normal +z) from light l by brute force: the attenuated
// radiance integrated over the light's surface on an n x n midpoint grid,
// in double.
double brute_force_irradiance(const Light& l, const glm::dvec3& p, int n = 800) {
  const glm::dvec3 c(l.position), du(l.axis_u), dv(l.axis_v), nl(l.direction);
  const double tan_h = double(l.spread_tan), norm = double(l.spread_norm);
  const double cell = 4.0 * glm::length(du) * glm::length(dv) / (double(n) * n);
  double e = 0.0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double a = -1.0 + (2.0 * i + 1.0) / n, b = -1.0 + (2.0 * j + 1.0) / n;
      if (l.ellipse && a * a + b * b > 1.0) continue;
      const glm::dvec3 q = c + a * du + b * dv;
      const glm::dvec3 w = q - p;
      const double d2 = glm::dot(w, w), d = std::sqrt(d2);
      const double cos_p = w.z / d, cos_l = -glm::dot(w, nl) / d;
      if (cos_p <= 0.0 || cos_l <= 0.0) continue;
      const double tan_a = std::sqrt(std::max(0.0, 1.0 - cos_l * cos_l)) / cos_l;
      const double atten = std::max((tan_h - tan_a) * norm, 0.0);
      e += atten * cos_p * cos_l / d2 * cell;
    }
  return e;
}

}  // namespace

// Cycles' area light Spread: the irradiance from light sampling and from
// BSDF-style rays that hit the light (cosine-weighted directions) both equal
// the integral of the attenuated radiance over the light, at points under
// it, off its axis and where the spread cuts the light; zero where no part of
// the light is within the spread; and a hit reports the density with which
// sample() produces that direction (clipped region included), for MIS.
TEST(Lights, AreaSpreadSampledAndHitAgreeWithBruteForce) {
  const vec3 n(0.0f, 0.0f, 1.0f);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uni(0.0f, 0x1.fffffep-1f);
  for (float spread : {30.0f, 90.0f})
    for (bool ellipse : {false, true}) {
      LightSampler lights;
      lights.build({spread_area_light(spread, ellipse)}, {}, nullptr, 10.0f);
      for (vec3 p : {vec3(0.0f, 0.0f, 0.0f), vec3(0.3f, 0.5f, 0.0f), vec3(0.6f, -0.2f, 0.0f), vec3(-0.2f, 0.8f, 0.0f),
                     vec3(1.2f, 0.0f, 0.0f), vec3(0.0f, -1.5f, 0.0f)}) {
        SCOPED_TRACE(testing::Message() << "spread " << spread << (ellipse ? " ellipse" : " rectangle") << " at ("
                                        << p.x << ", " << p.y << ")");
        const double ref = brute_force_irradiance(lights.lights()[0], glm::dvec3(p));
        const int N = 200000;
        double e_light = 0.0, e_hit = 0.0, e2_light = 0.0, e2_hit = 0.0;
        int pdf_checked = 0;
        for (int i = 0; i < N; ++i) {
          const vec2 u((i + uni(rng)) / N, uni(rng));
          LightSample ls;
          if (lights.sample(p, n, u, ls)) {
            const float cos_p = glm::dot(ls.wi, n);
            const double x = cos_p > 0.0f ? double(ls.li.x) * cos_p / ls.pdf : 0.0;
            e_light += x;
            e2_light += x * x;
            if (i % 64 == 0) {  // the hit sees the same radiance and density
              float t, pdf;
              vec3 le;
              ASSERT_EQ(lights.intersect_lights(p, ls.wi, kInf, &t, &le, &pdf, p, n, kRayDiffuse), 0);
              EXPECT_NEAR(pdf / ls.pdf, 1.0f, 2e-3f);
              EXPECT_NEAR(le.x / ls.li.x, 1.0f, 2e-3f);
              ++pdf_checked;
            }
          }
          const vec3 wi = sample_cosine_hemisphere(vec2(uni(rng), uni(rng)));  // around +z
          float t, pdf;
          vec3 le;
          if (lights.intersect_lights(p, wi, kInf, &t, &le, &pdf, p, n, kRayDiffuse) == 0) {
            e_hit += double(le.x) * kPi;
            e2_hit += double(le.x) * kPi * double(le.x) * kPi;
          }
        }
        e_light /= N;
        e_hit /= N;
        // Standard errors of both estimates: they must agree within 4 of them.
        const double sd_light = std::sqrt(std::max(0.0, e2_light / N - e_light * e_light) / N);
        const double sd_hit = std::sqrt(std::max(0.0, e2_hit / N - e_hit * e_hit) / N);
        if (ref == 0.0) {
          EXPECT_EQ(e_light, 0.0);
          EXPECT_EQ(e_hit, 0.0);
          continue;
        }
        EXPECT_GT(pdf_checked, 0);
        EXPECT_LT(sd_light, 0.005 * ref);  // the clipped sampling keeps light sampling precise
        EXPECT_NEAR(e_light, ref, 4.0 * sd_light + 2e-3 * ref) << "light sampling, +- " << sd_light;
        EXPECT_NEAR(e_hit, ref, 4.0 * sd_hit + 2e-3 * ref) << "hits, +- " << sd_hit;
      }
    }
}

// Spread keeps the light's power (Cycles' normalisation): the irradiance on
// a floor much larger than the light's footprint, integrated, is the same
// with any spread. Through the brute-force integral, which the test above
// ties to the sampler.
TEST(Lights, AreaSpreadKeepsThePower) {
  auto flux = [](const Light& l) {
    double f = 0.0;
    const int k = 80;
    const double half = 8.0, cell = (2.0 * half / k) * (2.0 * half / k);
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j)
        f += brute_force_irradiance(l, glm::dvec3(-half + (i + 0.5) * 2.0 * half / k, -half + (j + 0.5) * 2.0 * half / k, 0.0),
                                    60) * cell;
    return f;
  };
  const double f30 = flux(spread_area_light(30.0f, false)), f90 = flux(spread_area_light(90.0f, false));
  EXPECT_NEAR(f30 / f90, 1.0, 0.02) << f30 << " vs " << f90;
}
