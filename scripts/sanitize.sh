#!/usr/bin/env bash
# Builds the native tests with AddressSanitizer + UndefinedBehaviorSanitizer
# in build-asan and runs them, with g++ (the compiler the product ships with;
# clang ignores the `#pragma GCC target` of the AVX2 kernels). Slow tests are
# filtered out by default (set SANITIZE_FILTER to change the GoogleTest filter).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${SANITIZE_BUILD_DIR:-build-asan}
FLAGS="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer -g -O1"
cmake -S . -B "$OUT" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=${SANITIZE_CXX:-g++} \
  -DCMAKE_CXX_FLAGS="$FLAGS" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined" -DPYTHON_EXECUTABLE=/usr/bin/python3 >/dev/null
cmake --build "$OUT" -j"$(nproc)" --target tessera_tests
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# Left out: tests that repeat renders many times for statistics (the code they
# run is covered by the other render tests), to keep CI short.
"$OUT/tessera_tests" --gtest_filter="${SANITIZE_FILTER:--BVH.MillionRandomRaysMatchBruteForce:*Benchmark*:Controls.ErrorEstimateIsHonest:Controls.MoreSamplesNeverRaiseTheError:Controls.AdaptiveSampling*}"
