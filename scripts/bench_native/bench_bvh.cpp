// Side-by-side benchmark of Tessera's BVH (build + single-ray traversal)
// against Embree 3 (RTC_BUILD_QUALITY_MEDIUM, rtcIntersect1 / rtcOccluded1; by
// default and with RTC_SCENE_FLAG_ROBUST).
//
//   bench_bvh [--mode compare|builders|watertight|all] [--runs N] [--res R] [--threads 1,2]
//             [--bins 4,8,16,32,64] [--builder-threads T] [--builder-res R] [--builder-meshes a,b]
//             [--clock wall|cpu] [--stat median|min] mesh files...
//   bench_bvh --mode trace [--kind primary|diffuse|random|shadow|all] [--engine tessera|sse2|embree|embree-robust] ...
//             (one engine only, for perf; PASSES=1 also prints each pass's Mrays/s, MISS=1 moves
//             the rays off the mesh: the per-ray cost outside the traversal loop)
//   bench_bvh --mode ab --ab-base no-collapse,separate-leaves ...
//             (default tree against one built with those options, same traversal, alternating)
//   bench_bvh --mode ab --ab-base max-leaf=8,sah-block=4,bins=32,tri-cost=1.5,sweep,drop-degenerate ...
//             (binary build options of the base tree; drop-degenerate: without triangles
//             with two equal vertices, which never hit; --mode trace builds with them too)
//   bench_bvh --mode stats mesh...   (the BVH8's node fill, leaf and block sizes)
//   bench_bvh --mode build [--engine both|tessera|embree] [--threads 1,2] [--runs N] mesh...
//             (builds only, engines alternating in one loop per thread count: median wall and
//             process CPU time; one engine alone for perf / callgrind)
//   DIFFDUMP=1 bench_bvh --mode compare ...
//             (prints each ray whose BVH4/BVH8/Embree results differ, with every
//             triangle the scalar test hits and near misses, brute force)
//   bench_bvh --mode ab --ab-base avx2-kernel ...
//             (the default tree traced by the AVX2 BVH8 kernel against the default (AVX-512) kernel)
//
// Both engines trace exactly the same ray arrays, chunked over TBB
// parallel_for inside a task_arena of the given thread count. Every figure is
// the median of --runs repetitions in one process.
#include <embree3/rtcore.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <cstdio>
#include <cstring>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "core/bvh8.h"
#include "core/mesh.h"
#include "core/simd.h"
#include "core/triangle.h"
#include "io/mesh_file.h"
#include "scene_fixtures.h"
#ifdef TESSERA_BVH_COUNTERS
#include "core/simd_tri4.h"
#endif

using namespace tessera;

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// --clock cpu: time the 1-thread passes by the calling thread's CPU time
// (CLOCK_THREAD_CPUTIME_ID) instead of wall time, so that other processes on
// a shared machine do not count; a 1-thread task_arena runs on its caller.
bool g_cpu_clock = false;
double thread_seconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// --stat min: report the fastest run instead of the median (other load on a
// shared machine only ever adds time).
bool g_min_stat = false;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  if (g_min_stat && !v.empty()) return v[0];
  size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

// Small deterministic per-ray random numbers (PCG hash), so ray generation
// does not depend on thread scheduling.
struct Rng {
  uint64_t s;
  explicit Rng(uint64_t seed) : s(seed * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull) {}
  float next() {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    uint32_t x = uint32_t(((s >> 18u) ^ s) >> 27u);
    uint32_t rot = uint32_t(s >> 59u);
    x = (x >> rot) | (x << ((32 - rot) & 31));
    return float(x >> 8) * (1.0f / 16777216.0f);
  }
};

struct RayArray {
  std::string kind;
  bool shadow = false;
  std::vector<vec3> o, d;
  std::vector<float> tmax;
  size_t size() const { return o.size(); }
  void push(const vec3& org, const vec3& dir, float t) {
    o.push_back(org);
    d.push_back(dir);
    tmax.push_back(t);
  }
};

struct Results {
  std::vector<float> t;  // hit distance, kInf on a miss (shadow: 0 occluded / kInf clear)
};

// ---------------------------------------------------------------- Embree

// Bytes Embree holds (memory monitor over all devices): vertex and index
// buffers plus the BVH of the scenes alive.
std::atomic<long long> g_embree_bytes{0};
bool embree_monitor(void*, ssize_t bytes, bool) {
  g_embree_bytes += bytes;
  return true;
}

struct EmbreeScene {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ~EmbreeScene() { release(); }
  void release() {
    if (scene) rtcReleaseScene(scene);
    scene = nullptr;
  }
};

// robust: RTC_SCENE_FLAG_ROBUST, Embree's mode without the optimisations
// that cost accuracy (conservative box test, edge tests that do not let
// rays through shared edges): the guarantee Tessera's traversal always gives.
void embree_build(RTCDevice device, const TriangleSoup& s, EmbreeScene& es, bool robust = false) {
  es.release();
  es.scene = rtcNewScene(device);
  if (robust) rtcSetSceneFlags(es.scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(es.scene, RTC_BUILD_QUALITY_MEDIUM);
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_MEDIUM);
  const size_t nv = s.positions.size() / 3;
  float* v = static_cast<float*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
  std::memcpy(v, s.positions.data(), nv * 3 * sizeof(float));
  uint32_t* idx = static_cast<uint32_t*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), s.num_triangles()));
  std::memcpy(idx, s.indices.data(), s.indices.size() * sizeof(uint32_t));
  rtcCommitGeometry(g);
  rtcAttachGeometry(es.scene, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(es.scene);
}

// Ray i of the array as Embree takes it (segment [0, tmax]).
RTCRay embree_ray(const RayArray& rays, size_t i) {
  RTCRay r;
  r.org_x = rays.o[i].x, r.org_y = rays.o[i].y, r.org_z = rays.o[i].z;
  r.dir_x = rays.d[i].x, r.dir_y = rays.d[i].y, r.dir_z = rays.d[i].z;
  r.tnear = 0.0f;
  r.tfar = rays.tmax[i];
  r.time = 0.0f;
  r.mask = ~0u;
  r.id = 0;
  r.flags = 0;
  return r;
}

void embree_trace(RTCScene scene, const RayArray& rays, size_t begin, size_t end, Results& out) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  for (size_t i = begin; i < end; ++i) {
    if (rays.shadow) {
      RTCRay r = embree_ray(rays, i);
      rtcOccluded1(scene, &ctx, &r);
      out.t[i] = r.tfar < 0.0f ? 0.0f : kInf;
    } else {
      RTCRayHit rh;
      rh.ray = embree_ray(rays, i);
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene, &ctx, &rh);
      out.t[i] = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID ? rh.ray.tfar : kInf;
    }
  }
}

