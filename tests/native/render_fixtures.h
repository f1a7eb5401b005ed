// Rendering a test scene whole, for the native tests that compare images.
#pragma once
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "core/render.h"

namespace tessera::fixtures {

struct Result {
  std::vector<float> px;  // RGBA, rows bottom to top
  RenderStats stats;
};
inline Result render(const Scene& s, RenderOptions opt) {
  RenderSession session(s, opt);
  session.render();
  return {session.pixels(), session.stats()};
}
// Renders with one thread and with all threads and other tiles, expects the
// same image from both, and returns the one-thread render.
inline Result render_on_one_and_all_threads(const Scene& s, RenderOptions opt) {
  opt.threads = 1;
  Result one = render(s, opt);
  opt.threads = 0;
  opt.tile_size = 5;
  const Result all = render(s, opt);
  EXPECT_EQ(one.px.size(), all.px.size());
  if (one.px.size() == all.px.size())
    EXPECT_EQ(0, std::memcmp(one.px.data(), all.px.data(), one.px.size() * sizeof(float)));
  EXPECT_EQ(one.stats.pixel_samples, all.stats.pixel_samples);
  return one;
}
// The mean over the pixels and the RGB channels.
inline double mean_rgb(const std::vector<float>& a) {
  double m = 0.0;
  for (size_t i = 0; i < a.size(); ++i)
    if (i % 4 != 3) m += a[i];
  return m / double(a.size() / 4 * 3);
}

}  // namespace tessera::fixtures
