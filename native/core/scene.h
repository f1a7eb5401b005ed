// The scene the core renders: unique meshes (each with its BLAS), instances
// that place them (the TLAS is built over their world bounds), materials,
// lights, world and camera. Built once per render from the add-on's arrays.
#pragma once
#include <new>
#include <string>
#include <type_traits>
#include <vector>
#include "background.h"
#include "camera.h"
#include "lights.h"
#include "material.h"
#include "mesh.h"
#include "texture.h"

namespace tessera {

struct Instance {
  mat4 to_world{1.0f};
  mat4 to_local{1.0f};
  glm::mat3 normal_to_world{1.0f};
  uint32_t mesh = 0;
  uint32_t material_offset = 0;  // into Scene::instance_materials
  uint32_t num_slots = 0;
  bool identity = true;
  // The linear part's determinant is negative: the cross product of placed
  // edges points against the normal transform of the object-space normal.
  bool mirrored = false;
  // Object Properties > Visibility > Ray Visibility (visibility.h): the ray
  // kinds that see the instance; the others pass it. An instance hidden
  // from any kind keeps its own BLAS (Scene::commit); hidden from every
  // scattered kind, its emission lights nothing (Cycles'
  // object_usable_as_light).
  uint8_t visibility = kVisibleToAll;
};

struct Hit {
  float t = kInf;
  float u = 0.0f, v = 0.0f;
  uint32_t instance = ~0u;
  uint32_t prim = ~0u;  // leaf order within the instance's mesh
  // The triangle's vertices: lane `lane` of the Tri4 leaf block `tri`, in
  // render space if the hit came from the merged BLAS (render_space), else
  // in the instance's object space.
  const Tri4* tri = nullptr;
  uint32_t lane = 0;
  bool render_space = false;
};

// What shading needs to know about a hit, in world space.
struct SurfaceInteraction {
  vec3 p;
  vec3 p_error;   // absolute error bound of p, for robust ray origins
  vec3 ng;        // unit geometric normal, front side
  vec3 ns;        // unit shading normal, front side
  bool back_face; // the ray arrived at the back of the triangle
  uint32_t material;
  vec2 uv{0.0f};  // the mesh's UV map, where a material needs it
};

// Uninitialised room for a hit's textured copy of its material, filled only
// when the material has textures (Material is trivially destructible). A
// std::optional<Material> in its place was zero-filled, 764 bytes, on every
// hit: 8% of the integrator's own time on the Cornell box.
struct MaterialScratch {
  alignas(Material) unsigned char bytes[sizeof(Material)];
};
static_assert(std::is_trivially_destructible_v<Material>);

class Scene {
  // Declared first, so destroyed last: once the meshes' trees have gone back
  // to the build allocator's retained memory (bvh_memory.cpp), it is
  // returned to the kernel, and a freed scene leaves nothing mapped.
  struct ReleaseRetainedBuildMemory {
    ReleaseRetainedBuildMemory() = default;
    ReleaseRetainedBuildMemory(const ReleaseRetainedBuildMemory&) = default;
    ReleaseRetainedBuildMemory& operator=(const ReleaseRetainedBuildMemory&) = default;
    ~ReleaseRetainedBuildMemory() { bvh_release_retained(); }
  } release_retained_on_destruction_;

 public:
  std::vector<Mesh> meshes;
  std::vector<Instance> instances;
  std::vector<uint32_t> instance_materials;  // per instance: material index per slot
  std::vector<Material> materials;           // materials[0] is the default material
  std::vector<Texture> textures;
  std::vector<Light> lights;
  Background background;
  Camera camera;
  std::vector<std::string> warnings;

  Scene() { materials.push_back(Material{}); }

  uint32_t add_instance(uint32_t mesh, const mat4& to_world, const std::vector<uint32_t>& slot_materials,
                        uint8_t visibility = kVisibleToAll);
  // Builds the TLAS and the light sampler; call once after adding everything
  // (camera included: see render_origin).
  void commit();

  // Camera-relative render space. Floats far from the origin are coarse (1/128
  // apart at 1e5), so a scene viewed from there loses every detail under that
  // size. When the camera is at least kRebaseDistance from the world origin,
  // commit() moves the scene (instance transforms, lights, camera; each new
  // translation rounded once from exact double differences) so that the camera
  // sits at the origin, and records the world position of the new origin
  // here. After commit() the core works in render space: world = render +
  // render_origin. Nearer cameras keep world space as it is.
  static constexpr float kRebaseDistance = 1024.0f;
  vec3 render_origin{0.0f};