// ---------------------------------------------------------------- Tessera

Mesh tessera_build(const TriangleSoup& s, const BuildOptions& opt) {
  MeshInput in;
  in.positions = s.positions.data();
  in.num_vertices = s.positions.size() / 3;
  in.indices = s.indices.data();
  in.num_triangles = s.num_triangles();
  return build_mesh(in, opt);
}

// Diagnostic (DIFFDUMP=1): every triangle the scalar watertight test hits
// with tmax inf, with the distance to its plane in double.
void brute_force_dump(const TriangleSoup& s, const vec3& o, const vec3& d) {
  const RayShear sh(d);
  for (size_t k = 0; k < s.num_triangles(); ++k) {
    vec3 p[3];
    double P[3][3];
    for (int j = 0; j < 3; ++j) {
      const float* q = &s.positions[3 * s.indices[3 * k + j]];
      p[j] = vec3(q[0], q[1], q[2]);
      for (int c = 0; c < 3; ++c) P[j][c] = q[c];
    }
    double e1[3], e2[3], n[3];
    for (int c = 0; c < 3; ++c) e1[c] = P[1][c] - P[0][c], e2[c] = P[2][c] - P[0][c];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1], n[1] = e1[2] * e2[0] - e1[0] * e2[2], n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    const double dn = n[0] * d.x + n[1] * d.y + n[2] * d.z;
    const double tp = ((P[0][0] - o.x) * n[0] + (P[0][1] - o.y) * n[1] + (P[0][2] - o.z) * n[2]) / dn;
    TriangleHit h;
    const bool hit = intersect_triangle(p[0], p[1], p[2], o, sh, kInf, h);
    if (hit || (tp > 0 && tp < 10 && std::fabs(dn) > 0)) {
      // near misses: barycentrics in double
      double q[3] = {o.x + tp * d.x - P[0][0], o.y + tp * d.y - P[0][1], o.z + tp * d.z - P[0][2]};
      double d00 = e1[0]*e1[0]+e1[1]*e1[1]+e1[2]*e1[2], d01 = e1[0]*e2[0]+e1[1]*e2[1]+e1[2]*e2[2], d11 = e2[0]*e2[0]+e2[1]*e2[1]+e2[2]*e2[2];
      double d20 = q[0]*e1[0]+q[1]*e1[1]+q[2]*e1[2], d21 = q[0]*e2[0]+q[1]*e2[1]+q[2]*e2[2];
      double den = d00 * d11 - d01 * d01, bv = (d11 * d20 - d01 * d21) / den, bw = (d00 * d21 - d01 * d20) / den;
      double bu = 1 - bv - bw, mn = std::min(bu, std::min(bv, bw));
      if (hit || mn > -1e-5)
        std::fprintf(stderr, "   tri %zu hit %d t %.9g plane t %.12g bary min %.3g v %.9g %.9g %.9g / %.9g %.9g %.9g / %.9g %.9g %.9g\n", k, int(hit), hit ? h.t : -1.0f, tp, mn,
                     p[0].x, p[0].y, p[0].z, p[1].x, p[1].y, p[1].z, p[2].x, p[2].y, p[2].z);
    }
  }
}

void tessera_trace(const Mesh& mesh, const RayArray& rays, size_t begin, size_t end, Results& out,
                   TraversalOrder order, std::vector<uint32_t>* prims = nullptr) {
  for (size_t i = begin; i < end; ++i) {
    if (rays.shadow) {
      out.t[i] = occluded_mesh(mesh, rays.o[i], rays.d[i], rays.tmax[i]) ? 0.0f : kInf;
    } else {
      float tmax = rays.tmax[i];
      MeshHit h;
      bool hit = intersect_mesh(mesh, rays.o[i], rays.d[i], tmax, h, order);
      out.t[i] = hit ? h.t : kInf;
      if (prims) (*prims)[i] = hit ? h.prim : ~0u;
    }
  }
}

// Runs fn over the rays in chunks on `threads` threads; returns seconds.
constexpr size_t kChunk = 256;
double run_parallel(int threads, size_t n, const std::function<void(size_t, size_t)>& fn) {
  tbb::task_arena arena(threads);
  double secs = 0.0;
  arena.execute([&] {
    const bool cpu = g_cpu_clock && threads == 1;
    auto t0 = Clock::now();
    const double c0 = cpu ? thread_seconds() : 0.0;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kChunk),
                      [&](const tbb::blocked_range<size_t>& r) { fn(r.begin(), r.end()); });
    secs = cpu ? thread_seconds() - c0 : seconds_since(t0);
  });
  return secs;
}

// ---------------------------------------------------------------- rays

struct RaySets {
  std::vector<RayArray> sets;  // primary, diffuse, random, shadow
};

// A scene's own camera, from a PLY header line that
// scripts/export_scene_mesh.py writes: "comment camera eye forward up fov_y".
struct SceneCamera {
  bool valid = false;
  vec3 eye{0.0f}, forward{0.0f, 0.0f, -1.0f}, up{0.0f, 1.0f, 0.0f};
  float fov_y = 0.0f;
};

SceneCamera read_scene_camera(const std::string& path) {
  SceneCamera cam;
  std::ifstream in(path, std::ios::binary);
  std::string line;
  while (std::getline(in, line) && line != "end_header") {
    std::istringstream s(line);
    std::string a, b;
    s >> a >> b;
    if (a != "comment" || b != "camera") continue;
    s >> cam.eye.x >> cam.eye.y >> cam.eye.z >> cam.forward.x >> cam.forward.y >> cam.forward.z >> cam.up.x >>
        cam.up.y >> cam.up.z >> cam.fov_y;
    cam.valid = bool(s) && cam.fov_y > 0.0f;
  }
  return cam;
}

