// The render loop: the image is cut into tiles that TBB renders in parallel,
// in passes of a few samples each, so that the display fills in and a cancel
// is seen within one tile. Every (pixel, sample) has its own random stream and
// every pixel sums its samples in order: the image does not depend on the
// thread count or the tile order.
#pragma once
#include <atomic>
#include <mutex>
#include <vector>
#include "film.h"
#include "integrator.h"

namespace tessera {

struct RenderStats {
  double seconds = 0.0;
  uint64_t rays = 0;
  uint64_t invalid_samples = 0;
  int samples_done = 0;
  bool cancelled = false;
};

class RenderSession {
 public:
  RenderSession(const Scene& scene, const RenderOptions& options);

  // Renders until done or cancelled; call from one thread.
  void render();
  void cancel() { cancel_.store(true); }

  int width() const { return x1_ - x0_; }
  int height() const { return y1_ - y0_; }
  int samples_done() const { return samples_done_.load(); }
  int samples_total() const { return options_.samples; }
  // RGBA of the region, rows bottom to top, as of the last finished pass.
  std::vector<float> pixels() const;
  RenderStats stats() const;

 private:
  void render_tile(int tile, int sample_begin, int sample_end, PathCounters& counters);

  const Scene& scene_;
  RenderOptions options_;
  PixelFilter filter_;
  int x0_, y0_, x1_, y1_;
  int tiles_x_, tiles_y_;
  std::vector<vec3> sum_;  // per pixel, sum of sample radiance

  mutable std::mutex display_mutex_;
  std::vector<float> display_;  // RGBA means after the last pass
  std::atomic<bool> cancel_{false};
  std::atomic<int> samples_done_{0};
  RenderStats stats_;
};

}  // namespace tessera
