// Run-time choice of the SIMD path. The product is compiled for the x86-64
// baseline (SSE2); code for AVX2 (with FMA) and AVX-512 lives in functions
// compiled for that target (bvh8_avx2.cpp, bvh8_avx512.cpp) and is only
// called when the CPU reports it.
#pragma once

namespace tessera {

enum class SimdLevel { SSE2 = 0, AVX2 = 1 };

// What the CPU supports, checked once (__builtin_cpu_supports): AVX2 means
// AVX2 and FMA (no CPU has shipped the one without the other). The
// environment variable TESSERA_SIMD=sse2 forces the baseline, TESSERA_SIMD=avx2
// AVX2 without AVX-512 (for tests and benchmarks of each path).
SimdLevel cpu_simd_level();
const char* simd_level_name(SimdLevel level);

// AVX-512 F, VL, DQ and BW on top of AVX2 and FMA (cpu_simd_level() is then AVX2:
// same BVH8, the AVX-512 traversal replaces the AVX2 one; see bvh8.h).
bool cpu_has_avx512();

// GFNI (the sampler's bit reversals, sampler.h), set once when the module
// loads (false before: the portable path); false with TESSERA_SIMD=sse2. A
// variable rather than a function: the sampler reads it at every draw.
extern const bool g_cpu_has_gfni;

}  // namespace tessera