// Primary rays from the scene's camera when the file has one (an interior,
// seen from inside), else from a pinhole outside the mesh looking at it.
RaySets make_rays(const Mesh& mesh, int res, const SceneCamera& camera = {}) {
  RaySets rs;
  const AABB b = mesh.bounds();
  const vec3 c = b.center();
  const float radius = 0.5f * glm::length(b.extent());
  // Pinhole camera outside the mesh, 45 degree field of view, looking at the centre.
  float fov = 45.0f * kPi / 180.0f;
  vec3 view_dir = glm::normalize(vec3(-0.35f, -0.25f, -1.0f));
  vec3 eye = c - view_dir * (radius / std::sin(0.5f * fov) * 1.05f);
  vec3 right = glm::normalize(glm::cross(view_dir, vec3(0, 1, 0)));
  vec3 up = glm::cross(right, view_dir);
  // The point light the shadow rays go to: above and beside an outside
  // mesh; just above the camera inside a scene (the room the camera sees).
  vec3 light = c + radius * vec3(1.5f, 3.0f, 2.0f);
  if (camera.valid) {
    fov = camera.fov_y;
    view_dir = glm::normalize(camera.forward);
    eye = camera.eye;
    right = glm::normalize(glm::cross(view_dir, camera.up));
    up = glm::cross(right, view_dir);
    light = eye + 0.02f * radius * up;
  }
  const float tan_half = std::tan(0.5f * fov);
  RayArray primary;
  primary.kind = "primary";
  for (int y = 0; y < res; ++y)
    for (int x = 0; x < res; ++x) {
      float px = (2.0f * (x + 0.5f) / res - 1.0f) * tan_half;
      float py = (1.0f - 2.0f * (y + 0.5f) / res) * tan_half;
      primary.push(eye, glm::normalize(view_dir + px * right + py * up), kInf);
    }
  // Reference primary hits (Tessera, closest hit) to spawn secondary rays.
  Results ref;
  ref.t.resize(primary.size());
  std::vector<uint32_t> prims(primary.size());
  tessera_trace(mesh, primary, 0, primary.size(), ref, TraversalOrder::Ordered, &prims);

  RayArray diffuse, shadow, random;
  diffuse.kind = "diffuse";
  shadow.kind = "shadow";
  shadow.shadow = true;
  random.kind = "random";
  const float eps = 1e-4f * radius;
  const std::vector<vec3> verts = leaf_order_vertices(mesh);
  for (size_t i = 0; i < primary.size(); ++i) {
    if (ref.t[i] == kInf) continue;
    const vec3* v = &verts[3 * size_t(prims[i])];
    vec3 n = glm::cross(v[1] - v[0], v[2] - v[0]);
    float len = glm::length(n);
    if (!(len > 0.0f)) continue;
    n /= len;
    if (glm::dot(n, primary.d[i]) > 0.0f) n = -n;
    const vec3 p = primary.o[i] + ref.t[i] * primary.d[i] + eps * n;
    Rng rng(i * 7919 + 17);
    float r1 = rng.next(), r2 = rng.next();
    float r = std::sqrt(r1), phi = 2.0f * kPi * r2;
    Frame f(n);
    diffuse.push(p, glm::normalize(f.to_world(vec3(r * std::cos(phi), r * std::sin(phi), std::sqrt(1.0f - r1)))), kInf);
    vec3 to_light = light - p;
    float dist = glm::length(to_light);
    shadow.push(p, to_light / dist, dist * (1.0f - 1e-4f));
  }
  const size_t num_random = size_t(res) * size_t(res);
  for (size_t i = 0; i < num_random; ++i) {
    Rng rng(i * 104729 + 3);
    vec3 o = c + (b.extent() * 1.2f) * vec3(rng.next() - 0.5f, rng.next() - 0.5f, rng.next() - 0.5f);
    float z = 2.0f * rng.next() - 1.0f, phi = 2.0f * kPi * rng.next();
    float s = std::sqrt(std::max(0.0f, 1.0f - z * z));
    random.push(o, vec3(s * std::cos(phi), s * std::sin(phi), z), kInf);
  }
  rs.sets.push_back(std::move(primary));
  rs.sets.push_back(std::move(diffuse));
  rs.sets.push_back(std::move(random));
  rs.sets.push_back(std::move(shadow));
  return rs;
}

// Whether two hit distances along the ray from o (unit direction) agree:
// within 1e-4 relative, or within 4 float epsilons of the coordinates'
// magnitude at the hit, M = |o|_inf + t. A hit point, whichever engine
// computes it, is known to about an ulp of its coordinates, not of t: at
// t = 0.001 in a room 18 m across, 1e-4 relative is 1e-7, a twentieth of
// the coordinates' ulp (1.9e-6 at 18).
bool same_distance(float ta, float tb, const vec3& o) {
  const float t = std::max(std::abs(ta), std::abs(tb));
  const float m = std::max(std::abs(o.x), std::max(std::abs(o.y), std::abs(o.z))) + t;
  return std::abs(ta - tb) <= 1e-4f * t + 4.0f * FLT_EPSILON * m;
}

// Fraction of rays where both engines agree: same hit/miss and, for hits,
// the same distance (same_distance).
double agreement(const Results& a, const Results& b, const RayArray& rays, size_t* disagree) {
  size_t bad = 0;
  for (size_t i = 0; i < a.t.size(); ++i) {
    float ta = a.t[i], tb = b.t[i];
    bool ha = ta != kInf, hb = tb != kInf;
    if (ha != hb) ++bad;
    else if (ha && !same_distance(ta, tb, rays.o[i])) ++bad;
  }
  *disagree = bad;
  return a.t.empty() ? 1.0 : 1.0 - double(bad) / double(a.t.size());
}

std::string basename_of(const std::string& p) {
  size_t s = p.find_last_of('/');
  return s == std::string::npos ? p : p.substr(s + 1);
}

std::vector<int> parse_ints(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string tok;
  while (std::getline(ss, tok, ',')) out.push_back(std::stoi(tok));
  return out;
}

struct Config {
  std::string mode = "compare";
  int runs = 5;
  int res = 1024;
  std::vector<int> threads{1, 2};
  std::vector<int> bins{4, 8, 16, 32, 64};
  int builder_threads = 1;
  int builder_res = 512;
  std::vector<std::string> meshes;
  std::vector<std::string> builder_meshes;  // empty: all
  std::string kind = "all";         // --mode trace
  std::string engine = "tessera";   // --mode trace: tessera, sse2, embree or embree-robust
  bool engine_set = false;          // --mode build: both engines unless --engine is given
  std::string ab_base;              // --mode ab: options of the base tree
};

// ---------------------------------------------------------------- modes

std::string fmt_mb(size_t bytes) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", bytes / 1048576.0);
  return b;
}

// Minor page faults of the process so far (first touches of fresh memory; a
// load-independent figure, unlike the times).
double minor_faults() {
  rusage u;
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_minflt);
}

