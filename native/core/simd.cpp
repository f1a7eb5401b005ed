#include "simd.h"

#include <cstdlib>
#include <cstring>

namespace tessera {

// TESSERA_SIMD is `level`, in lower or upper case (simd.h).
static bool simd_env_is(const char* level, const char* upper) {
  const char* env = std::getenv("TESSERA_SIMD");
  return env && (std::strcmp(env, level) == 0 || std::strcmp(env, upper) == 0);
}

static SimdLevel detect() {
  if (simd_env_is("sse2", "SSE2")) return SimdLevel::SSE2;
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
  if (simd_env_is("avx2", "AVX2")) return false;
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

// Not cpu_simd_level(): GFNI comes without AVX2 too (Intel's Tremont cores).
static bool detect_gfni() {
  if (simd_env_is("sse2", "SSE2")) return false;
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
