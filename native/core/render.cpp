#include "render.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace tessera {

RenderSession::RenderSession(const Scene& scene, const RenderOptions& options)
    : scene_(scene), options_(options), filter_(options.filter_width), features_(options.specialise ? scene_features(scene) : SceneFeatures::all()) {
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
  // The error target needs the estimate, whatever estimate_error says.
  film_.resize(width(), height(), options.estimate_error || options.error_target > 0.0f,
               features_.camera_emission && options.max_camera_rays > 1, options.film_transparent);
  display_.assign(size_t(width()) * height() * 4, 0.0f);
  data_passes_.configure(options.passes, film_.size(), scene.camera);
  for (int b = 0; b < kNumDataPasses; ++b)
    if (data_passes_.mask() & (1u << b)) pass_display_[b].assign(film_.size() * pass_channels(1u << b), 0.0f);
  if (options.passes & kPassSampleCount) sample_count_display_.assign(film_.size(), 0.0f);
  // Caustics from small lights through smooth surfaces, where the scene has them (light_tracer.h).
  light_tracer_ = std::make_unique<LightTracer>(scene, options_, filter_, x0_, y0_, x1_, y1_);
  if (light_tracer_->active()) {
    features_.traced_lights = light_tracer_->traced().data();
    light_image_.assign(film_.size(), vec3(0.0f));
  } else {
    light_tracer_.reset();
  }
}

void RenderSession::render_tile(int tile, PathCounters& counters) {
  const int ts = options_.tile_size;
  const int tx = tile % tiles_x_, ty = tile / tiles_x_;
  const int px0 = x0_ + tx * ts, py0 = y0_ + ty * ts;
  const int px1 = std::min(px0 + ts, x1_), py1 = std::min(py0 + ts, y1_);
  for (int py = py0; py < py1; ++py)
    for (int px = px0; px < px1; ++px) {
      const size_t i = size_t(py - y0_) * width() + (px - x0_);
      render_pixel(px, py, film_.active(i) ? pass_end_[i] : film_.count(i), counters);
    }
}

void RenderSession::render_pixel(int px, int py, int sample_end, PathCounters& counters) {
  const size_t i = size_t(py - y0_) * width() + (px - x0_);
  const int sample_begin = film_.count(i);
  const int extra_rays = film_.extra_camera_rays(i);
  const bool keep_le = film_.has_camera_emission();
  const uint64_t rays_before = counters.rays;
  StreamSeeds path_seeds(uint32_t(px), uint32_t(py), path_stream_seed(options_.seed, extra_rays));
  for (int s = sample_begin; s < sample_end; ++s) {
    // Pixel coordinates are those of the full frame, so a region render
    // reproduces the full render's pixels exactly.
    vec3 le, rest;
    vec3* le_out = keep_le ? &le : nullptr;
    vec3* rest_out = keep_le ? &rest : nullptr;
    float transparency = 0.0f;
    float* transparency_out = film_.has_transparency() ? &transparency : nullptr;
    if (!data_passes_.mask()) {
      film_.add(i, s, sample(px, py, s, options_.seed, path_seeds, extra_rays, counters, nullptr, le_out, rest_out, transparency_out));
    } else {
      FirstHit first(data_passes_.mask(), options_.pass_alpha_threshold);
      film_.add(i, s, sample(px, py, s, options_.seed, path_seeds, extra_rays, counters, &first, le_out, rest_out, transparency_out));
      data_passes_.add(i, first);
    }
    if (keep_le) film_.add_camera_emission(i, le, rest);
    if (transparency_out) film_.add_transparency(i, transparency);
  }
  if (keep_le) film_.add_path_rays(i, counters.rays - rays_before - uint64_t(extra_rays) * (sample_end - sample_begin));
  if (sample_end > sample_begin) film_.set_count(i, sample_end);
  // The error estimate's replicates (film.h): the pixel's samples from
  // independently scrambled streams, kept apart from the image, brought
  // up to the pixel's count (a pixel followed from this pass on catches
  // up from sample 0, whether or not it gets samples of its own now).
  const int slot = film_.replicate_slot(px - x0_, py - y0_);
  if (slot < 0) return;
  const int from = film_.replicate_samples(slot), to = film_.count(i);
  if (to <= from) return;
  for (int k = 0; k < film_.replicate_streams(slot); ++k) {
    const uint32_t seed = options_.seed + uint32_t(k + 1) * kReplicateSeed;
    StreamSeeds replicate_seeds(uint32_t(px), uint32_t(py), path_stream_seed(seed, extra_rays));
    for (int s = from; s < to; ++s)
      film_.add_replicate(slot, k, sample(px, py, s, seed, replicate_seeds, extra_rays, counters, nullptr, nullptr, nullptr));
  }
  film_.set_replicate_samples(slot, to);
}

