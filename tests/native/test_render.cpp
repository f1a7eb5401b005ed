// Whole-render properties: determinism across thread counts, region renders
// equal to the full frame, no NaN, cancel.
#include <gtest/gtest.h>

#include <thread>

#include "core/render.h"
#include "scene_fixtures.h"

using namespace tessera;

namespace {
std::vector<float> render(const Scene& s, RenderOptions opt) {
  RenderSession session(s, opt);
  session.render();
  return session.pixels();
}
}  // namespace

TEST(Render, SameImageWithOneThreadAndAllThreads) {
  Scene s;
  fixtures::build_cornell_box(s, 40, 24);
  RenderOptions opt;
  opt.samples = 16;
  opt.threads = 1;
  std::vector<float> one = render(s, opt);
  opt.threads = 0;
  opt.tile_size = 5;  // other tiles and order too
  std::vector<float> all = render(s, opt);
  ASSERT_EQ(one.size(), all.size());
  EXPECT_EQ(0, std::memcmp(one.data(), all.data(), one.size() * sizeof(float)));
}

TEST(Render, SeedChangesTheNoiseNotTheImage) {
  Scene s;
  fixtures::build_cornell_box(s, 16, 16);
  RenderOptions opt;
  opt.samples = 64;
  std::vector<float> a = render(s, opt);
  opt.seed = 7;
  std::vector<float> b = render(s, opt);
  double ma = 0, mb = 0;
  bool differ = false;
  for (size_t i = 0; i < a.size(); i += 4) ma += a[i], mb += b[i], differ |= a[i] != b[i];
  EXPECT_TRUE(differ);
  EXPECT_NEAR(ma / mb, 1.0, 0.03);
}

TEST(Render, RegionPixelsEqualTheFullFrame) {
  Scene s;
  fixtures::build_cornell_box(s, 32, 32);
  RenderOptions opt;
  opt.samples = 4;
  std::vector<float> full = render(s, opt);
  opt.region_x0 = 5, opt.region_x1 = 21, opt.region_y0 = 16, opt.region_y1 = 32;
  std::vector<float> part = render(s, opt);
  ASSERT_EQ(part.size(), size_t(16 * 16 * 4));
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x)
      for (int c = 0; c < 4; ++c)
        ASSERT_EQ(part[4 * (y * 16 + x) + c], full[4 * ((y + 16) * 32 + x + 5) + c]);
}

TEST(Render, CornellBoxIsLitAndFinite) {
  Scene s;
  fixtures::build_cornell_box(s, 24, 24);
  RenderOptions opt;
  opt.samples = 32;
  std::vector<float> px = render(s, opt);
  double sum = 0;
  for (float v : px) {
    ASSERT_TRUE(std::isfinite(v));
    ASSERT_GE(v, 0.0f);
    sum += v;
  }
  EXPECT_GT(sum / px.size(), 0.1);
}

TEST(Render, CancelStopsPromptly) {
  Scene s;
  fixtures::build_cornell_box(s, 256, 256);
  RenderOptions opt;
  opt.samples = 100000;
  RenderSession session(s, opt);
  std::thread t([&] { session.render(); });
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  auto t0 = std::chrono::steady_clock::now();
  session.cancel();
  t.join();
  double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_TRUE(session.stats().cancelled);
  EXPECT_LT(session.samples_done(), 100000);
  EXPECT_LT(waited, 2.0) << "cancel took " << waited << " s";  // generous: one tile of work
}
