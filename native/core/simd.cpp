#include "simd.h"

#include <cstdlib>
#include <cstring>

namespace tessera {

static SimdLevel detect() {
  const char* env = std::getenv("TESSERA_SIMD");
  if (env && (std::strcmp(env, "sse2") == 0 || std::strcmp(env, "SSE2") == 0)) return SimdLevel::SSE2;
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  // The BVH8 kernels use FMA next to AVX2 (every CPU with AVX2 has had it).
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return SimdLevel::AVX2;
#endif
  return SimdLevel::SSE2;
}

SimdLevel cpu_simd_level() {
  static const SimdLevel level = detect();
  return level;
}

static bool detect_avx512() {
  if (cpu_simd_level() != SimdLevel::AVX2) return false;
  const char* env = std::getenv("TESSERA_SIMD");
  if (env && (std::strcmp(env, "avx2") == 0 || std::strcmp(env, "AVX2") == 0)) return false;
#if defined(__x86_64__) || defined(__i386__)
  // FMA comes with the AVX2 level already.
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
         __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw");
#else
  return false;
#endif
}

bool cpu_has_avx512() {
  static const bool has = detect_avx512();
  return has;
}

static bool detect_gfni() {
  const char* env = std::getenv("TESSERA_SIMD");
  if (env && (std::strcmp(env, "sse2") == 0 || std::strcmp(env, "SSE2") == 0)) return false;
#if defined(__x86_64__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("gfni");
#else
  return false;
#endif
}

const bool g_cpu_has_gfni = detect_gfni();

const char* simd_level_name(SimdLevel level) { return level == SimdLevel::AVX2 ? "avx2" : "sse2"; }

}  // namespace tessera
