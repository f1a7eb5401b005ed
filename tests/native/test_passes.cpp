// Render passes besides Combined (passes.h): first-hit data averaged over a
// pixel's samples, as Cycles writes them.
#include <gtest/gtest.h>

#include <cmath>

#include "core/render.h"
#include "scene_fixtures.h"

using namespace tessera;

namespace {

// A floor (z = 0, 8 x 8) with one material, under a camera at height 3
// looking down, whose frame also shows the background beyond the floor.
void floor_scene(Scene& s, const Material& m, int size = 24) {
  s.materials.push_back(m);
  fixtures::add_quad(s, {-4, -4, 0}, {4, -4, 0}, {4, 4, 0}, {-4, 4, 0}, 1);
  Light sun;
  sun.type = LightType::Sun;
  sun.direction = glm::normalize(vec3(0.2f, 0.1f, -1.0f));
  sun.radiance = vec3(2.0f);
  s.lights.push_back(sun);
  s.camera.to_world = mat4(1.0f);
  s.camera.to_world[3] = vec4(0, 0, 3, 1);
  // The frame spans +-6 at the floor's depth (0.5 per pixel at 24 pixels):
  // the floor covers the middle, the background the border.
  s.camera.left = s.camera.bottom = -2.0f;
  s.camera.right = s.camera.top = 2.0f;
  s.camera.width = s.camera.height = size;
  s.commit();
}

struct Rendered {
  std::vector<float> combined;
  std::vector<std::vector<float>> passes;  // by PassBits bit index
};

Rendered render(const Scene& s, uint32_t passes, int spp = 8, float alpha_threshold = 0.5f) {
  RenderOptions opt;
  opt.samples = spp;
  opt.max_bounces = 2;
  opt.passes = passes;
  opt.pass_alpha_threshold = alpha_threshold;
  RenderSession session(s, opt);
  session.render();
  Rendered r{session.pixels(), {}};
  for (int b = 0; b < kNumDataPasses; ++b) r.passes.push_back(session.pass_pixels(1u << b));
  return r;
}

// Where the centre of pixel (x, y) meets the plane z = 0.
vec3 floor_point(const Camera& c, int x, int y) {
  const Ray r = c.generate_ray(vec2(x + 0.5f, y + 0.5f));
  return r.o + r.d * (-r.o.z / r.d.z);
}

}  // namespace

TEST(Passes, NoneEnabledMeansNoPassPixels) {
  Scene s;
  Material m;
  floor_scene(s, m, 8);
  const Rendered r = render(s, 0, 2);
  for (const auto& p : r.passes) EXPECT_TRUE(p.empty());
}

TEST(Passes, CombinedIsTheSameWithPassesOn) {
  // The passes only record; the paths and their random numbers are unchanged.
  Scene s;
  Material m;
  m.roughness = 0.3f;
  floor_scene(s, m, 12);
  const Rendered off = render(s, 0, 4), on = render(s, kPassAllData, 4);
  ASSERT_EQ(off.combined.size(), on.combined.size());
  for (size_t i = 0; i < off.combined.size(); ++i) ASSERT_EQ(off.combined[i], on.combined[i]) << i;
}

TEST(Passes, FirstHitDataOnTheFloorAndTheBackground) {
  Scene s;
  Material m;
  m.base_color = vec3(0.6f, 0.4f, 0.2f);
  m.metallic = 0.25f;
  m.transmission = 0.0f;
  m.roughness = 0.8f;
  m.emission_front = vec3(0.5f, 0.25f, 0.125f);
  floor_scene(s, m);
  const Rendered r = render(s, kPassAllData);
  const Camera& c = s.camera;
  const vec3 diffuse = (1.0f - m.metallic) * m.base_color;
  int floor_pixels = 0, background_pixels = 0;
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const size_t i = size_t(y) * c.width + x;
      const float* depth = &r.passes[0][i];
      const float* normal = &r.passes[1][3 * i];
      const float* diffcol = &r.passes[2][3 * i];
      const float* emit = &r.passes[3][3 * i];
      const float* dn_normal = &r.passes[4][3 * i];
      const float* dn_depth = &r.passes[6][i];
      const Ray ray = c.generate_ray(vec2(x + 0.5f, y + 0.5f));
      const vec3 p = floor_point(c, x, y);
      // The filter reaches 1.5 pixels (0.75) from a pixel's centre.
      const float reach = std::max(std::abs(p.x), std::abs(p.y));
      if (reach < 4.0f - 0.8f) {
        ++floor_pixels;
        // Camera-space z, not the ray length (which grows off-centre).
        EXPECT_NEAR(depth[0], 3.0f, 1e-4f) << x << "," << y;
        EXPECT_NEAR(normal[0], 0.0f, 1e-5f);
        EXPECT_NEAR(normal[1], 0.0f, 1e-5f);
        EXPECT_NEAR(normal[2], 1.0f, 1e-5f);
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(diffcol[k], diffuse[k], 1e-5f);
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(emit[k], m.emission_front[k], 1e-5f);
        // Camera space (Cycles): the floor faces the camera, z forward.
        EXPECT_NEAR(dn_normal[2], -1.0f, 1e-5f);
        // The camera ray's length from the near clip plane (Cycles' ray_length).
        EXPECT_NEAR(dn_depth[0], (3.0f - c.clip_start) / -ray.d.z, 0.02f * dn_depth[0]);  // over the footprint
      } else if (reach > 4.0f + 0.8f) {
        ++background_pixels;
        EXPECT_EQ(depth[0], 1e10f);  // Cycles: nothing hit
        for (int k = 0; k < 3; ++k) EXPECT_EQ(normal[k], 0.0f);
      }
    }
  EXPECT_GT(floor_pixels, 100);
  EXPECT_GT(background_pixels, 20);
}

