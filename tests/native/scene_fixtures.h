// Small scenes built in code for the native tests.
#pragma once
#include <random>
#include <vector>

#include "core/scene.h"

namespace tessera::fixtures {

// A UV sphere with shared vertices (poles shared by a whole fan), closed
// (test_numerics.cpp's watertightness and self-intersection tests, and
// bench_bvh --mode watertight).
struct SphereMesh {
  std::vector<float> pos;
  std::vector<uint32_t> idx;
};
inline SphereMesh uv_sphere(int rings, int segments, float radius, vec3 center) {
  SphereMesh m;
  auto add = [&](vec3 p) {
    p = center + radius * p;
    m.pos.insert(m.pos.end(), {p.x, p.y, p.z});
  };
  add(vec3(0, 0, 1));
  for (int i = 1; i < rings; ++i) {
    float th = kPi * i / rings;
    for (int j = 0; j < segments; ++j) {
      float ph = 2.0f * kPi * j / segments;
      add(vec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)));
    }
  }
  add(vec3(0, 0, -1));
  const uint32_t south = uint32_t(m.pos.size() / 3 - 1);
  auto ring = [&](int i, int j) { return uint32_t(1 + (i - 1) * segments + (j % segments)); };
  for (int j = 0; j < segments; ++j) {
    m.idx.insert(m.idx.end(), {0u, ring(1, j), ring(1, j + 1)});
    m.idx.insert(m.idx.end(), {south, ring(rings - 1, j + 1), ring(rings - 1, j)});
  }
  for (int i = 1; i < rings - 1; ++i)
    for (int j = 0; j < segments; ++j) {
      m.idx.insert(m.idx.end(), {ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.idx.insert(m.idx.end(), {ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  return m;
}

// The rays of the watertightness test for triangle t of sphere m (centre
// c, radius r): for each edge a-b, aimed exactly at the vertex a and at 7
// points along the edge (each edge is shared by two triangles, so each is
// visited from both sides), 4 from near the centre and 4 from outside,
// within a 60-degree cone around the normal (not grazing the silhouette).
// fn(o, d, dist): unit direction d, dist from o to the target. Seeded by t,
// so the rays do not depend on the order triangles are visited in.
template <typename Fn>
void for_each_edge_ray(const SphereMesh& m, vec3 c, float r, size_t t, Fn&& fn) {
  const vec3* pos = reinterpret_cast<const vec3*>(m.pos.data());
  std::mt19937 rng(uint32_t(t) * 7919u + 1u);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int e = 0; e < 3; ++e) {
    const vec3 a = pos[m.idx[3 * t + e]], b = pos[m.idx[3 * t + (e + 1) % 3]];
    for (int k = 0; k < 8; ++k) {
      const vec3 target = k == 0 ? a : a + (k / 8.0f) * (b - a);
      const vec3 n = glm::normalize(target - c);
      for (int j = 0; j < 8; ++j) {
        vec3 o;
        if (j < 4) {
          o = c + 0.5f * r * (vec3(u(rng), u(rng), u(rng)) - 0.5f);
        } else {
          Frame fr(n);
          float z = 0.5f + 0.5f * u(rng), phi = 2.0f * kPi * u(rng), s = std::sqrt(1.0f - z * z);
          o = target + 2.0f * r * fr.to_world(vec3(s * std::cos(phi), s * std::sin(phi), z));
        }
        const vec3 d = target - o;
        const float dist = glm::length(d);
        fn(o, d / dist, dist);
      }
    }
  }
}

// The mesh input over vertex positions (3 floats each) and triangle indices
// (3 each) that the caller keeps alive.
inline MeshInput mesh_input(const std::vector<float>& pos, const std::vector<uint32_t>& idx) {
  MeshInput in;
  in.positions = pos.data();
  in.num_vertices = pos.size() / 3;
  in.indices = idx.data();
  in.num_triangles = idx.size() / 3;
  return in;
}

// Adds an axis-aligned quad (two triangles) as its own mesh and instance.
inline void add_quad(Scene& s, vec3 a, vec3 b, vec3 c, vec3 d, uint32_t material, const mat4& xf = mat4(1.0f)) {
  const float pos[12] = {a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z, d.x, d.y, d.z};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  MeshInput in;
  in.positions = pos;
  in.num_vertices = 4;
  in.indices = idx;
  in.num_triangles = 2;
  s.meshes.push_back(build_mesh(in));
  s.add_instance(uint32_t(s.meshes.size() - 1), xf, {material});
}

// A closed white box [-1,1]^3 with a red left wall, lit by an emissive quad
// under the ceiling, seen from the front through an opening at z = 1.
// Commits the scene unless told not to (to change the camera first: commit()
// moves a scene seen from far away into camera-relative render space).
inline void build_cornell_box(Scene& s, int width = 32, int height = 32, const mat4& xf = mat4(1.0f), float scale = 1.0f,
                              bool commit = true) {
  Material white;
  white.base_color = vec3(0.7f);
  Material red;
  red.base_color = vec3(0.7f, 0.1f, 0.1f);
  Material light;
  light.base_color = vec3(0.0f);
  light.emission_front = light.emission_back = vec3(10.0f);
  s.materials.push_back(white);
  s.materials.push_back(red);
  s.materials.push_back(light);
  const uint32_t W = 1, R = 2, L = 3;
  auto q = [&](vec3 a, vec3 b, vec3 c, vec3 d, uint32_t m) { add_quad(s, a * scale, b * scale, c * scale, d * scale, m, xf); };
  q({-1, -1, -1}, {1, -1, -1}, {1, -1, 1}, {-1, -1, 1}, W);   // floor
  q({-1, 1, -1}, {-1, 1, 1}, {1, 1, 1}, {1, 1, -1}, W);       // ceiling
  q({-1, -1, -1}, {-1, 1, -1}, {1, 1, -1}, {1, -1, -1}, W);   // back
  q({-1, -1, -1}, {-1, -1, 1}, {-1, 1, 1}, {-1, 1, -1}, R);   // left
  q({1, -1, -1}, {1, 1, -1}, {1, 1, 1}, {1, -1, 1}, W);       // right
  q({-0.3f, 0.99f, -0.3f}, {0.3f, 0.99f, -0.3f}, {0.3f, 0.99f, 0.3f}, {-0.3f, 0.99f, 0.3f}, L);
  Camera& c = s.camera;
  c.to_world = xf * mat4(vec4(1, 0, 0, 0), vec4(0, 1, 0, 0), vec4(0, 0, 1, 0), vec4(0, 0, 3.5f * scale, 1));
  c.left = c.bottom = -0.3f;
  c.right = c.top = 0.3f;
  c.clip_start = 0.01f * scale;
  c.clip_end = 100.0f * scale;
  c.width = width;
  c.height = height;
  if (commit) s.commit();
}

// The same box with its emissive quad turned off, lit by a point light
// under the ceiling instead: nothing a ray can hit emits.
inline void build_cornell_box_lit_by_a_point_light(Scene& s, int width, int height) {
  build_cornell_box(s, width, height, mat4(1.0f), 1.0f, /*commit=*/false);
  s.materials[3].emission_front = s.materials[3].emission_back = vec3(0.0f);
  Light point;
  point.type = LightType::Point;
  point.position = vec3(0.0f, 0.8f, 0.0f);
  point.radiance = vec3(5.0f);
  s.lights.push_back(point);
  s.commit();
}

}  // namespace tessera::fixtures
