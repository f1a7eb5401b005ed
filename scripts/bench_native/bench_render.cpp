// A whole render on one thread, for instruction counts of the render loop
// (deterministic where timings on a shared VM are not):
//   valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null build-bench/scripts/bench_native/bench_render 32 1
// renders the native tests' Cornell box (tests/native/scene_fixtures.h, 96 x 96)
// with SAMPLES samples per pixel (default 32), RUNS times (default 3), and
// prints the fastest run's CPU seconds.
#include <cstdio>
#include <cstdlib>
#include <ctime>

#include "core/render.h"
#include "scene_fixtures.h"

using namespace tessera;

int main(int argc, char** argv) {
  Scene scene;
  fixtures::build_cornell_box(scene, 96, 96);
  RenderOptions options;
  options.samples = argc > 1 ? std::atoi(argv[1]) : 32;
  options.threads = 1;
  const int runs = argc > 2 ? std::atoi(argv[2]) : 3;
  double best = 1e30;
  for (int r = 0; r < runs; ++r) {
    timespec a, b;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &a);
    RenderSession session(scene, options);
    session.render();
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &b);
    const double seconds = double(b.tv_sec - a.tv_sec) + 1e-9 * double(b.tv_nsec - a.tv_nsec);
    if (seconds < best) best = seconds;
  }
  std::printf("bench_render: 96 x 96, %d spp, 1 thread, fastest of %d: %.4f s CPU\n", options.samples, runs, best);
}