TEST(Passes, BackFacesReportTheNormalTowardsTheCamera) {
  Scene s;
  Material m;
  floor_scene(s, m, 8);
  // Seen from below: the camera at z = -3 looking up (+z).
  s.camera.to_world = mat4(vec4(1, 0, 0, 0), vec4(0, -1, 0, 0), vec4(0, 0, -1, 0), vec4(0, 0, -3, 1));
  const Rendered r = render(s, kPassNormal | kPassDepth, 2);
  const size_t centre = size_t(4) * 8 + 4;
  EXPECT_NEAR(r.passes[1][3 * centre + 2], -1.0f, 1e-5f);
  EXPECT_NEAR(r.passes[0][centre], 3.0f, 1e-4f);
}

TEST(Passes, DenoisingAlbedoLooksThroughAMirror) {
  // A smooth metal mirror facing the camera reflects the background and the
  // sky: Cycles waits past specular-like surfaces, so the feature vertex is
  // after the mirror and the albedo there is the mirror's F0 x what it sees.
  Scene s;
  Material mirror;
  mirror.base_color = vec3(0.9f, 0.5f, 0.5f);
  mirror.metallic = 1.0f;
  mirror.roughness = 0.0f;
  Material back;
  back.base_color = vec3(0.25f, 0.5f, 0.75f);
  back.roughness = 1.0f;
  back.specular = 0.0f;  // (a rough specular lobe would add its F0 to the albedo, as in Cycles)
  s.materials.push_back(mirror);
  s.materials.push_back(back);
  // Mirror at z = 0 facing up, a diffuse ceiling at z = 6 facing down, camera between them.
  fixtures::add_quad(s, {-20, -20, 0}, {20, -20, 0}, {20, 20, 0}, {-20, 20, 0}, 1);
  fixtures::add_quad(s, {-20, -20, 6}, {-20, 20, 6}, {20, 20, 6}, {20, -20, 6}, 2);
  Light sun;
  sun.type = LightType::Sun;
  sun.direction = vec3(0, 0, -1);
  s.lights.push_back(sun);
  s.camera.to_world = mat4(1.0f);
  s.camera.to_world[3] = vec4(0, 0, 3, 1);
  s.camera.width = s.camera.height = 8;
  s.commit();
  const Rendered r = render(s, kPassDenoisingAlbedo | kPassDiffuseColor, 4);
  const size_t centre = size_t(4) * 8 + 4;
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(r.passes[5][3 * centre + k], mirror.base_color[k] * back.base_color[k], 1e-3f) << k;
    EXPECT_NEAR(r.passes[2][3 * centre + k], 0.0f, 1e-6f);  // a metal has no diffuse closure
  }
}

// Blender's pass alpha threshold: Depth, Normal and Diffuse Color come from
// the first surface at least that opaque along the camera ray (Cycles'
// film_write_data_passes); a sample that scatters off a more transparent
// surface records none. Emission stays that of the first surface.
TEST(Passes, AlphaThresholdLooksThroughMostlyTransparentSurfaces) {
  Scene s;
  Material floor;
  floor.base_color = vec3(0.2f, 0.4f, 0.6f);
  floor.roughness = 1.0f;
  Material veil;  // 30% opaque, white, over the middle of the floor at height 1
  veil.base_color = vec3(1.0f);
  veil.roughness = 1.0f;
  veil.alpha = 0.3f;
  floor_scene(s, floor);
  s.materials.push_back(veil);
  fixtures::add_quad(s, {-2, -2, 1}, {2, -2, 1}, {2, 2, 1}, {-2, 2, 1}, uint32_t(s.materials.size() - 1));
  s.commit();
  const int inner = 4;  // pixels well inside the veil (it spans +-2 at depth 2: 6 px each side of the centre)
  for (float threshold : {0.5f, 0.2f, 0.0f}) {
    const Rendered r = render(s, kPassDepth | kPassDiffuseColor, 64, threshold);
    const int c = s.camera.width / 2;
    for (int y = c - inner; y < c + inner; ++y)
      for (int x = c - inner; x < c + inner; ++x) {
        const size_t i = size_t(y) * s.camera.width + x;
        const float depth = r.passes[0][i];
        const float* diffcol = &r.passes[2][3 * i];
        if (threshold > 0.3f) {
          EXPECT_NEAR(depth, 3.0f, 1e-3f) << "threshold " << threshold;  // the floor, through the veil
        } else {
          EXPECT_NEAR(depth, 2.0f, 1e-3f) << "threshold " << threshold;  // the veil
        }
        EXPECT_GT(diffcol[0], 0.0f);
      }
  }
}
