// The render loop: the image is cut into tiles that TBB renders in parallel,
// in passes of a few samples each, so that the display fills in and a cancel
// is seen within one tile. Every (pixel, sample) has its own random stream and
// every pixel sums its samples in order: the image does not depend on the
// thread count or the tile order. Adaptive sampling, the time limit and the
// error target are decided between passes (RenderSession::render); adaptive
// sampling decides from the film at pass boundaries that do not depend on
// threads (a pixel's own samples and its neighbours' convergence), so it is
// deterministic too.
#pragma once
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <vector>
#include "film.h"
#include "integrator.h"
#include "light_tracer.h"

namespace tessera {

struct RenderStats {
  double seconds = 0.0;
  uint64_t rays = 0;
  uint64_t invalid_samples = 0;
  uint64_t skipped_rays = 0;   // not traced because the scene does not need them
  int samples_done = 0;        // passes reached this many samples per pixel
  uint64_t pixel_samples = 0;  // samples taken, over all pixels
  double estimated_error = 0.0;  // Film::estimated_relative_error at the end
  size_t active_pixels = 0;    // pixels adaptive sampling had not stopped
  size_t antialiased_pixels = 0;  // pixels with extra camera rays (emitter antialiasing)
  uint64_t light_paths = 0;    // caustic light paths traced (light_tracer.h; 0: not used)
  // Why the render ended: "samples", "noise threshold" (every pixel
  // converged), "error target", "time limit", "cancelled".
  const char* stop_reason = "samples";
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
  // Live figures while rendering (as of the last finished pass).
  double elapsed_seconds() const;
  // The elapsed time when the live figures below were last updated (the
  // last pass boundary): rates and the remaining time are taken at it, not
  // at now, or they would sag between updates.
  double update_seconds() const { return update_seconds_.load(); }
  // Estimated seconds left: the whole render's time extrapolated from the
  // progress (samples, error target) at the last update, capped by the time
  // limit, less the time elapsed.
  double remaining_seconds() const;
  double estimated_error() const { return estimated_error_.load(); }
  uint64_t pixel_samples() const { return pixel_samples_.load(); }
  uint64_t rays() const { return rays_.load(); }
  // Fraction done, 0..1: the largest of samples, time and (from the error
  // falling as 1/sqrt(samples)) error target progress.
  double progress() const;
  // RGBA of the region, rows bottom to top, as of the last finished pass.
  std::vector<float> pixels() const;
  // One enabled data pass (PassBits), pass_channels(pass) floats per pixel,
  // rows bottom to top, as of the last finished pass; empty if not enabled.
  std::vector<float> pass_pixels(uint32_t pass) const;
  RenderStats stats() const;
  // Samples taken per pixel of the region, rows bottom to top; call after render().
  std::vector<int> sample_counts() const;

 private:
  // Renders the tile's active pixels from their sample count up to
  // pass_end_ (per pixel).
  void render_tile(int tile, PathCounters& counters);
  // Renders pixel (px, py) of the full frame from its sample count up to
  // sample_end, and its replicates up to its count.
  void render_pixel(int px, int py, int sample_end, PathCounters& counters);
  // The error-driven pass of adaptive sampling under a time limit or error
  // target (render.cpp): spreads `budget` samples over the active pixels
  // (setting pass_end_), at most max(step, its count) more per pixel and never past
  // options_.samples; returns the samples given.
  uint64_t allocate_by_error(uint64_t budget, int step);
  // The camera ray of pixel (px, py) of the full frame for the sampler's sample.
  Ray camera_ray(int px, int py, Sampler& sampler) const;
  // Sample s of pixel (px, py) with scrambling seed `seed`: the path's
  // radiance, its camera emission term averaged over its own and extra_rays
  // more camera rays (emitter antialiasing); camera_le and rest (each if not null) get the
  // path's own camera emission (Li) and the rest of its radiance;
  // transparency (if not null) the path's (Li). path_seeds: the pixel's
  // stream for the path, StreamSeeds(px, py, path_stream_seed(seed,
  // extra_rays)), shared by its samples.
  vec3 sample(int px, int py, int s, uint32_t seed, StreamSeeds& path_seeds, int extra_rays, PathCounters& counters,
              FirstHit* first, vec3* camera_le, vec3* rest, float* transparency = nullptr) const;
  static uint32_t path_stream_seed(uint32_t seed, int extra_rays) {
    return extra_rays == 0 ? seed : seed ^ kSplitPathSeed;
  }
  // Emitter antialiasing's choice, between passes: each pixel's extra camera
  // rays per sample from its camera emission statistics (render.cpp);
  // returns the pixels it started over, each with the sample count it had.
  std::vector<std::pair<size_t, int>> choose_camera_rays();
  // Scrambling seed offset of a split pixel's camera rays.
  static constexpr uint32_t kCameraRaySeed = 0x85ebca6bU;
  static constexpr uint32_t kSplitPathSeed = 0xc2b2ae35U;  // ... and the paths' numbers
  // Scrambling seed offset of the error estimate's replicates (film.h).
  static constexpr uint32_t kReplicateSeed = 0x9e3779b9U;
  bool out_of_time() const;
  // Progress as of the last update from samples and the error target
  // (which falls as 1/sqrt(samples)); progress() adds the time limit.
  double sample_progress() const;

  const Scene& scene_;
  RenderOptions options_;
  PixelFilter filter_;
  SceneFeatures features_;
  int x0_, y0_, x1_, y1_;
  int tiles_x_, tiles_y_;
  Film film_;
  std::unique_ptr<LightTracer> light_tracer_;  // null: no caustics to light-trace
  std::vector<vec3> light_image_;             // its splats, summed
  uint64_t light_paths_ = 0;                  // light paths traced so far
  std::vector<int> pass_end_;  // per pixel: the sample count this pass renders it to
  std::vector<double> weight_;  // scratch of allocate_by_error
  DataPasses data_passes_;  // the enabled passes besides Combined (none: nothing recorded)

  mutable std::mutex display_mutex_;
  std::vector<float> display_;  // RGBA means after the last pass
  std::vector<float> pass_display_[kNumDataPasses];  // per PassBits bit: the enabled passes after the last pass
  std::vector<float> sample_count_display_;          // Debug Sample Count after the last pass, if enabled
  std::atomic<bool> cancel_{false};
  std::atomic<int> samples_done_{0};
  std::atomic<double> estimated_error_{0.0};
  std::atomic<double> update_seconds_{0.0};
  std::atomic<uint64_t> pixel_samples_{0};
  std::atomic<uint64_t> rays_{0};
  std::atomic<bool> started_{false};
  std::chrono::steady_clock::time_point start_;
  RenderStats stats_;
};

}  // namespace tessera
