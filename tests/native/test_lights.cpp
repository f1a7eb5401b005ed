// Light units and shapes that the add-on's Cycles conversions rely on
// (addon/tessera/export/lights.py): the sun disk carries its whole
// irradiance, and the spot edge with and without Cycles 3.x's cosine.
#include <gtest/gtest.h>

#include <cmath>

#include "core/render.h"
#include "scene_fixtures.h"

using namespace tessera;

namespace {

// A white diffuse floor at z = 0 seen from (0, 0, 2) looking down -z.
void floor_scene(Scene& s, const Light& light) {
  Material white;
  white.base_color = vec3(0.8f);
  white.roughness = 1.0f;
  white.specular = 0.0f;
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

// Cycles 4.0+ drops the cosine to the axis from the spot attenuation: with
// the camera at the light, every pixel sees the floor point whose direction
// from the light is the pixel's own, so the ratio of the two images is that
// direction's cosine to the axis.
TEST(Lights, SpotCosineFactorIsOptional) {
  Light spot;
  spot.type = LightType::Spot;
  spot.position = vec3(0, 0, 2);
  spot.direction = vec3(0, 0, -1);
  spot.spot_cos = std::cos(0.7f);
  spot.radiance = vec3(10.0f);
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
