// Caustic light paths (light_tracer.h): a glass ball under a small spot light
// focuses it onto a rough floor. Light tracing takes over the paths camera ->
// floor -> glass -> light from the path tracer: the image's expectation must
// stay the same, its caustic far less noisy, and the light image the same
// with any number of threads.
#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>
#include <cmath>
#include <vector>

#include "core/light_tracer.h"
#include "render_fixtures.h"
#include "scene_fixtures.h"

using namespace tessera;
using namespace tessera::fixtures;

namespace {

constexpr int kSize = 32;

// Floor z = 0, a smooth-shaded glass ball of radius 0.5 at height 0.8, a spot
// light of radius `radius` 3 above it pointing down, the camera looking down
// at the ball's shadow from the side.
void caustic_scene(Scene& s, float radius = 0.3f) {
  Material floor;  // Principled: diffuse and a rough specular lobe
  floor.base_color = vec3(0.8f);
  Material glass;
  glass.base_color = vec3(1.0f);
  glass.transmission = 1.0f;
  glass.roughness = 0.0f;
  glass.ior = 1.5f;
  s.materials.push_back(floor);
  s.materials.push_back(glass);
  add_quad(s, {-3, -3, 0}, {3, -3, 0}, {3, 3, 0}, {-3, 3, 0}, 1);
  static const SphereMesh ball = uv_sphere(24, 48, 0.5f, vec3(0, 0, 0.8f));
  std::vector<float> normals;
  for (uint32_t v : ball.idx) {
    const vec3 p(ball.pos[3 * v], ball.pos[3 * v + 1], ball.pos[3 * v + 2]);
    const vec3 n = glm::normalize(p - vec3(0, 0, 0.8f));
    normals.insert(normals.end(), {n.x, n.y, n.z});
  }
  MeshInput in = mesh_input(ball.pos, ball.idx);
  in.corner_normals = normals.data();
  s.meshes.push_back(build_mesh(in));
  s.add_instance(uint32_t(s.meshes.size() - 1), mat4(1.0f), {2});
  Light spot;
  spot.type = LightType::Spot;
  spot.position = vec3(0, 0, 3);
  spot.direction = vec3(0, 0, -1);
  spot.spot_cos = std::cos(0.4f);
  spot.spot_smooth = 0.05f;
  spot.radius = radius;
  spot.radiance = vec3(3.0f / (radius * radius));  // the same power whatever the radius
  s.lights.push_back(spot);
  Camera& c = s.camera;
  c.to_world = glm::inverse(glm::lookAt(vec3(0.0f, -2.5f, 2.5f), vec3(0.0f, 0.0f, 0.2f), vec3(0, 0, 1)));
  c.left = c.bottom = -0.45f;
  c.right = c.top = 0.45f;
  c.clip_start = 0.01f;
  c.clip_end = 100.0f;
  c.width = c.height = kSize;
  s.commit();
}

RenderOptions options(float light_paths, int samples, uint32_t seed) {
  RenderOptions o;
  o.samples = samples;
  o.seed = seed;
  o.caustic_light_paths = light_paths;
  o.estimate_error = false;
  return o;
}

// Means over 8 x 8 pixel blocks, RGB averaged.
std::vector<double> blocks(const std::vector<float>& px) {
  std::vector<double> b(16, 0.0);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x)
      for (int k = 0; k < 3; ++k) b[size_t(y / 8) * 4 + x / 8] += px[4 * (size_t(y) * kSize + x) + k] / (64.0 * 3.0);
  return b;
}

// Sum over pixels and channels of the squared difference of two renders.
double squared_difference(const std::vector<float>& a, const std::vector<float>& b) {
  double d = 0.0;
  for (size_t i = 0; i < a.size(); ++i)
    if (i % 4 != 3) d += double(a[i] - b[i]) * (a[i] - b[i]);
  return d;
}

}  // namespace