void compare(const Config& cfg) {
  std::printf("## Tessera vs Embree\n\n");
  std::printf("Build: median wall time of %d builds (Tessera: `build_mesh`, default options; Embree: scene + geometry "
              "setup and `rtcCommitScene`, RTC_BUILD_QUALITY_MEDIUM). Build ratio = Embree time / Tessera time "
              "(> 1: Tessera faster). SAH cost: Tessera's tree as traversed, relative to the root box area "
              "(traversal cost 1, triangle cost 1): \"binary\" is the binary SAH tree before collapsing (per triangle), \"wide\" the tree that is traversed (one step per node, one per 4-triangle block). "
              "Tessera's default path on this CPU: %s (%s).\n\n",
              cfg.runs, cpu_simd_level() != SimdLevel::AVX2 ? "sse2" : g_bvh8_avx512 ? "avx512" : "avx2",
              cpu_simd_level() != SimdLevel::AVX2 ? "BVH4, four-wide SSE2 node test"
              : g_bvh8_avx512 ? "BVH8, the AVX-512 kernel: eight-wide multiply-add node test into mask registers, in-register child sort"
                              : "BVH8, the AVX2 kernel: eight-wide multiply-add node test, in-register child sort");
  std::string build_table =
      "| mesh | triangles | threads | Tessera build ms | Embree build ms | ratio | Tessera SAH (binary) | Tessera SAH (wide) | Tessera MB | Embree MB |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  std::string trace_table =
      "| mesh | ray kind | rays | threads | Tessera Mrays/s | Tessera SSE2 BVH4 Mrays/s | Embree Mrays/s | Embree robust Mrays/s | ratio | ratio SSE2 | ratio robust | agreement |\n"
      "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  char line[512];
  for (const std::string& path : cfg.meshes) {
    TriangleSoup soup = load_mesh_file(path);
    const std::string name = basename_of(path);
    Mesh mesh;
    BuildOptions sse_opt;
    sse_opt.bvh_width = 4; if (getenv("ML")) sse_opt.max_leaf_size = atoi(getenv("ML"));
    const Mesh mesh_sse = tessera_build(soup, sse_opt);
    std::vector<EmbreeScene> escenes(cfg.threads.size()), robust_scenes(cfg.threads.size());
    std::vector<RTCDevice> devices;
    for (size_t ti = 0; ti < cfg.threads.size(); ++ti) {
      const int nt = cfg.threads[ti];
      std::string conf = "threads=" + std::to_string(nt);
      if (const char* ec = getenv("EMBREE_CONFIG")) conf += std::string(",") + ec;
      RTCDevice dev = rtcNewDevice(conf.c_str());
      rtcSetDeviceMemoryMonitorFunction(dev, embree_monitor, nullptr);
      devices.push_back(dev);
      tbb::global_control gc(tbb::global_control::max_allowed_parallelism, nt);
      tbb::task_arena arena(nt);
      std::vector<double> tt, te, tf, ef;
      arena.execute([&] {
        for (int r = 0; r < cfg.runs; ++r) {
          // The previous tree is released before the clock starts, for both
          // engines (as --mode build does): the figure is the build's.
          mesh = Mesh{};
          double f0 = minor_faults();
          auto t0 = Clock::now();
          mesh = tessera_build(soup, [] { BuildOptions o; if (getenv("ML")) o.max_leaf_size = atoi(getenv("ML")); return o; }());
          tt.push_back(seconds_since(t0));
          tf.push_back(minor_faults() - f0);
          escenes[ti].release();
          f0 = minor_faults();
          t0 = Clock::now();
          embree_build(dev, soup, escenes[ti]);
          te.push_back(seconds_since(t0));
          ef.push_back(minor_faults() - f0);
        }
      });
      std::fprintf(stderr, "%s %d threads: page faults per build (median) Tessera %.0f, Embree %.0f\n", name.c_str(), nt,
                   median(tf), median(ef));
      // Embree's bytes for this one scene: all scenes released, then the last build.
      escenes[ti].release();
      const long long before = g_embree_bytes.load();
      arena.execute([&] { embree_build(dev, soup, escenes[ti]); });
      const size_t ebytes = size_t(std::max(0LL, g_embree_bytes.load() - before));
      std::snprintf(line, sizeof line, "| %s | %zu | %d | %.1f | %.1f | %.2f | %.2f | %.2f | %.1f | %s |\n", name.c_str(),
                    soup.num_triangles(), nt, 1e3 * median(tt), 1e3 * median(te), median(te) / median(tt),
                    mesh_sah_cost(mesh), mesh.width() == 8 ? sah_cost(mesh.bvh8) : sah_cost(mesh.bvh),
                    mesh.memory_bytes() / 1048576.0, ebytes ? fmt_mb(ebytes).c_str() : "-");
      build_table += line;
      std::fprintf(stderr, "%s", line);
      arena.execute([&] { embree_build(dev, soup, robust_scenes[ti], /*robust=*/true); });
    }
    RaySets rs = make_rays(mesh, cfg.res, read_scene_camera(path));
    for (const RayArray& rays : rs.sets) {
      for (size_t ti = 0; ti < cfg.threads.size(); ++ti) {
        const int nt = cfg.threads[ti];
        tbb::global_control gc(tbb::global_control::max_allowed_parallelism, nt);
        Results rt, re, rs4, rr;
        rt.t.assign(rays.size(), -1.0f);
        re.t.assign(rays.size(), -1.0f);
        rs4.t.assign(rays.size(), -1.0f);
        rr.t.assign(rays.size(), -1.0f);
        RTCScene es = escenes[ti].scene, er = robust_scenes[ti].scene;
        std::vector<double> st, se, s4, sr;
        for (int r = 0; r < cfg.runs; ++r) {
          st.push_back(run_parallel(nt, rays.size(), [&](size_t b, size_t e) {
            tessera_trace(mesh, rays, b, e, rt, TraversalOrder::Ordered);
          }));
          s4.push_back(run_parallel(nt, rays.size(), [&](size_t b, size_t e) {
            tessera_trace(mesh_sse, rays, b, e, rs4, TraversalOrder::Ordered);
          }));
          se.push_back(run_parallel(nt, rays.size(), [&](size_t b, size_t e) { embree_trace(es, rays, b, e, re); }));
          sr.push_back(run_parallel(nt, rays.size(), [&](size_t b, size_t e) { embree_trace(er, rays, b, e, rr); }));
        }
        size_t bad = 0;
        double agree = agreement(rt, re, rays, &bad);
        if (rs4.t != rt.t) std::fprintf(stderr, "warning: BVH4 and BVH8 results differ on %s %s\n", name.c_str(), rays.kind.c_str());
        if (getenv("DIFFDUMP"))
          for (size_t i = 0; i < rays.size(); ++i)
            if (rs4.t[i] != rt.t[i] || (rt.t[i] != re.t[i] && !same_distance(rt.t[i], re.t[i], rays.o[i])))
              std::fprintf(stderr, "ray %zu o %.9g %.9g %.9g d %.9g %.9g %.9g tmax %.9g: t8 %.9g t4 %.9g embree %.9g\n", i,
                           rays.o[i].x, rays.o[i].y, rays.o[i].z, rays.d[i].x, rays.d[i].y, rays.d[i].z, rays.tmax[i],
                           rt.t[i], rs4.t[i], re.t[i]),
              brute_force_dump(soup, rays.o[i], rays.d[i]);
        double mt = rays.size() / median(st) * 1e-6, me = rays.size() / median(se) * 1e-6;
        double m4 = rays.size() / median(s4) * 1e-6, mr = rays.size() / median(sr) * 1e-6;
        std::snprintf(line, sizeof line, "| %s | %s | %zu | %d | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.4f%% (%zu differ) |\n",
                      name.c_str(), rays.kind.c_str(), rays.size(), nt, mt, m4, me, mr, mt / me, m4 / me, mt / mr,
                      100.0 * agree, bad);
        trace_table += line;
        std::fprintf(stderr, "%s", line);
      }
    }
    escenes.clear();
    robust_scenes.clear();
    for (RTCDevice d : devices) rtcReleaseDevice(d);
  }
  std::printf("### Build\n\n%s\n### Traversal\n\nMrays/s = rays / median %s of %d passes over the whole ray "
              "array. Ratio = Tessera (default path) / Embree (>= 1: Tessera as fast or faster); ratio SSE2 = the SSE2 BVH4 fallback (what runs on CPUs without AVX2) / Embree, measured in the same loop; ratio robust = Tessera / Embree with RTC_SCENE_FLAG_ROBUST (its mode without the optimisations that cost accuracy, the guarantee Tessera's watertight test and conservative box test always give), same build quality, same loop. Agreement: same hit/miss and, for "
              "hits, distances within 1e-4 relative or 4 float epsilons of the hit's coordinates (|o|_inf + t): "
              "a hit point is known to about an ulp of its coordinates, whichever engine computes it.\n\n%s\n",
              build_table.c_str(), g_cpu_clock ? "time (1 thread: thread CPU time, 2 threads: wall time)" : "wall time",
              cfg.runs, trace_table.c_str());
  std::fflush(stdout);
}