uint64_t RenderSession::allocate_by_error(uint64_t budget, int step) {
  const int w = width(), h = height(), total = options_.samples;
  const size_t n = film_.size();
  // The error a pixel contributes at n_i samples is ~ v_i / n_i (v_i: its
  // per-sample variance); for a fixed number of samples over the image the
  // squared error is least when n_i ~ sqrt(v_i) (Lagrange). The weight is the
  // square root of the pixel's sample variance or, if larger, of its 3x3
  // neighbourhood's mean: a pixel whose rare bright samples have not shown up
  // yet, next to one where they have, is not sure to be smooth. (The sample
  // variance over-states the Sobol mean's error where the integrand is smooth;
  // n x the class-A half difference, which does not, did no better on the
  // shared scenes, the pixel's own variance alone worse: docs/convergence/ADAPTIVE.md.)
  std::vector<double> v(n, 0.0);
  for (size_t i = 0; i < n; ++i) v[i] = film_.sample_variance(i);
  weight_.assign(n, 0.0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = size_t(y) * w + x;
      if (!film_.active(i) || film_.count(i) >= total) continue;
      double sum = 0.0;
      int k = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
          sum += v[size_t(ny) * w + nx], ++k;
        }
      weight_[i] = std::sqrt(std::max(v[i], sum / k));
    }
  // Water-filling: pixel i is brought up to lambda * weight_i samples (at
  // most step or its count more, never past total), lambda the largest that
  // fits the budget.
  auto given = [&](double lambda, bool write) {
    uint64_t sum = 0;
    for (size_t i = 0; i < n; ++i) {
      const int c = film_.count(i);
      int k = 0;
      if (weight_[i] > 0.0) {
        const double want = lambda * weight_[i] - c;
        k = want <= 0.0 ? 0 : int(std::min<double>(want, std::min(std::max(step, c), total - c)));
      }
      if (write) pass_end_[i] = c + k;
      sum += uint64_t(k);
    }
    return sum;
  };
  double lo = 0.0, hi = 1.0;
  while (given(hi, false) < budget && hi < 1e30) hi *= 2.0;
  for (int it = 0; it < 60 && hi > lo * (1.0 + 1e-9); ++it) {
    const double mid = 0.5 * (lo + hi);
    (given(mid, false) <= budget ? lo : hi) = mid;
  }
  uint64_t sum = given(lo, true);
  if (sum == 0) {
    // Nothing to tell the pixels apart (all black so far): the same for each.
    for (size_t i = 0; i < n; ++i) {
      const int c = film_.count(i);
      pass_end_[i] = film_.active(i) ? std::min(total, c + step) : c;
      sum += uint64_t(pass_end_[i] - c);
    }
  }
  return sum;
}

Ray RenderSession::camera_ray(int px, int py, Sampler& sampler) const {
  const vec2 offset = filter_.sample(sampler.get_2d());
  // The aperture sample is drawn only with depth of field (pinhole images stay as they were).
  const vec2 u_lens = scene_.camera.has_lens() ? sampler.get_2d() : vec2(0.5f);
  return scene_.camera.generate_ray(vec2(px + 0.5f, py + 0.5f) + offset, u_lens);
}

