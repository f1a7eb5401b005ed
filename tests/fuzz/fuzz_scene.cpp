// libFuzzer target: random buffers as a triangle soup (positions may be
// NaN/Inf/huge/denormal, indices out of range) go through build_mesh, an
// instance with a random transform, commit (TLAS, light sampler), and rays
// traced against the result. Nothing may crash, hang or read out of bounds.
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/scene.h"

using namespace tessera;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 8) return 0;
  const uint32_t nv = 1 + data[0] % 64, nt = data[1] % 96;
  const uint8_t flags = data[2];
  data += 3, size -= 3;
  auto take_float = [&](float fallback) {
    if (size < 4) return fallback;
    float f;
    std::memcpy(&f, data, 4);
    data += 4, size -= 4;
    return f;
  };
  std::vector<float> pos(3 * nv), normals;
  for (float& p : pos) p = take_float(0.5f);
  std::vector<uint32_t> idx(3 * nt), slots(nt);
  for (uint32_t& i : idx) {
    i = size ? data[0] % (nv + 2) : 0;  // sometimes out of range
    if (size) ++data, --size;
  }
  for (uint32_t& s : slots) s = size ? (data[0] % 4) : 0;
  if (flags & 1) {
    normals.resize(9 * nt);
    for (float& n : normals) n = take_float(0.0f);
  }
  Scene s;
  Material emit;
  emit.emission_front = vec3(take_float(1.0f), 1.0f, 1.0f);
  s.materials.push_back(emit);
  MeshInput in;
  in.positions = pos.data();
  in.num_vertices = nv;
  in.indices = idx.data();
  in.num_triangles = nt;
  in.material_slots = slots.data();
  in.corner_normals = (flags & 1) ? normals.data() : nullptr;
  s.meshes.push_back(build_mesh(in));
  mat4 xf(1.0f);
  if (flags & 2)
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 3; ++r) xf[c][r] = take_float(xf[c][r]);
  s.add_instance(0, xf, {0, 1, 0, 1});
  if (flags & 4) s.add_instance(0, mat4(1.0f), {1});
  s.commit();
  for (int i = 0; i < 16; ++i) {
    Ray r{vec3(take_float(0.0f), take_float(0.0f), take_float(5.0f)),
          vec3(take_float(0.1f), take_float(0.2f), take_float(-1.0f)), kInf};
    Hit h;
    if (s.intersect(r, h)) {
      SurfaceInteraction si = s.interaction(r, h);
      (void)si;
    }
    s.occluded(r.o, r.d, take_float(100.0f));
  }
  return 0;
}
