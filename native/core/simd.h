// Run-time choice of the SIMD path. The product is compiled for the x86-64
// baseline (SSE2); code for AVX2 lives in functions compiled for that target
// (bvh8_avx2.cpp) and is only called when the CPU reports it.
#pragma once

namespace tessera {

enum class SimdLevel { SSE2 = 0, AVX2 = 1 };

// What the CPU supports, checked once (__builtin_cpu_supports). The
// environment variable TESSERA_SIMD=sse2 forces the baseline (for tests and
// benchmarks of the fallback).
SimdLevel cpu_simd_level();
const char* simd_level_name(SimdLevel level);

}  // namespace tessera
