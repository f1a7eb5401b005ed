#!/usr/bin/env bash
# Fuzzes the scene builder / BVH / traversal (tests/fuzz/fuzz_scene.cpp) with
# libFuzzer + AddressSanitizer + UBSan for a bounded time.
#   scripts/fuzz.sh [seconds=45]
# Needs clang and libclang-rt-14-dev (scripts/setup.sh installs them).
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_MAX=${1:-45}
OUT=${FUZZ_BUILD_DIR:-build-fuzz}
mkdir -p "$OUT/corpus"
CXX=${FUZZ_CXX:-clang++}
FLAGS="-std=c++17 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined -Inative"
# The core's sources, as CMakeLists.txt lists them for tessera_core.
mapfile -t SRCS < <(sed -n '/^add_library(tessera_core STATIC/,/)/p' CMakeLists.txt | grep -o 'native/core/[a-z0-9_]*\.cpp')
echo "tessera fuzz: building $OUT/fuzz_scene"
objs=()
for src in tests/fuzz/fuzz_scene.cpp "${SRCS[@]}"; do
  obj="$OUT/$(basename "$src" .cpp).o"
  extra=""
  # clang ignores the kernels' `#pragma GCC target`: their instruction sets
  # come from the command line here (the fuzzer runs on this CPU only).
  case "$src" in
    *_avx2.cpp) extra="-mavx2 -mfma" ;;
    *_avx512.cpp) extra="-mavx2 -mfma -mavx512f -mavx512vl -mavx512dq -mavx512bw" ;;
  esac
  $CXX $FLAGS $extra -c "$src" -o "$obj" &
  objs+=("$obj")
done
wait
$CXX $FLAGS "${objs[@]}" -ltbb -o "$OUT/fuzz_scene"
echo "tessera fuzz: replaying the inputs of past findings (tests/fuzz/crashes)"
UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 "$OUT/fuzz_scene" tests/fuzz/crashes/* 2>&1 | tail -n 3
echo "tessera fuzz: running for ${SECONDS_MAX} s"
UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  "$OUT/fuzz_scene" -max_total_time="$SECONDS_MAX" -max_len=4096 -timeout=10 -rss_limit_mb=2048 \
  -print_final_stats=1 -artifact_prefix="$OUT/" "$OUT/corpus" 2>&1 | tail -n 25