TEST(LightTracing, KeepsTheImage) {
  Scene s;
  caustic_scene(s);
  // Path tracing alone (more samples: its caustic is the noisy one) against
  // path tracing with light tracing, each over seeds; block means compared
  // against their spread over the seeds. Blocks under 2% of the brightest
  // are left out: glints of the light in the ball that light tracing finds
  // on the far floor, path tracing finds a few times in a million samples
  // (its seeds then agree on nothing and say nothing of their error).
  constexpr int kSeeds = 4;
  std::vector<std::vector<double>> pt, lt;
  for (uint32_t seed = 0; seed < kSeeds; ++seed) {
    const Result a = render(s, options(0.0f, 512, seed));
    const Result b = render(s, options(0.25f, 128, seed));
    EXPECT_EQ(a.stats.light_paths, 0u);
    EXPECT_EQ(b.stats.light_paths, uint64_t(0.25 * 128 * kSize * kSize));
    pt.push_back(blocks(a.px)), lt.push_back(blocks(b.px));
  }
  auto mean_sd = [&](const std::vector<std::vector<double>>& v, size_t k, double* sd) {
    double m = 0.0, var = 0.0;
    for (int i = 0; i < kSeeds; ++i) m += v[i][k] / kSeeds;
    for (int i = 0; i < kSeeds; ++i) var += (v[i][k] - m) * (v[i][k] - m) / (kSeeds - 1);
    *sd = std::sqrt(var / kSeeds);
    return m;
  };
  double brightest = 0.0, sd;
  for (size_t k = 0; k < 16; ++k) brightest = std::max(brightest, mean_sd(pt, k, &sd));
  double largest_z = 0.0, total_pt = 0.0, total_lt = 0.0;
  int compared = 0;
  for (size_t k = 0; k < 16; ++k) {
    double sd_pt, sd_lt;
    const double m_pt = mean_sd(pt, k, &sd_pt), m_lt = mean_sd(lt, k, &sd_lt);
    total_pt += m_pt, total_lt += m_lt;
    if (m_pt < 0.02 * brightest) continue;
    ++compared;
    const double se = std::sqrt(sd_pt * sd_pt + sd_lt * sd_lt) + 0.005 * m_pt;
    largest_z = std::max(largest_z, std::abs(m_lt - m_pt) / se);
    EXPECT_NEAR(m_lt, m_pt, 5.0 * se) << "block " << k;
  }
  std::printf("%d blocks compared, largest difference %.2f standard errors; image means %.5f and %.5f\n", compared,
              largest_z, total_pt / 16, total_lt / 16);
  EXPECT_GE(compared, 10);
  EXPECT_NEAR(total_lt, total_pt, 0.03 * total_pt);
}

// A 5 cm light: the caustic that path tracing finds only now and then, and
// light tracing at every path through the ball. The noise is the squared
// difference between two seeds' images, at equal samples.
TEST(LightTracing, TakesTheNoiseOutOfTheCaustic) {
  Scene s;
  caustic_scene(s, 0.05f);
  const Result a0 = render(s, options(0.0f, 64, 0)), a1 = render(s, options(0.0f, 64, 1));
  const Result b0 = render(s, options(0.25f, 64, 0)), b1 = render(s, options(0.25f, 64, 1));
  const double noise_pt = squared_difference(a0.px, a1.px), noise_lt = squared_difference(b0.px, b1.px);
  std::printf("squared difference between seeds: path tracing %.4g, with light tracing %.4g\n", noise_pt, noise_lt);
  EXPECT_LT(noise_lt, 0.2 * noise_pt);
}

TEST(LightTracing, TheImageDoesNotDependOnTheThreads) {
  Scene s;
  caustic_scene(s);
  const Result r = render_on_one_and_all_threads(s, options(0.25f, 16, 3));
  EXPECT_GT(r.stats.light_paths, 0u);
}

// Where the two halves would count different paths, or nothing can make a
// caustic, no light paths are traced and the path tracer keeps them all.
TEST(LightTracing, OnlyWhereTheSceneAndSettingsAllowIt) {
  auto light_paths = [](Scene& s, RenderOptions o) { return render(s, o).stats.light_paths; };
  {
    Scene s;
    caustic_scene(s);
    EXPECT_GT(light_paths(s, options(0.25f, 2, 0)), 0u);
    EXPECT_EQ(light_paths(s, options(0.0f, 2, 0)), 0u);
    RenderOptions clamped = options(0.25f, 2, 0);
    clamped.clamp_indirect = 10.0f;
    EXPECT_EQ(light_paths(s, clamped), 0u);
    RenderOptions kinds = options(0.25f, 2, 0);
    kinds.max_transmission_bounces = 2;
    EXPECT_EQ(light_paths(s, kinds), 0u);
    RenderOptions pinpoint = options(0.25f, 2, 0);
    pinpoint.filter_width = 0.01f;
    EXPECT_EQ(light_paths(s, pinpoint), 0u);
    RenderOptions region = options(0.25f, 2, 0);
    region.region_x0 = 4, region.region_x1 = 20, region.region_y0 = 4, region.region_y1 = 20;
    EXPECT_EQ(light_paths(s, region), 0u);
  }
  {
    Scene s;  // depth of field
    caustic_scene(s);
    s.camera.aperture_radius = 0.05f;
    EXPECT_EQ(light_paths(s, options(0.25f, 2, 0)), 0u);
  }
  {
    Scene s;  // a rough ball: no delta surface
    caustic_scene(s);
    s.materials[2].roughness = 0.3f;
    EXPECT_EQ(light_paths(s, options(0.25f, 2, 0)), 0u);
  }
  {
    Scene s;  // a light of radius 0: rays never hit it, the path tracer has no such paths
    caustic_scene(s, 0.0f);
    EXPECT_EQ(light_paths(s, options(0.25f, 2, 0)), 0u);
  }
}