vec3 RenderSession::sample(int px, int py, int s, uint32_t seed, StreamSeeds& path_seeds, int extra_rays,
                           PathCounters& counters, FirstHit* first, vec3* camera_le, vec3* rest,
                           float* transparency) const {
  // Emitter antialiasing: the pixel integral of the path's radiance is that
  // of the emission the camera ray sees first plus that of the rest, and the
  // first term, whose edges against bright lights carry a pixel's error,
  // gets K = extra_rays more camera rays per sample while the path goes on
  // from its own: Le(x_0) + rest(x_0) becomes rest(x_0) + (Le(x_0) +
  // sum_j Le(y_j)) / (K + 1), the same expectation. The path's x_0 over the
  // samples stays a (0,2)-sequence (the rest has edges too: from the stream's
  // every K-th point instead it converged as if random, and the image got
  // worse); the y_j are the aligned block s K .. s K + K - 1 of a stream of
  // their own (the index shuffle maps aligned blocks to aligned blocks), so
  // they are stratified among themselves and, with K fixed, all of the
  // pixel's are the first n K points of one (0,2)-sequence. A split pixel
  // starts over (choose_camera_rays) with its path's numbers from another
  // stream, apart from the samples that chose to split it.
  Sampler sampler(path_seeds, uint32_t(s));  // seed, or seed ^ kSplitPathSeed with extra rays
  const Ray ray = camera_ray(px, py, sampler);
  vec3 le0(0.0f);
  const vec3 L = Li(scene_, ray, sampler, options_, counters, features_, first,
                    extra_rays > 0 || camera_le || rest ? &le0 : nullptr, transparency);
  if (camera_le) *camera_le = le0;
  if (rest) *rest = L - le0;
  if (extra_rays == 0) return L;
  const uint32_t first_ray = uint32_t(s) * uint32_t(extra_rays);
  vec3 le_sum = le0;
  for (int k = 0; k < extra_rays; ++k) {
    Sampler extra(uint32_t(px), uint32_t(py), first_ray + uint32_t(k), seed ^ kCameraRaySeed);
    le_sum += camera_emission(scene_, camera_ray(px, py, extra), options_, counters);
  }
  return L - le0 + le_sum / float(extra_rays + 1);
}

std::vector<std::pair<size_t, int>> RenderSession::choose_camera_rays() {
  // Each pixel by its own samples (Film::wanted_camera_rays_log2). A pixel
  // split now starts over: its samples so far, one camera ray each, would
  // keep the error of the edge it is split for (at 64 samples, the first 8
  // of veach_mis's brightest light edge carried most of it); they only
  // chose K, and the caller renders the pixel again up to the count it had
  // (returned with it). A split pixel later keeps the most it was given (its
  // blocks of camera rays stay apart in its stream).
  std::vector<std::pair<size_t, int>> restarted;
  int max_log2 = 0;
  while (max_log2 < 8 && (2 << max_log2) <= options_.max_camera_rays - 1) ++max_log2;
  for (size_t i = 0; i < film_.size(); ++i) {
    if (!film_.active(i)) continue;
    const int had = film_.extra_camera_rays_log2(i), l = film_.wanted_camera_rays_log2(i, max_log2);
    if (l <= had) continue;
    if (had == 0) {
      restarted.emplace_back(i, film_.count(i));
      film_.restart(i);
      data_passes_.restart(i);
    }
    film_.set_extra_camera_rays_log2(i, l);
  }
  return restarted;
}

