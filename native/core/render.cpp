#include "render.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>

namespace tessera {

RenderSession::RenderSession(const Scene& scene, const RenderOptions& options)
    : scene_(scene), options_(options), filter_(options.filter_width) {
  const int w = scene.camera.width, h = scene.camera.height;
  x0_ = 0, y0_ = 0, x1_ = w, y1_ = h;
  if (options.region_x1 > options.region_x0 && options.region_y1 > options.region_y0) {
    x0_ = std::clamp(options.region_x0, 0, w);
    x1_ = std::clamp(options.region_x1, x0_, w);
    y0_ = std::clamp(options.region_y0, 0, h);
    y1_ = std::clamp(options.region_y1, y0_, h);
  }
  options_.tile_size = std::max(1, options.tile_size);
  tiles_x_ = (width() + options_.tile_size - 1) / options_.tile_size;
  tiles_y_ = (height() + options_.tile_size - 1) / options_.tile_size;
  sum_.assign(size_t(width()) * height(), vec3(0.0f));
  display_.assign(size_t(width()) * height() * 4, 0.0f);
}

void RenderSession::render_tile(int tile, int sample_begin, int sample_end, PathCounters& counters) {
  const int ts = options_.tile_size;
  const int tx = tile % tiles_x_, ty = tile / tiles_x_;
  const int px0 = x0_ + tx * ts, py0 = y0_ + ty * ts;
  const int px1 = std::min(px0 + ts, x1_), py1 = std::min(py0 + ts, y1_);
  for (int py = py0; py < py1; ++py) {
    for (int px = px0; px < px1; ++px) {
      vec3& sum = sum_[size_t(py - y0_) * width() + (px - x0_)];
      for (int s = sample_begin; s < sample_end; ++s) {
        // Pixel coordinates are those of the full frame, so a region render
        // reproduces the full render's pixels exactly.
        Sampler sampler(uint32_t(px), uint32_t(py), uint32_t(s), options_.seed);
        vec2 offset = filter_.sample(sampler.get_2d());
        Ray ray = scene_.camera.generate_ray(vec2(px + 0.5f, py + 0.5f) + offset);
        sum += Li(scene_, ray, sampler, options_, counters);
      }
    }
  }
}

void RenderSession::render() {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
  tbb::enumerable_thread_specific<PathCounters> counters;
  const int num_tiles = tiles_x_ * tiles_y_;
  const int total = std::max(0, options_.samples);
  int done = 0;
  // Passes of 1, 1, 2, 4, ... up to 16 samples: quick first feedback, then
  // fewer display updates.
  int pass = 1;
  while (done < total && !cancel_.load()) {
    const int end = std::min(total, done + pass);
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<int>(0, num_tiles, 1), [&](const tbb::blocked_range<int>& r) {
        PathCounters& c = counters.local();
        for (int t = r.begin(); t != r.end(); ++t) {
          if (cancel_.load(std::memory_order_relaxed)) return;
          render_tile(t, done, end, c);
        }
      });
    });
    if (cancel_.load()) break;
    done = end;
    {
      std::lock_guard<std::mutex> lock(display_mutex_);
      const float inv = 1.0f / done;
      for (size_t i = 0; i < sum_.size(); ++i) {
        display_[4 * i + 0] = sum_[i].x * inv;
        display_[4 * i + 1] = sum_[i].y * inv;
        display_[4 * i + 2] = sum_[i].z * inv;
        display_[4 * i + 3] = 1.0f;
      }
    }
    samples_done_.store(done);
    if (done > 1) pass = std::min(pass * 2, 16);
  }
  PathCounters all;
  for (const PathCounters& c : counters) {
    all.rays += c.rays;
    all.invalid_samples += c.invalid_samples;
  }
  std::lock_guard<std::mutex> lock(display_mutex_);
  stats_.seconds = std::chrono::duration<double>(clock::now() - start).count();
  stats_.rays = all.rays;
  stats_.invalid_samples = all.invalid_samples;
  stats_.samples_done = done;
  stats_.cancelled = cancel_.load();
}

std::vector<float> RenderSession::pixels() const {
  std::lock_guard<std::mutex> lock(display_mutex_);
  return display_;
}

RenderStats RenderSession::stats() const {
  std::lock_guard<std::mutex> lock(display_mutex_);
  return stats_;
}

}  // namespace tessera