// The base tree's build options and triangles named by --ab-base (--mode ab;
// --mode trace builds with them too).
BuildOptions ab_options(const std::string& spec) {
  BuildOptions base_opt;
  if (spec.find("no-collapse") != std::string::npos) base_opt.collapse_small_subtrees = false;
  if (spec.find("separate-leaves") != std::string::npos) base_opt.leaves_next_to_parent = false;
  // max-leaf=N, sah-block=N, bins=N, tri-cost=X: the binary build's options.
  auto opt_value = [&](const char* key) -> const char* {
    const size_t at = spec.find(key);
    return at == std::string::npos ? nullptr : spec.c_str() + at + std::strlen(key);
  };
  if (const char* v = opt_value("max-leaf=")) base_opt.max_leaf_size = std::atoi(v);
  if (const char* v = opt_value("sah-block=")) base_opt.sah_block_size = std::atoi(v);
  if (const char* v = opt_value("bins=")) base_opt.bins = std::atoi(v);
  if (const char* v = opt_value("tri-cost=")) base_opt.intersection_cost = float(std::atof(v));
  if (spec.find("sweep") != std::string::npos) base_opt.method = SplitMethod::SweepSAH;
  return base_opt;
}

// drop-degenerate: leaves out triangles with two equal vertices (the
// watertight test never hits them: one edge function is zero and the other
// two are exact opposites), as a build could.
TriangleSoup ab_soup(const TriangleSoup& soup, const std::string& spec) {
  if (spec.find("drop-degenerate") == std::string::npos) return soup;
  TriangleSoup out = soup;
  out.indices.clear();
  const float* p = soup.positions.data();
  auto same = [&](uint32_t a, uint32_t b) {
    return p[3 * a] == p[3 * b] && p[3 * a + 1] == p[3 * b + 1] && p[3 * a + 2] == p[3 * b + 2];
  };
  for (size_t t = 0; t < soup.num_triangles(); ++t) {
    const uint32_t* i = &soup.indices[3 * t];
    if (same(i[0], i[1]) || same(i[1], i[2]) || same(i[0], i[2])) continue;
    out.indices.insert(out.indices.end(), i, i + 3);
  }
  std::printf("drop-degenerate: %zu of %zu triangles left out\n", soup.num_triangles() - out.num_triangles(),
              soup.num_triangles());
  return out;
}

// --mode trace: one engine on one ray kind, repeated, for profilers (perf)
// and A/B runs; prints Mrays/s per pass.
void trace_only(const Config& cfg) {
  for (const std::string& path : cfg.meshes) {
    TriangleSoup soup = ab_soup(load_mesh_file(path), cfg.ab_base);
    BuildOptions opt = ab_options(cfg.ab_base);
    if (cfg.engine == "sse2") opt.bvh_width = 4;
    const Mesh mesh = tessera_build(soup, opt);
    RTCDevice dev = rtcNewDevice("threads=1");
    EmbreeScene es;
    const bool embree = cfg.engine == "embree" || cfg.engine == "embree-robust";
    if (embree) embree_build(dev, soup, es, cfg.engine == "embree-robust");
    RaySets rs = make_rays(mesh, cfg.res, read_scene_camera(path));
    if (getenv("MISS")) {  // rays that miss the root box: the per-ray cost outside the traversal loop
      const vec3 c = mesh.bounds().center();
      const float radius = glm::length(mesh.bounds().extent());
      for (RayArray& rays : rs.sets)
        for (size_t i = 0; i < rays.size(); ++i) rays.o[i] = c + 4.0f * radius * rays.d[i];
    }
    for (const RayArray& rays : rs.sets) {
      if (rays.kind != cfg.kind && cfg.kind != "all") continue;
      Results out;
      out.t.assign(rays.size(), -1.0f);
      std::vector<double> st;
      for (int r = 0; r < cfg.runs; ++r)
        st.push_back(run_parallel(1, rays.size(), [&](size_t b, size_t e) {
          if (embree) embree_trace(es.scene, rays, b, e, out);
          else tessera_trace(mesh, rays, b, e, out, TraversalOrder::Ordered);
        }));
      std::printf("%s %s %s %.3f Mrays/s\n", basename_of(path).c_str(), rays.kind.c_str(), cfg.engine.c_str(),
                  rays.size() / median(st) * 1e-6);
      if (getenv("PASSES")) {  // each pass's Mrays/s, in order
        for (double s : st) std::printf(" %.1f", rays.size() / s * 1e-6);
        std::printf("\n");
      }
#ifdef TESSERA_BVH_COUNTERS
      {  // per ray over all passes; node visits by number of children hit
        WideCounters& c = g_wide_counters;
        const double n = double(c.rays);
        std::printf("  per ray: nodes %.2f, children hit %.2f, leaves %.2f, blocks %.2f, sign pass %.2f, t pass %.2f, zero-edge blocks %.3f\n  visits by hits:",
                    c.nodes / n, c.hits_children / n, c.leaves / n, c.blocks / n, c.sign_pass / n, c.t_pass / n, c.zero_path / n);
        for (int k = 0; k <= 8; ++k) std::printf(" %d:%.1f%%", k, 100.0 * c.hit_hist[k] / double(c.nodes));
        std::printf("\n");
        c = WideCounters{};
      }
#endif

      std::fflush(stdout);
    }
    es.release();
    rtcReleaseDevice(dev);
  }
}