double RenderSession::elapsed_seconds() const {
  if (!started_.load(std::memory_order_acquire)) return 0.0;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

bool RenderSession::out_of_time() const {
  return options_.time_limit > 0.0 && elapsed_seconds() >= options_.time_limit;
}

double RenderSession::sample_progress() const {
  double p = double(samples_done_.load()) / std::max(1, options_.samples);
  const double err = estimated_error_.load();
  if (options_.error_target > 0.0f && err > 0.0) p = std::max(p, std::pow(options_.error_target / err, 2.0));
  return p;
}

double RenderSession::remaining_seconds() const {
  const double updated = update_seconds_.load();
  const double p = sample_progress();
  double total = p > 0.0 && updated > 0.0 ? updated / std::min(p, 1.0) : kInf;
  if (options_.time_limit > 0.0) total = std::min(total, options_.time_limit);
  return std::isfinite(total) ? std::max(0.0, total - elapsed_seconds()) : -1.0;
}

double RenderSession::progress() const {
  double p = sample_progress();
  if (options_.time_limit > 0.0) p = std::max(p, elapsed_seconds() / options_.time_limit);
  return std::clamp(p, 0.0, 1.0);
}

void RenderSession::render() {
  start_ = std::chrono::steady_clock::now();
  started_.store(true, std::memory_order_release);
  tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
  tbb::enumerable_thread_specific<PathCounters> counters;
  const int num_tiles = tiles_x_ * tiles_y_;
  const int total = std::max(0, options_.samples);
  const size_t num_pixels = film_.size();
  // Adaptive sampling needs a few samples per half before its estimate
  // means anything; automatic minimum: as Cycles, ~ 1/sqrt(threshold), at least 8.
  const bool adaptive = options_.adaptive_threshold > 0.0f;
  const int min_adaptive = options_.adaptive_min_samples > 0
                               ? options_.adaptive_min_samples
                               : std::max(8, int(std::ceil(1.0f / std::sqrt(std::max(options_.adaptive_threshold, 1e-8f)))));
  // The image-wide error estimate is checked from this many samples on.
  constexpr int kMinSamplesForErrorTarget = 8;
  constexpr int kAdaptiveConfirmations = 2;
  constexpr int kMinSamplesForCameraRays = 4;
  std::vector<int> converged_passes(adaptive ? num_pixels : 0, 0);
  std::vector<uint8_t> stop_now(adaptive ? num_pixels : 0, 0);
  const char* stop_reason = "samples";
  int done = 0;
  size_t active = num_pixels;
  double seconds_per_pixel_sample = 0.0;  // measured, for sizing passes under a time limit
  // Passes of 1, 1, 2, 4, ... up to 16 samples: quick first feedback, then
  // fewer display updates. Without a time limit the pass boundaries depend
  // only on the settings, never on threads or timing.
  int pass = 1;
  if (!features_.emits && !data_passes_.mask() && !film_.has_transparency()) {
    // Nothing emits: the image is black, no path needs tracing (unless
    // passes or a transparent film's alpha want what the camera sees).
    done = total;
    std::lock_guard<std::mutex> lock(display_mutex_);
    for (size_t i = 0; i < num_pixels; ++i) display_[4 * i + 3] = 1.0f;
    samples_done_.store(done);
  }
  // Adaptive sampling with a time limit or an error target has a budget
  // rather than a sample count to reach: once every pixel has the minimum,
  // each pass spreads its samples over the pixels still above the noise
  // threshold by their estimated error (allocate_by_error) instead of
  // giving each the same number.
  const bool by_error = adaptive && (options_.time_limit > 0.0 || options_.error_target > 0.0f);
  pass_end_.assign(num_pixels, 0);
  std::vector<int> pass_begin(num_pixels, 0);
  bool more = done < total;
  while (more && !cancel_.load()) {
    if (out_of_time()) {
      stop_reason = "time limit";
      break;
    }
    int this_pass = pass;
    // Samples this pass may take over all pixels under the time limit.
    uint64_t fit = std::numeric_limits<uint64_t>::max();
    if (options_.time_limit > 0.0 && seconds_per_pixel_sample > 0.0) {
      // Shrink the pass to what the remaining time allows.
      const double remaining = options_.time_limit - elapsed_seconds();
      fit = uint64_t(std::max(1.0, remaining / seconds_per_pixel_sample));
      this_pass = std::max(1, std::min<int>(pass, int(std::min<uint64_t>(fit / std::max<size_t>(active, 1), 1 << 20))));
    }
    uint64_t pass_samples = 0;
    const bool error_pass = by_error && done >= min_adaptive;
    const int end = std::min(total, done + this_pass);
    if (error_pass) {
      pass_samples = allocate_by_error(std::min<uint64_t>(fit, uint64_t(pass) * std::max<size_t>(active, 1)), pass);
    } else {
      for (size_t i = 0; i < num_pixels; ++i) {
        pass_end_[i] = film_.active(i) ? std::max(end, film_.count(i)) : film_.count(i);
        pass_samples += uint64_t(pass_end_[i] - film_.count(i));
      }
    }
    for (size_t i = 0; i < num_pixels; ++i) pass_begin[i] = film_.count(i);
    const auto pass_start = std::chrono::steady_clock::now();
    std::atomic<bool> timed_out{false};
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<int>(0, num_tiles, 1), [&](const tbb::blocked_range<int>& r) {
        PathCounters& c = counters.local();
        for (int t = r.begin(); t != r.end(); ++t) {
          if (cancel_.load(std::memory_order_relaxed)) return;
          // Tiles not started when the time is up keep their samples so far
          // (every pixel has its own count, so the image stays consistent).
          if (out_of_time()) {
            timed_out.store(true, std::memory_order_relaxed);
            return;
          }
          render_tile(t, c);
        }
      });
    });
    if (cancel_.load()) break;
    if (light_tracer_ && pass_samples > 0 && !timed_out.load()) {
      // Light paths in proportion to the camera samples this pass took, in
      // chunks whose connections are added in chunk order: the light image
      // does not depend on the threads.
      const uint64_t n = uint64_t(std::llround(double(options_.caustic_light_paths) * double(pass_samples)));
      constexpr uint64_t kChunk = 4096;
      std::vector<std::vector<LightTracer::Splat>> chunks((n + kChunk - 1) / kChunk);
      const uint64_t first = light_paths_;
      arena.execute([&] {
        tbb::parallel_for(size_t(0), chunks.size(), [&](size_t c) {
          const uint64_t b = first + c * kChunk;
          light_tracer_->trace(b, std::min(kChunk, first + n - b), options_.seed, chunks[c], counters.local());
        });
      });
      // Each band of rows takes the splats that reach it, all in path order.
      const int bands = 16, rows = (height() + bands - 1) / bands;
      arena.execute([&] {
        tbb::parallel_for(0, bands, [&](int band) {
          const int y0 = y0_ + band * rows, y1 = std::min(y1_, y0 + rows);
          for (const auto& chunk : chunks)
            for (const LightTracer::Splat& sp : chunk) light_tracer_->splat(sp, light_image_, y0, y1);
        });
      });
      light_paths_ += n;
    }
    const double pass_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - pass_start).count();
    if (!timed_out.load() && pass_samples > 0) seconds_per_pixel_sample = pass_seconds / double(pass_samples);
    // done: the pass's sample count (uniform passes; tiles the time limit
    // skipped keep fewer), or after error-driven passes the fewest samples of
    // a pixel still sampling (the render goes on while one has fewer than total).
    if (!error_pass) {
      done = end;
    } else {
      int fewest = total;
      for (size_t i = 0; i < num_pixels; ++i)
        if (film_.active(i)) fewest = std::min(fewest, film_.count(i));
      done = fewest;
    }

    // Adaptive sampling. A pixel stops when under the threshold at two pass
    // boundaries in a row and so is every pixel around it (Cycles spreads
    // non-convergence to neighbours the same way, film_adaptive_sampling_
    // filter_x/y): one split of a pixel's samples is a one-degree-of-freedom
    // estimate, and a pixel whose rare bright samples have not shown up yet
    // would otherwise stop early and stay dark (biased low). Uses only the
    // film at the pass boundary, so it does not depend on threads.
    if (adaptive && done >= min_adaptive) {
      const int w = width(), h = height();
      for (size_t i = 0; i < num_pixels; ++i) {
        if (!film_.active(i)) continue;
        // A pixel this pass gave nothing (error-driven passes) has nothing
        // new to confirm.
        if (film_.count(i) == pass_begin[i]) continue;
        converged_passes[i] = film_.pixel_error(i) < options_.adaptive_threshold ? std::min(converged_passes[i] + 1, 255) : 0;
      }
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const size_t i = size_t(y) * w + x;
          if (!film_.active(i)) continue;
          bool all = true;
          for (int dy = -1; dy <= 1 && all; ++dy)
            for (int dx = -1; dx <= 1 && all; ++dx) {
              const int nx = x + dx, ny = y + dy;
              if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
              const size_t n = size_t(ny) * w + nx;
              all = !film_.active(n) || converged_passes[n] >= kAdaptiveConfirmations;
            }
          if (all) stop_now[i] = 1;
        }
      for (size_t i = 0; i < num_pixels; ++i) {
        if (stop_now[i]) film_.deactivate(i), stop_now[i] = 0;
      }
    }
    uint64_t taken = 0;
    active = 0;
    for (size_t i = 0; i < num_pixels; ++i) {
      taken += uint64_t(film_.count(i));
      active += film_.active(i) ? 1 : 0;
    }
    // Emitter antialiasing from the fourth sample on.
    if (film_.has_camera_emission() && done >= kMinSamplesForCameraRays) {
      const auto restarted = choose_camera_rays();
      arena.execute([&] {
        tbb::parallel_for(size_t(0), restarted.size(), [&](size_t k) {
          const size_t i = restarted[k].first;
          render_pixel(x0_ + int(i % width()), y0_ + int(i / width()), restarted[k].second, counters.local());
        });
      });
    }
    PathCounters all;
    for (const PathCounters& c : counters) all.rays += c.rays;
    const double err = film_.estimated_relative_error();
    {
      std::lock_guard<std::mutex> lock(display_mutex_);
      const float light_scale = light_tracer_ ? float(light_tracer_->scale(light_paths_)) : 0.0f;
      for (size_t i = 0; i < num_pixels; ++i) {
        vec3 m = film_.mean(i);
        if (light_tracer_) m += light_image_[i] * light_scale;
        display_[4 * i + 0] = m.x;
        display_[4 * i + 1] = m.y;
        display_[4 * i + 2] = m.z;
        display_[4 * i + 3] = film_.alpha(i);
      }
      for (int b = 0; b < kNumDataPasses; ++b) {
        if (pass_display_[b].empty()) continue;
        const uint32_t bit = 1u << b;
        const int nc = pass_channels(bit);
        for (size_t i = 0; i < num_pixels; ++i) data_passes_.resolve(i, film_.count(i), bit, &pass_display_[b][nc * i]);
      }
      if (!sample_count_display_.empty()) {
        const float scale = 1.0f / float(std::max(1, total));
        for (size_t i = 0; i < num_pixels; ++i) sample_count_display_[i] = float(film_.count(i)) * scale;
      }
    }
    rays_.store(all.rays);
    pixel_samples_.store(taken);
    estimated_error_.store(err);
    update_seconds_.store(elapsed_seconds());
    samples_done_.store(done);
    if (timed_out.load() || (options_.time_limit > 0.0 && out_of_time() && done < total)) {
      stop_reason = "time limit";
      break;
    }
    if (options_.error_target > 0.0f && done >= kMinSamplesForErrorTarget && err < options_.error_target) {
      stop_reason = "error target";
      break;
    }
    if (active == 0) {
      stop_reason = "noise threshold";
      break;
    }
    if (done > 1) pass = std::min(pass * 2, 16);
    more = done < total;
  }
  PathCounters all;
  for (const PathCounters& c : counters) {
    all.rays += c.rays;
    all.invalid_samples += c.invalid_samples;
    all.skipped_rays += c.skipped_rays;
  }
  std::lock_guard<std::mutex> lock(display_mutex_);
  stats_.seconds = elapsed_seconds();
  stats_.rays = all.rays;
  stats_.invalid_samples = all.invalid_samples;
  stats_.skipped_rays = all.skipped_rays;
  stats_.samples_done = done;
  stats_.pixel_samples = pixel_samples_.load();
  stats_.estimated_error = estimated_error_.load();
  stats_.active_pixels = active;
  stats_.light_paths = light_paths_;
  stats_.antialiased_pixels = 0;
  if (film_.has_camera_emission())
    for (size_t i = 0; i < num_pixels; ++i) stats_.antialiased_pixels += film_.extra_camera_rays(i) > 0;
  stats_.cancelled = cancel_.load();
  stats_.stop_reason = stats_.cancelled ? "cancelled" : stop_reason;
}

std::vector<float> RenderSession::pixels() const {
  std::lock_guard<std::mutex> lock(display_mutex_);
  return display_;
}

std::vector<float> RenderSession::pass_pixels(uint32_t pass) const {
  if (pass == kPassSampleCount) {
    std::lock_guard<std::mutex> lock(display_mutex_);
    return sample_count_display_;
  }
  for (int b = 0; b < kNumDataPasses; ++b)
    if (pass == (1u << b)) {
      std::lock_guard<std::mutex> lock(display_mutex_);
      return pass_display_[b];
    }
  return {};
}

std::vector<int> RenderSession::sample_counts() const {
  std::vector<int> counts(film_.size());
  for (size_t i = 0; i < counts.size(); ++i) counts[i] = film_.count(i);
  return counts;
}

RenderStats RenderSession::stats() const {
  std::lock_guard<std::mutex> lock(display_mutex_);
  return stats_;
}

}  // namespace tessera