  // Every instance, whatever its visibility (tests, tools).
  bool intersect(const Ray& ray, Hit& hit) const;
  // A ray of one kind (visibility.h): instances hidden from it are passed.
  bool intersect(const Ray& ray, Hit& hit, RayKind kind) const {
    return hidden_from_ & kind ? intersect_visible(ray, hit, kind) : intersect(ray, hit);
  }
  // Shadow rays: instances with Shadow visibility off are passed.
  bool occluded(const vec3& o, const vec3& d, float tmax) const;
  SurfaceInteraction interaction(const Ray& ray, const Hit& hit) const;
  // The material of the hit triangle, without the rest of the interaction.
  uint32_t material_index(const Hit& hit) const {
    const Instance& inst = instances[hit.instance];
    const Mesh& mesh = meshes[inst.mesh];
    return material_of(inst, mesh.slot(mesh.prim_ids[hit.prim]));
  }
  // The material parameters at a hit, textures applied.
  Material material_at(const SurfaceInteraction& si) const {
    const Material& m = materials[si.material];
    return m.has_textures() ? textured_material(m, si.uv) : m;
  }
  // The same without copying (a Material with its closure list is ~760
  // bytes): the stored material, or the textured copy made in `scratch`.
  // after_diffuse: the path has scattered diffusely, so the BSDF's textured
  // inputs come from the textures' blurred levels (Texture::coarse).
  const Material& material_at(const SurfaceInteraction& si, MaterialScratch& scratch, bool after_diffuse = false) const {
    const Material& m = materials[si.material];
    if (!m.has_textures()) return m;
    return *new (scratch.bytes) Material(textured_material(m, si.uv, after_diffuse));
  }

  const LightSampler& light_sampler() const { return light_sampler_; }
  AABB bounds() const { return tlas_.bounds(); }
  size_t num_triangles() const;           // unique (stored) triangles
  size_t num_instanced_triangles() const; // as rendered
  size_t memory_bytes() const;            // triangles, attributes and BVHs
  // Instances whose triangles commit() moved into the merged BLAS (below).
  size_t num_merged_instances() const { return merged_instances_.size(); }
  double build_seconds = 0.0;

 private:
  uint32_t material_of(const Instance& inst, uint32_t slot) const {
    return slot < inst.num_slots ? instance_materials[inst.material_offset + slot] : 0;
  }
  void rebase_on_camera();
  std::vector<EmissiveTriangle> collect_emissive_triangles() const;
  Material textured_material(const Material& m, vec2 uv, bool after_diffuse = false) const;
  void apply_normal_map(SurfaceInteraction& si, const Material& m, const vec3* v, bool render_space, const vec2* uv,
                        const Instance& inst) const;
  float texture_value(const TextureRef& ref, vec2 uv, bool after_diffuse = false) const;
  void merge_single_use_instances(std::vector<uint32_t>& tlas_items);
  bool intersect_visible(const Ray& ray, Hit& hit, RayKind kind) const;
  // kMasked: skips the instances hidden from rays of kind `kind`.
  template <bool kAnyHit, bool kMasked = false>
  bool trace(const vec3& o, const vec3& d, float tmax, Hit* hit, uint8_t kind = 0) const;
  template <bool kAnyHit>
  bool trace_item(uint32_t id, const vec3& o, const vec3& d, float& tmax, Hit* hit) const;
  // The TLAS's primitives: an instance index, or kMergedItem for merged_.
  static constexpr uint32_t kMergedItem = ~0u;
  BVH tlas_;
  std::vector<uint32_t> tlas_items_;
  // Meshes placed by exactly one instance gain nothing from a BLAS of their
  // own: their triangles, in render space, share one BLAS (as Cycles puts
  // every object that is not instanced into its top-level BVH), so a ray
  // walks one tree instead of overlapping instance boxes, each with its own
  // ray transform and tree. merged_owner_ maps a merged leaf-order triangle
  // back to its instance and that mesh's leaf-order index, so hits (and all
  // shading) are as if the instance had been hit.
  struct MergedOwner {
    uint32_t instance, prim;
  };
  Mesh merged_;
  std::vector<MergedOwner> merged_owner_;
  std::vector<uint32_t> merged_instances_;  // their meshes' vertices are merged_'s (restore_merged_vertices)
  void restore_merged_vertices();
  void release_merged_meshes();
  uint8_t hidden_from_ = 0;  // the ray kinds some TLAS item is hidden from
  LightSampler light_sampler_;
};

}  // namespace tessera