// --mode ab: the default tree against one built with the options named by
// --ab-base (comma-separated: no-collapse, separate-leaves), both traced by
// the default traversal, alternating pass by pass over the same rays in one
// process; prints both and the median of the per-pass ratios.
void ab(const Config& cfg) {
  for (const std::string& path : cfg.meshes) {
    TriangleSoup soup = load_mesh_file(path);
    const Mesh mesh = tessera_build(soup, BuildOptions{});
    BuildOptions base_opt = ab_options(cfg.ab_base);
    const TriangleSoup base_soup = ab_soup(soup, cfg.ab_base);
    const Mesh base = tessera_build(base_soup, base_opt);
    // avx2-kernel: the base passes run the AVX2 BVH8 traversal instead of the AVX-512 one.
    const bool new_kernel = g_bvh8_avx512;
    const bool base_kernel = cfg.ab_base.find("avx2-kernel") != std::string::npos ? false : new_kernel;
    auto nodes = [](const Mesh& m) { return m.width() == 8 ? m.bvh8.num_nodes : m.bvh.num_nodes; };
    auto blocks = [](const Mesh& m) { return m.width() == 8 ? m.bvh8.num_blocks : m.bvh.num_blocks; };
    auto wide_sah = [](const Mesh& m) { return m.width() == 8 ? sah_cost(m.bvh8) : sah_cost(m.bvh); };
    std::printf("%s: nodes %u / %u, blocks %u / %u, wide SAH %.2f / %.2f, MB %.1f / %.1f (base / new)\n",
                basename_of(path).c_str(), nodes(base), nodes(mesh), blocks(base), blocks(mesh), wide_sah(base),
                wide_sah(mesh), base.memory_bytes() / 1048576.0, mesh.memory_bytes() / 1048576.0);
    RaySets rs = make_rays(mesh, cfg.res, read_scene_camera(path));
    for (const RayArray& rays : rs.sets) {
      if (rays.kind != cfg.kind && cfg.kind != "all") continue;
      Results a, b;
      a.t.assign(rays.size(), -1.0f);
      b.t.assign(rays.size(), -1.0f);
      std::vector<double> sa, sb, ratio;
      for (int r = 0; r < cfg.runs; ++r) {
        g_bvh8_avx512 = base_kernel;
        sb.push_back(run_parallel(1, rays.size(), [&](size_t i0, size_t i1) {
          tessera_trace(base, rays, i0, i1, b, TraversalOrder::Ordered);
        }));
        g_bvh8_avx512 = new_kernel;
        sa.push_back(run_parallel(1, rays.size(), [&](size_t i0, size_t i1) {
          tessera_trace(mesh, rays, i0, i1, a, TraversalOrder::Ordered);
        }));
        ratio.push_back(sb.back() / sa.back());
      }
      size_t bad = 0, inexact = 0;
      agreement(a, b, rays, &bad);
      for (size_t i = 0; i < rays.size(); ++i) inexact += std::memcmp(&a.t[i], &b.t[i], sizeof(float)) != 0;
      std::printf("%-20s %-8s base %6.2f new %6.2f Mrays/s  new/base %.3f  (%zu differ, %zu not bit-identical)\n",
                  basename_of(path).c_str(), rays.kind.c_str(), rays.size() / median(sb) * 1e-6,
                  rays.size() / median(sa) * 1e-6, median(ratio), bad, inexact);
      std::fflush(stdout);
    }
  }
}

// --mode stats: the default BVH8's shape: nodes by child count, leaves by
// block count, triangles per block (distinct, the rest repeat the last),
// and the depth of the leaves.
void tree_stats(const Config& cfg) {
  for (const std::string& path : cfg.meshes) {
    TriangleSoup soup = load_mesh_file(path);
    const Mesh mesh = tessera_build(soup, BuildOptions{});
    if (mesh.width() != 8) continue;
    const BVH8& b = mesh.bvh8;
    size_t kids[9] = {}, leaf_blocks[9] = {}, lanes[5] = {}, leaves = 0, nodes = 0, depth_sum = 0, tris = 0;
    std::vector<std::pair<uint32_t, int>> todo{{0u, 0}};
    while (!todo.empty()) {
      auto [ref, depth] = todo.back();
      todo.pop_back();
      const BVH8Node& n = b.node(ref);
      ++nodes;
      ++kids[n.num_children];
      for (int c = 0; c < 8; ++c) {
        const uint32_t r = n.child[c];
        if (r == kBVH4EmptyChild) continue;
        if (!bvh4_is_leaf(r)) {
          todo.push_back({r, depth + 1});
          continue;
        }
        ++leaves;
        depth_sum += depth + 1;
        ++leaf_blocks[bvh4_leaf_blocks(r)];
        const Tri4* t = b.blocks(r);
        for (uint32_t k = 0; k < bvh4_leaf_blocks(r); ++k) {
          int distinct = 1;
          for (int l = 1; l < 4; ++l) distinct += t[k].prim[l] != t[k].prim[l - 1];
          ++lanes[distinct];
          tris += distinct;
        }
      }
    }
    std::printf("%s: %zu triangles, %zu nodes, %zu leaves (mean depth %.2f), %zu blocks, %.2f triangles per block, wide SAH %.2f, binary SAH %.2f\n",
                basename_of(path).c_str(), soup.num_triangles(), nodes, leaves, double(depth_sum) / leaves,
                size_t(b.num_blocks), double(tris) / b.num_blocks, sah_cost(b), mesh_sah_cost(mesh));
    std::printf("  nodes by children:");
    for (int k = 1; k <= 8; ++k) std::printf(" %d:%.1f%%", k, 100.0 * kids[k] / nodes);
    std::printf("\n  leaves by blocks:");
    for (int k = 1; k <= 8; ++k) if (leaf_blocks[k]) std::printf(" %d:%.1f%%", k, 100.0 * leaf_blocks[k] / leaves);
    std::printf("\n  blocks by triangles:");
    for (int k = 1; k <= 4; ++k) std::printf(" %d:%.1f%%", k, 100.0 * lanes[k] / b.num_blocks);
    std::printf("\n");
  }
}

void builders(const Config& cfg) {
  const int nt = cfg.builder_threads;
  std::printf("## Tessera builders and traversal order\n\n");
  std::printf("Threads: %d, rays from a %dx%d image (same kinds as above). Medians of %d runs. Throughput in Mrays/s (closest hit for primary / diffuse / random, "
              "any hit for shadow). Sweep = full-sweep SAH (sorts every axis at every node).\n\n",
              nt, cfg.builder_res, cfg.builder_res, cfg.runs);
  std::printf("| mesh | builder | traversal | build ms | SAH (binary) | SAH (wide) | primary | diffuse | random | shadow |\n"
              "|---|---|---|---:|---:|---:|---:|---:|---:|---:|\n");
  std::fflush(stdout);
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, nt);
  for (const std::string& path : cfg.meshes) {
    const std::string name = basename_of(path);
    if (!cfg.builder_meshes.empty() &&
        std::find(cfg.builder_meshes.begin(), cfg.builder_meshes.end(), name) == cfg.builder_meshes.end())
      continue;
    TriangleSoup soup = load_mesh_file(path);
    RaySets rs = make_rays(tessera_build(soup, BuildOptions{}), cfg.builder_res, read_scene_camera(path));
    struct Variant { std::string label; BuildOptions opt; };
    std::vector<Variant> variants;
    { BuildOptions o; o.method = SplitMethod::Midpoint; variants.push_back({"midpoint", o}); }
    { BuildOptions o; o.method = SplitMethod::SweepSAH; variants.push_back({"sweep SAH", o}); }
    for (int bins : cfg.bins) {
      BuildOptions o;
      o.method = SplitMethod::BinnedSAH;
      o.bins = bins;
      variants.push_back({"binned SAH, " + std::to_string(bins) + " bins", o});
    }
    for (const Variant& v : variants) {
      Mesh mesh;
      std::vector<double> tb;
      tbb::task_arena arena(nt);
      arena.execute([&] {
        for (int r = 0; r < cfg.runs; ++r) {
          auto t0 = Clock::now();
          mesh = tessera_build(soup, v.opt);
          tb.push_back(seconds_since(t0));
        }
      });
      for (TraversalOrder order : {TraversalOrder::Ordered, TraversalOrder::Unordered}) {
        std::string cells;
        for (const RayArray& rays : rs.sets) {
          Results rt;
          rt.t.resize(rays.size());
          std::vector<double> st;
          for (int r = 0; r < cfg.runs; ++r)
            st.push_back(run_parallel(nt, rays.size(),
                                      [&](size_t b, size_t e) { tessera_trace(mesh, rays, b, e, rt, order); }));
          char c[32];
          std::snprintf(c, sizeof c, " %.2f |", rays.size() / median(st) * 1e-6);
          cells += c;
        }
        std::printf("| %s | %s | %s | %.1f | %.2f | %.2f |%s\n", name.c_str(), v.label.c_str(),
                    order == TraversalOrder::Ordered ? "ordered" : "unordered", 1e3 * median(tb),
                    mesh_sah_cost(mesh), mesh.width() == 8 ? sah_cost(mesh.bvh8) : sah_cost(mesh.bvh), cells.c_str());
        std::fflush(stdout);
      }
    }
  }
  std::printf("\n");
}

// --mode build: builds only. Per thread count, the engines alternate
// (Tessera, Embree, Tessera, ...) in one task_arena; wall time and the
// process's CPU time (all threads) per build, medians; ratio = Embree /
// Tessera. --engine tessera or embree builds only that one (for perf).
double process_seconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// FNV-1a over the wide tree as traversed (nodes reached from the root, their
// leaf blocks, depth first; the arena's padding is left out) and prim_ids:
// equal hashes from two builds (or two versions of the builder) mean the
// traversal sees the same tree.
template <typename Tree>
uint64_t tree_hash(const Tree& t, const std::vector<uint32_t>& prim_ids) {
  uint64_t h = 1469598103934665603ull;
  auto add = [&](const void* p, size_t n) {
    for (size_t i = 0; i < n; ++i) h = (h ^ static_cast<const unsigned char*>(p)[i]) * 1099511628211ull;
  };
  std::vector<uint32_t> stack{0u};
  while (!stack.empty() && !t.empty()) {
    const auto& node = t.node(stack.back());
    stack.pop_back();
    add(&node, sizeof(node));
    for (uint32_t c = 0; c < node.num_children; ++c) {
      const uint32_t ref = node.child[c];
      if (bvh4_is_leaf(ref)) add(t.blocks(ref), bvh4_leaf_blocks(ref) * sizeof(Tri4));
      else stack.push_back(ref);
    }
  }
  add(prim_ids.data(), prim_ids.size() * sizeof(uint32_t));
  return h;
}

void build_only(const Config& cfg) {
  const bool do_t = !cfg.engine_set || cfg.engine != "embree", do_e = !cfg.engine_set || cfg.engine == "embree" || cfg.engine == "both";
  std::printf("| mesh | threads | Tessera wall ms | Embree wall ms | ratio wall | Tessera CPU ms | Embree CPU ms | ratio CPU | SAH binary | SAH wide | Tessera faults | Embree faults | tree hash |\n"
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
  for (const std::string& path : cfg.meshes) {
    TriangleSoup soup = load_mesh_file(path);
    const std::string name = basename_of(path);
    for (int nt : cfg.threads) {
      std::string conf = "threads=" + std::to_string(nt);
      RTCDevice dev = do_e ? rtcNewDevice(conf.c_str()) : nullptr;
      EmbreeScene es;
      Mesh mesh;
      tbb::global_control gc(tbb::global_control::max_allowed_parallelism, nt);
      tbb::task_arena arena(nt);
      std::vector<double> tw, tc, ew, ec, tf, ef;
      arena.execute([&] {
        for (int r = 0; r < cfg.runs; ++r) {
          if (do_t) {
            mesh = Mesh{};  // the old mesh's release is not timed
            const double f0 = minor_faults(), c0 = process_seconds();
            auto t0 = Clock::now();
            mesh = tessera_build(soup, BuildOptions{});
            tw.push_back(seconds_since(t0));
            tc.push_back(process_seconds() - c0);
            tf.push_back(minor_faults() - f0);
          }
          if (do_e) {
            es.release();
            const double f0 = minor_faults(), c0 = process_seconds();
            auto t0 = Clock::now();
            embree_build(dev, soup, es);
            ew.push_back(seconds_since(t0));
            ec.push_back(process_seconds() - c0);
            ef.push_back(minor_faults() - f0);
          }
        }
      });
      es.release();
      if (dev) rtcReleaseDevice(dev);
      auto ms = [](const std::vector<double>& v) { return v.empty() ? 0.0 : 1e3 * median(v); };
      auto ratio = [&](const std::vector<double>& e, const std::vector<double>& t) {
        return e.empty() || t.empty() ? 0.0 : median(e) / median(t);
      };
      auto med = [](const std::vector<double>& v) { return v.empty() ? 0.0 : median(v); };
      const uint64_t hash = !do_t ? 0 : mesh.width() == 8 ? tree_hash(mesh.bvh8, mesh.prim_ids) : tree_hash(mesh.bvh, mesh.prim_ids);
      std::printf("| %s | %d | %.2f | %.2f | %.3f | %.2f | %.2f | %.3f | %.2f | %.2f | %.0f | %.0f | %016llx |\n", name.c_str(), nt,
                  ms(tw), ms(ew), ratio(ew, tw), ms(tc), ms(ec), ratio(ec, tc), do_t ? mesh_sah_cost(mesh) : 0.0f,
                  do_t ? (mesh.width() == 8 ? sah_cost(mesh.bvh8) : sah_cost(mesh.bvh)) : 0.0f, med(tf), med(ef),
                  (unsigned long long)hash);
      std::fflush(stdout);
    }
  }
}

// --mode watertight (and --mode all): what the engines' speed buys, or
// leaves out. The rays of the native test Numerics.WatertightAtSharedEdgesAndVertices:
// aimed exactly at the vertices of a closed UV sphere (48 rings, 96
// segments) and at 7 points along each shared edge, from inside and from
// outside (a 60-degree cone around the normal), at four scales and
// placements. A ray that hits nowhere near its target went through a crack
// between two triangles. Counted for Tessera, Embree and Embree robust
// (RTC_SCENE_FLAG_ROBUST); one thread, same rays.
void watertight(const Config&) {
  struct Case { float radius; vec3 center; const char* name; };
  const Case cases[] = {{1.0f, vec3(0.0f), "radius 1 at the origin"},
                        {1e-4f, vec3(0.0f), "radius 1e-4 at the origin"},
                        {1e4f, vec3(0.0f), "radius 1e4 at the origin"},
                        {1.0f, vec3(1e3f, 0.0f, -1e3f), "radius 1 at (1e3, 0, -1e3)"}};
  std::printf("## Watertightness: rays at shared edges and vertices\n\n"
              "The rays of the native test `Numerics.WatertightAtSharedEdgesAndVertices` (`fixtures::for_each_edge_ray`): "
              "aimed exactly at each vertex and at 7 points along each edge of a closed UV sphere (48 x 96, 9,024 "
              "triangles), 4 from inside and 4 from outside per point; a ray whose hit is not within 1e-3 radii of its "
              "target (or that hits nothing) went through a crack. What each engine's speed above is bought with.\n\n"
              "| sphere | rays | Tessera through | Embree through | Embree robust through |\n|---|---:|---:|---:|---:|\n");
  RTCDevice dev = rtcNewDevice("threads=1");
  for (const Case& cs : cases) {
    fixtures::SphereMesh m = fixtures::uv_sphere(48, 96, cs.radius, cs.center);
    RayArray rays;
    std::vector<float> dist;
    for (size_t t = 0; t < m.idx.size() / 3; ++t)
      fixtures::for_each_edge_ray(m, cs.center, cs.radius, t, [&](const vec3& o, const vec3& d, float to_target) {
        rays.push(o, d, kInf);
        dist.push_back(to_target);
      });
    TriangleSoup soup;
    soup.positions = std::move(m.pos);
    soup.indices = std::move(m.idx);
    const Mesh mesh = tessera_build(soup, BuildOptions{});
    EmbreeScene plain, robust;
    embree_build(dev, soup, plain);
    embree_build(dev, soup, robust, /*robust=*/true);
    Results r[3];
    for (Results& x : r) x.t.assign(rays.size(), kInf);
    tessera_trace(mesh, rays, 0, rays.size(), r[0], TraversalOrder::Ordered);
    embree_trace(plain.scene, rays, 0, rays.size(), r[1]);
    embree_trace(robust.scene, rays, 0, rays.size(), r[2]);
    size_t through[3] = {0, 0, 0};
    for (int x = 0; x < 3; ++x)
      for (size_t i = 0; i < rays.size(); ++i)
        if (!(std::abs(r[x].t[i] - dist[i]) <= 1e-3f * cs.radius)) ++through[x];
    std::printf("| %s | %zu | %zu | %zu | %zu |\n", cs.name, rays.size(), through[0], through[1], through[2]);
    std::fflush(stdout);
  }
  rtcReleaseDevice(dev);
  std::printf("\n");
}

}  // namespace

int main(int argc, char** argv) {
  Config cfg;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error("missing value after " + a);
      return argv[++i];
    };
    if (a == "--mode") cfg.mode = next();
    else if (a == "--kind") cfg.kind = next();
    else if (a == "--engine") cfg.engine = next(), cfg.engine_set = true;
    else if (a == "--ab-base") cfg.ab_base = next();
    else if (a == "--runs") cfg.runs = std::stoi(next());
    else if (a == "--clock") g_cpu_clock = next() == "cpu";
    else if (a == "--stat") g_min_stat = next() == "min";
    else if (a == "--res") cfg.res = std::stoi(next());
    else if (a == "--threads") cfg.threads = parse_ints(next());
    else if (a == "--bins") cfg.bins = parse_ints(next());
    else if (a == "--builder-threads") cfg.builder_threads = std::stoi(next());
    else if (a == "--builder-res") cfg.builder_res = std::stoi(next());
    else if (a == "--builder-meshes") {
      std::stringstream ss(next());
      std::string tok;
      while (std::getline(ss, tok, ',')) cfg.builder_meshes.push_back(tok);
    } else if (a.rfind("--", 0) == 0) {
      std::fprintf(stderr, "unknown option %s\n", a.c_str());
      return 2;
    } else cfg.meshes.push_back(a);
  }
  if (cfg.meshes.empty() && cfg.mode != "watertight") {
    std::fprintf(stderr, "usage: bench_bvh [--mode compare|builders|watertight|all] [--runs N] [--res R] [--threads 1,2] "
                         "[--bins 4,8,16] [--builder-threads T] [--builder-res R] [--builder-meshes a.obj,b.ply] mesh...\n");
    return 2;
  }
  if (cfg.mode == "compare" || cfg.mode == "all") compare(cfg);
  if (cfg.mode == "builders" || cfg.mode == "all") builders(cfg);
  if (cfg.mode == "watertight" || cfg.mode == "all") watertight(cfg);
  if (cfg.mode == "trace") trace_only(cfg);
  if (cfg.mode == "ab") ab(cfg);
  if (cfg.mode == "stats") tree_stats(cfg);
  if (cfg.mode == "build") build_only(cfg);
  return 0;
}
