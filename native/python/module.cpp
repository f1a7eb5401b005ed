// Python bindings of the core: buffers in, pixels out. No rendering logic
// lives here; every function converts arguments and calls into native/core.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <memory>
#include <stdexcept>
#include <thread>

#include "core/integrator.h"
#include "core/render.h"
#include "core/scene.h"

namespace py = pybind11;
using namespace tessera;

namespace {

template <typename T>
using Array = py::array_t<T, py::array::c_style | py::array::forcecast>;

// Checks that a buffer has the given trailing dimension and returns its rows.
template <typename T>
size_t rows_of(const Array<T>& a, py::ssize_t cols, const char* what) {
  if (a.ndim() == 2 && a.shape(1) == cols) return size_t(a.shape(0));
  if (a.ndim() == 1 && a.shape(0) % cols == 0) return size_t(a.shape(0) / cols);
  throw std::invalid_argument(std::string(what) + " must have " + std::to_string(cols) +
                              " values per row; got an array of shape " + py::str(py::tuple(py::cast(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim())))).cast<std::string>());
}

mat4 to_mat4(const Array<float>& m, const char* what) {
  if (m.size() != 16) throw std::invalid_argument(std::string(what) + " must be a 4x4 matrix");
  mat4 out;
  const float* p = m.data();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out[c][r] = p[4 * r + c];  // Blender rows -> GLM columns
  return out;
}

vec3 to_vec3(const std::vector<float>& v, const char* what) {
  if (v.size() < 3) throw std::invalid_argument(std::string(what) + " needs 3 components");
  return vec3(v[0], v[1], v[2]);
}

ClosureKind to_closure_kind(const std::string& kind) {
  if (kind == "PRINCIPLED") return ClosureKind::Principled;
  if (kind == "DIFFUSE") return ClosureKind::Diffuse;
  if (kind == "GLOSSY") return ClosureKind::Glossy;
  if (kind == "GLASS") return ClosureKind::Glass;
  if (kind == "TRANSPARENT") return ClosureKind::Transparent;
  throw std::invalid_argument("unknown closure kind '" + kind +
                              "'; expected PRINCIPLED, DIFFUSE, GLOSSY, GLASS or TRANSPARENT");
}

ShadingModel to_shading_model(const std::string& model) {
  if (model == "CYCLES_3") return ShadingModel::Cycles3;
  if (model == "CYCLES_4") return ShadingModel::Cycles4;
  if (model == "CYCLES_4_3") return ShadingModel::Cycles4_3;
  throw std::invalid_argument("unknown shading model '" + model + "'; expected CYCLES_3, CYCLES_4 or CYCLES_4_3");
}

// A closure from a dict with the keys of add_material's closure-0 arguments
// ("kind", "weight", "base_color", "metallic", "roughness", "specular", "ior",
// "transmission", "model", "multiscatter", "specular_tint", "coat",
// "coat_roughness", "coat_ior", "coat_tint", "diffuse_roughness"); missing
// keys take the Principled defaults.
Closure to_closure(const py::dict& d) {
  Closure c;
  for (auto item : d) {
    const std::string key = py::str(item.first);
    if (key == "kind") c.kind = to_closure_kind(item.second.cast<std::string>());
    else if (key == "model") c.model = to_shading_model(item.second.cast<std::string>());
    else if (key == "multiscatter") c.multiscatter = item.second.cast<bool>();
    else if (key == "specular_tint") c.specular_tint = to_vec3(item.second.cast<std::vector<float>>(), "closure specular_tint");
    else if (key == "coat") c.coat = item.second.cast<float>();
    else if (key == "coat_roughness") c.coat_roughness = item.second.cast<float>();
    else if (key == "coat_ior") c.coat_ior = item.second.cast<float>();
    else if (key == "coat_tint") c.coat_tint = to_vec3(item.second.cast<std::vector<float>>(), "closure coat_tint");
    else if (key == "diffuse_roughness") c.diffuse_roughness = item.second.cast<float>();
    else if (key == "weight") c.weight = item.second.cast<float>();
    else if (key == "base_color") c.color = to_vec3(item.second.cast<std::vector<float>>(), "closure base_color");
    else if (key == "metallic") c.metallic = item.second.cast<float>();
    else if (key == "roughness") c.roughness = item.second.cast<float>();
    else if (key == "specular") c.specular = item.second.cast<float>();
    else if (key == "ior") c.ior = item.second.cast<float>();
    else if (key == "transmission") c.transmission = item.second.cast<float>();
    else throw std::invalid_argument("add_material: unknown closure parameter '" + key + "'");
  }
  return c;
}

// A world-space point in the committed scene's render space (Scene::render_origin).
vec3 to_render_space(const Scene& s, const vec3& p) { return vec3(glm::dvec3(p) - glm::dvec3(s.render_origin)); }
// A world-space transform in render space: what is added or changed after a
// commit() that moved the scene lands where the rest of it is.
mat4 to_render_space(const Scene& s, mat4 m) {
  m[3] = vec4(to_render_space(s, vec3(m[3])), 1.0f);
  return m;
}

class PySession {
 public:
  PySession(std::shared_ptr<Scene> scene, const RenderOptions& options)
      : scene_(std::move(scene)), session_(*scene_, options) {}
  ~PySession() {
    session_.cancel();
    if (thread_.joinable()) thread_.join();
  }
  void start() {
    if (thread_.joinable()) throw std::runtime_error("this render session was already started");
    done_ = false;
    thread_ = std::thread([this] {
      session_.render();
      done_ = true;
    });
  }
  // Waits up to timeout seconds; returns true when the render has finished.
  bool wait(double timeout) {
    py::gil_scoped_release release;
    auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
    while (!done_.load() && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    if (done_.load() && thread_.joinable()) thread_.join();
    return done_.load();
  }
  void render() {
    py::gil_scoped_release release;
    session_.render();
  }
  void cancel() { session_.cancel(); }
  py::array_t<float> pixels() const {
    std::vector<float> p = session_.pixels();
    py::array_t<float> out({session_.height(), session_.width(), 4});
    std::copy(p.begin(), p.end(), out.mutable_data());
    return out;
  }
  // One enabled data pass by its Blender name: (height, width, channels).
  py::array_t<float> pass_pixels(const std::string& name) const {
    for (uint32_t bit = 1; bit & kPassAll; bit <<= 1) {
      if (name != pass_name(bit)) continue;
      std::vector<float> p = session_.pass_pixels(bit);
      if (p.empty())
        throw std::invalid_argument("pass '" + name + "' was not enabled; add it to RenderOptions.passes");
      py::array_t<float> out({session_.height(), session_.width(), pass_channels(bit)});
      std::copy(p.begin(), p.end(), out.mutable_data());
      return out;
    }
    throw std::invalid_argument("unknown pass '" + name + "'; the passes are the keys of PASSES");
  }
  py::dict stats() const {
    RenderStats s = session_.stats();
    py::dict d;
    d["seconds"] = s.seconds;
    d["rays"] = s.rays;
    d["invalid_samples"] = s.invalid_samples;
    d["skipped_rays"] = s.skipped_rays;
    d["samples_done"] = s.samples_done;
    d["pixel_samples"] = s.pixel_samples;
    d["estimated_error"] = s.estimated_error;
    d["active_pixels"] = s.active_pixels;
    d["antialiased_pixels"] = s.antialiased_pixels;
    d["light_paths"] = s.light_paths;
    d["stop_reason"] = std::string(s.stop_reason);
    d["cancelled"] = s.cancelled;
    return d;
  }
  RenderSession& session() { return session_; }

 private:
  std::shared_ptr<Scene> scene_;
  RenderSession session_;
  std::thread thread_;
  std::atomic<bool> done_{false};
};

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "Tessera's native core: scene building, BVH and path tracing";
  {
    py::dict passes;  // Blender pass name -> RenderOptions.passes bit
    for (uint32_t bit = 1; bit & kPassAll; bit <<= 1) passes[pass_name(bit)] = bit;
    m.attr("PASSES") = passes;
  }
  // Ray kinds for the visibility masks (visibility.h).
  m.attr("RAY_CAMERA") = uint32_t(kRayCamera);
  m.attr("RAY_DIFFUSE") = uint32_t(kRayDiffuse);
  m.attr("RAY_GLOSSY") = uint32_t(kRayGlossy);
  m.attr("RAY_TRANSMISSION") = uint32_t(kRayTransmission);
  m.attr("RAY_SHADOW") = uint32_t(kRayShadow);

  py::class_<RenderOptions>(m, "RenderOptions")
      .def(py::init<>())
      .def_readwrite("samples", &RenderOptions::samples)
      .def_readwrite("max_bounces", &RenderOptions::max_bounces)
      .def_readwrite("max_diffuse_bounces", &RenderOptions::max_diffuse_bounces)
      .def_readwrite("max_glossy_bounces", &RenderOptions::max_glossy_bounces)
      .def_readwrite("max_transmission_bounces", &RenderOptions::max_transmission_bounces)
      .def_readwrite("max_transparent_bounces", &RenderOptions::max_transparent_bounces)
      .def_readwrite("rr_depth", &RenderOptions::rr_depth)
      .def_readwrite("clamp_direct", &RenderOptions::clamp_direct)
      .def_readwrite("clamp_indirect", &RenderOptions::clamp_indirect)
      .def_readwrite("light_threshold", &RenderOptions::light_threshold)
      .def_readwrite("caustic_light_paths", &RenderOptions::caustic_light_paths)
      .def_readwrite("adaptive_threshold", &RenderOptions::adaptive_threshold)
      .def_readwrite("adaptive_min_samples", &RenderOptions::adaptive_min_samples)
      .def_readwrite("time_limit", &RenderOptions::time_limit)
      .def_readwrite("error_target", &RenderOptions::error_target)
      .def_readwrite("estimate_error", &RenderOptions::estimate_error)
      .def_readwrite("film_transparent", &RenderOptions::film_transparent)
      .def_readwrite("pass_alpha_threshold", &RenderOptions::pass_alpha_threshold)
      .def_readwrite("seed", &RenderOptions::seed)
      .def_readwrite("threads", &RenderOptions::threads)
      .def_readwrite("tile_size", &RenderOptions::tile_size)
      .def_readwrite("filter_width", &RenderOptions::filter_width)
      .def_readwrite("max_camera_rays", &RenderOptions::max_camera_rays)
      .def_readwrite("specialise", &RenderOptions::specialise,
                     "False: model every scene feature whether the scene has it or not (benchmarks)")
      .def_readwrite("passes", &RenderOptions::passes, "Data passes to write: a sum of PASSES values")
      .def_readwrite("region_x0", &RenderOptions::region_x0)
      .def_readwrite("region_y0", &RenderOptions::region_y0)
      .def_readwrite("region_x1", &RenderOptions::region_x1)
      .def_readwrite("region_y1", &RenderOptions::region_y1);

  m.def(
      "scene_features",
      [](const Scene& s) {
        const SceneFeatures f = scene_features(s);
        py::dict d;
        d["emits"] = f.emits;
        d["hittable_emitters"] = f.hittable_emitters;
        d["transparent"] = f.transparent;
        return d;
      },
      py::arg("scene"), "What the integrator models for a committed scene (SceneFeatures).");

  py::class_<Scene, std::shared_ptr<Scene>>(m, "Scene")
      .def(py::init<>())
      .def(
          "add_mesh",
          [](Scene& s, const Array<float>& positions, const Array<uint32_t>& indices, std::optional<Array<uint32_t>> slots,
             std::optional<Array<float>> normals, std::optional<Array<float>> uvs) {
            MeshInput in;
            in.num_vertices = rows_of(positions, 3, "positions");
            in.positions = positions.data();
            in.num_triangles = rows_of(indices, 3, "indices");
            in.indices = indices.data();
            if (slots) {
              if (size_t(slots->size()) != in.num_triangles)
                throw std::invalid_argument("material_slots must have one entry per triangle");
              in.material_slots = slots->data();
            }
            if (normals) {
              if (rows_of(*normals, 3, "corner_normals") != 3 * in.num_triangles)
                throw std::invalid_argument("corner_normals must have 3 normals per triangle");
              in.corner_normals = normals->data();
            }
            if (uvs) {
              if (rows_of(*uvs, 2, "corner_uvs") != 3 * in.num_triangles)
                throw std::invalid_argument("corner_uvs must have 3 UVs per triangle");
              in.corner_uvs = uvs->data();
            }
            Mesh mesh;
            {
              py::gil_scoped_release release;
              mesh = prepare_mesh(in);  // its BVH: Scene::commit, unless merged
            }
            s.meshes.push_back(std::move(mesh));
            return s.meshes.size() - 1;
          },
          py::arg("positions"), py::arg("indices"), py::arg("material_slots") = py::none(),
          py::arg("corner_normals") = py::none(), py::arg("corner_uvs") = py::none(),
          "Adds a mesh in object space (its BVH is built at commit, unless the mesh is merged into the scene's render-space BVH); returns its index.")
      .def("mesh_skipped_triangles", [](const Scene& s, size_t i) { return s.meshes.at(i).num_skipped_triangles; })
      .def(
          "add_instance",
          [](Scene& s, uint32_t mesh, const Array<float>& matrix, std::vector<uint32_t> slot_materials,
             uint32_t visibility) {
            if (mesh >= s.meshes.size()) throw std::out_of_range("add_instance: no mesh with index " + std::to_string(mesh));
            for (uint32_t mat : slot_materials)
              if (mat >= s.materials.size()) throw std::out_of_range("add_instance: no material with index " + std::to_string(mat));
            return s.add_instance(mesh, to_render_space(s, to_mat4(matrix, "matrix")), slot_materials, uint8_t(visibility & kVisibleToAll));
          },
          py::arg("mesh"), py::arg("matrix"), py::arg("slot_materials"), py::arg("visibility") = uint32_t(kVisibleToAll))
      .def(
          "add_texture",
          [](Scene& s, const Array<float>& pixels, const std::string& interpolation, const std::string& extension,
             const std::string& bytes, float diffuse_blur) {
            if (pixels.ndim() != 3 || pixels.shape(2) != 4)
              throw std::invalid_argument("texture pixels must be an array of shape (height, width, 4)");
            if (bytes != "" && bytes != "sRGB" && bytes != "linear")
              throw std::invalid_argument("add_texture: bytes must be '', 'sRGB' or 'linear', not '" + bytes + "'");
            if (!(diffuse_blur >= 0.0f && diffuse_blur <= 1.0f))
              throw std::invalid_argument("add_texture: diffuse_blur must be in [0, 1] (a fraction of the image's size; "
                                          "0 turns it off), not " + std::to_string(diffuse_blur));
            Texture t;
            const int h = int(pixels.shape(0)), w = int(pixels.shape(1));
            if (bytes.empty()) {
              t.height = h, t.width = w;
              const vec4* p = reinterpret_cast<const vec4*>(pixels.data());
              t.texels.assign(p, p + size_t(w) * h);
            } else {
              py::gil_scoped_release release;
              t.set_bytes(pixels.data(), w, h, bytes == "sRGB");
            }
            t.interpolation = interpolation == "Closest" ? Texture::Interpolation::Closest
                            : interpolation == "Cubic" || interpolation == "Smart" ? Texture::Interpolation::Cubic
                            : Texture::Interpolation::Linear;
            t.extension = extension == "EXTEND" ? Texture::Extension::Extend
                        : extension == "CLIP" ? Texture::Extension::Clip
                        : extension == "MIRROR" ? Texture::Extension::Mirror
                        : Texture::Extension::Repeat;
            {
              py::gil_scoped_release release;
              t.set_diffuse_blur(diffuse_blur);
            }
            s.textures.push_back(std::move(t));
            return s.textures.size() - 1;
          },
          py::arg("pixels"), py::arg("interpolation") = "Linear", py::arg("extension") = "REPEAT",
          py::arg("bytes") = "", py::arg("diffuse_blur") = 0.0f,
          "Adds an image texture (RGBA, rows bottom to top); returns its index. bytes='': linear floats; "
          "'sRGB' or 'linear': an 8-bit image as Blender reads it back (k / 255), stored as bytes and "
          "converted per texel from sRGB or as is. diffuse_blur: what paths see after a diffuse bounce is "
          "the image box-filtered over this fraction of its size (0: the image itself).")
      .def(
          "texture_average",
          [](const Scene& s, size_t i) {
            if (i >= s.textures.size()) throw std::out_of_range("texture_average: no texture " + std::to_string(i));
            const vec4 a = s.textures[i].average();
            return py::make_tuple(a.x, a.y, a.z, a.w);
          },
          py::arg("index"), "Mean linear RGBA of a texture's texels.")
      .def(
          "add_material",
          [](Scene& s, std::vector<float> base_color, float metallic, float roughness, float specular, float ior,
             float transmission, std::vector<float> emission_front, std::vector<float> emission_back,
             py::dict textures, float normal_strength, float emission_strength_front, float emission_strength_back,
             const std::string& kind, float weight, float alpha, std::vector<py::dict> closures,
             const std::string& model, bool multiscatter, std::vector<float> specular_tint, float coat,
             float coat_roughness, float coat_ior, std::vector<float> coat_tint, float diffuse_roughness) {
            Material m;
            m.kind = to_closure_kind(kind);
            m.model = to_shading_model(model);
            m.multiscatter = multiscatter;
            m.specular_tint = to_vec3(specular_tint, "specular_tint");
            m.coat = coat;
            m.coat_roughness = coat_roughness;
            m.coat_ior = coat_ior;
            m.coat_tint = to_vec3(coat_tint, "coat_tint");
            m.diffuse_roughness = diffuse_roughness;
            m.weight = weight;
            m.alpha = alpha;
            if (closures.size() > size_t(kMaxClosures - 1))
              throw std::invalid_argument("add_material: at most " + std::to_string(kMaxClosures) + " closures in all");
            for (const py::dict& d : closures) m.add_closure(to_closure(d));
            m.base_color = to_vec3(base_color, "base_color");
            m.metallic = metallic;
            m.roughness = roughness;
            m.specular = specular;
            m.ior = ior;
            m.transmission = transmission;
            m.emission_front = to_vec3(emission_front, "emission_front");
            m.emission_back = to_vec3(emission_back, "emission_back");
            m.normal_strength = normal_strength;
            m.emission_strength_front = emission_strength_front;
            m.emission_strength_back = emission_strength_back;
            // textures: {"base_color": (texture index, channel), ...}; channel 0 colour, 1 alpha.
            for (auto item : textures) {
              const std::string key = py::str(item.first);
              auto ref = item.second.cast<std::pair<int, int>>();
              if (ref.first < 0 || size_t(ref.first) >= s.textures.size())
                throw std::out_of_range("add_material: no texture with index " + std::to_string(ref.first));
              TextureRef r{ref.first, uint32_t(ref.second)};
              if (key == "base_color") m.base_color_tex = r;
              else if (key == "metallic") m.metallic_tex = r;
              else if (key == "roughness") m.roughness_tex = r;
              else if (key == "emission") m.emission_tex = r;
              else if (key == "normal") m.normal_tex = r;
              else if (key == "alpha") m.alpha_tex = r;
              else throw std::invalid_argument("add_material: unknown textured input '" + key + "'");
            }
            s.materials.push_back(m);
            return s.materials.size() - 1;
          },
          py::arg("base_color"), py::arg("metallic") = 0.0f, py::arg("roughness") = 0.5f, py::arg("specular") = 0.5f,
          py::arg("ior") = 1.45f, py::arg("transmission") = 0.0f,
          py::arg("emission_front") = std::vector<float>{0, 0, 0}, py::arg("emission_back") = std::vector<float>{0, 0, 0},
          py::arg("textures") = py::dict(), py::arg("normal_strength") = 1.0f,
          py::arg("emission_strength_front") = 1.0f, py::arg("emission_strength_back") = 0.0f,
          py::arg("kind") = "PRINCIPLED", py::arg("weight") = 1.0f, py::arg("alpha") = 1.0f,
          py::arg("closures") = std::vector<py::dict>(), py::arg("model") = "CYCLES_3",
          py::arg("multiscatter") = false, py::arg("specular_tint") = std::vector<float>{1, 1, 1},
          py::arg("coat") = 0.0f, py::arg("coat_roughness") = 0.03f, py::arg("coat_ior") = 1.5f,
          py::arg("coat_tint") = std::vector<float>{1, 1, 1}, py::arg("diffuse_roughness") = 0.0f,
          "Adds a material: closure 0 (kind, weight and the Principled-named parameters; base_color is the "
          "node's Color for other kinds; model: whose closures, CYCLES_3 for Blender 3.x, CYCLES_4 for 4.0 "
          "to 4.2, CYCLES_4_3 from 4.3; multiscatter: the Multiscatter GGX distribution; specular_tint, "
          "coat*, diffuse_roughness: Principled v2 inputs), Principled alpha of closure 0, and more closures "
          "as dicts with the same keys; returns its index.")
      .def(
          "add_light",
          [](Scene& s, const std::string& type, std::vector<float> position, std::vector<float> direction,
             std::vector<float> axis_u, std::vector<float> axis_v, float radius, float spot_cos, float spot_smooth,
             bool ellipse, std::vector<float> radiance, bool spot_cosine, bool sphere,
             std::vector<float> spot_to_local, float spread_tan, float spread_norm, uint32_t visibility) {
            Light l;
            l.visibility = uint8_t(visibility & kVisibleToAll);
            if (type == "POINT") l.type = LightType::Point;
            else if (type == "SPOT") l.type = LightType::Spot;
            else if (type == "SUN") l.type = LightType::Sun;
            else if (type == "AREA") l.type = LightType::Area;
            else throw std::invalid_argument("unknown light type '" + type + "'; expected POINT, SPOT, SUN or AREA");
            l.position = to_render_space(s, to_vec3(position, "position"));
            l.direction = glm::normalize(to_vec3(direction, "direction"));
            l.axis_u = to_vec3(axis_u, "axis_u");
            l.axis_v = to_vec3(axis_v, "axis_v");
            l.radius = radius;
            l.spot_cos = spot_cos;
            l.spot_smooth = spot_smooth;
            l.spot_cosine = spot_cosine;
            l.sphere = sphere;
            if (!spot_to_local.empty()) {  // row-major 3x3
              if (spot_to_local.size() != 9) throw std::invalid_argument("spot_to_local must be a 3x3 matrix");
              for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c) l.spot_to_local[c][r] = spot_to_local[3 * r + c];
              l.spot_scaled = true;
            }
            l.ellipse = ellipse;
            l.radiance = to_vec3(radiance, "radiance");
            l.area = 4.0f * glm::length(l.axis_u) * glm::length(l.axis_v) * (ellipse ? kPi / 4.0f : 1.0f);
            if (std::isfinite(spread_tan)) {  // area: Cycles' spread (export/lights.py, area_spread)
              if (!(spread_tan > 0.0f && spread_norm > 0.0f && std::isfinite(spread_norm)))
                throw std::invalid_argument("spread_tan and spread_norm must be positive and finite (or spread_tan inf: no spread)");
              l.spread_tan = spread_tan;
              l.spread_norm = spread_norm;
            }
            s.lights.push_back(l);
          },
          py::arg("type"), py::arg("position"), py::arg("direction") = std::vector<float>{0, 0, -1},
          py::arg("axis_u") = std::vector<float>{1, 0, 0}, py::arg("axis_v") = std::vector<float>{0, 1, 0},
          py::arg("radius") = 0.0f, py::arg("spot_cos") = -1.0f, py::arg("spot_smooth") = 0.0f,
          py::arg("ellipse") = false, py::arg("radiance") = std::vector<float>{1, 1, 1},
          py::arg("spot_cosine") = true, py::arg("sphere") = false, py::arg("spot_to_local") = std::vector<float>{},
          py::arg("spread_tan") = kInf, py::arg("spread_norm") = 0.0f,
          py::arg("visibility") = uint32_t(kLightDefaultVisibility))
      .def("set_world_color", [](Scene& s, std::vector<float> c) { s.background.set_color(to_vec3(c, "color")); })
      .def(
          "set_world_visibility", [](Scene& s, uint32_t visibility) { s.background.set_visibility(uint8_t(visibility)); },
          py::arg("visibility"),
          "World Properties > Ray Visibility: the ray kinds (RAY_CAMERA | RAY_DIFFUSE | ...) that see the world.")
      .def(
          "set_world_image",
          [](Scene& s, const Array<float>& pixels, const Array<float>& rotation, std::vector<float> strength) {
            if (pixels.ndim() != 3 || (pixels.shape(2) != 3 && pixels.shape(2) != 4))
              throw std::invalid_argument("world image must be an array of shape (height, width, 3 or 4)");
            if (rotation.size() != 9) throw std::invalid_argument("world rotation must be a 3x3 matrix");
            const int h = int(pixels.shape(0)), w = int(pixels.shape(1)), c = int(pixels.shape(2));
            std::vector<vec3> px(size_t(w) * h);
            const float* p = pixels.data();
            for (size_t i = 0; i < px.size(); ++i) px[i] = vec3(p[c * i], p[c * i + 1], p[c * i + 2]);
            glm::mat3 r;
            const float* q = rotation.data();
            for (int row = 0; row < 3; ++row)
              for (int col = 0; col < 3; ++col) r[col][row] = q[3 * row + col];
            s.background.set_image(std::move(px), w, h, r, to_vec3(strength, "strength"));
          },
          py::arg("pixels"), py::arg("rotation"), py::arg("strength"))
      .def(
          "set_camera",
          [](Scene& s, const std::string& type, const Array<float>& matrix, float left, float right, float bottom,
             float top, float clip_start, float clip_end, int width, int height, float aperture_radius,
             float focus_distance, int blades, float blades_rotation, float aperture_ratio) {
            if (width <= 0 || height <= 0) throw std::invalid_argument("image size must be positive");
            Camera& c = s.camera;
            c.type = type == "ORTHO" ? Camera::Type::Orthographic : Camera::Type::Perspective;
            c.to_world = to_render_space(s, to_mat4(matrix, "camera matrix"));
            c.left = left, c.right = right, c.bottom = bottom, c.top = top;
            c.clip_start = clip_start, c.clip_end = clip_end;
            c.width = width, c.height = height;
            c.aperture_radius = std::max(aperture_radius, 0.0f);
            c.focus_distance = focus_distance;
            c.blades = blades;
            c.blades_rotation = blades_rotation;
            c.aperture_ratio = aperture_ratio > 0.0f ? aperture_ratio : 1.0f;
          },
          py::arg("type"), py::arg("matrix"), py::arg("left"), py::arg("right"), py::arg("bottom"), py::arg("top"),
          py::arg("clip_start"), py::arg("clip_end"), py::arg("width"), py::arg("height"),
          py::arg("aperture_radius") = 0.0f, py::arg("focus_distance") = 10.0f, py::arg("blades") = 0,
          py::arg("blades_rotation") = 0.0f, py::arg("aperture_ratio") = 1.0f)
      .def("commit",
           [](Scene& s) {
             py::gil_scoped_release release;
             auto t0 = std::chrono::steady_clock::now();
             s.commit();
             s.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
           })
      .def(
          "intersect",
          [](const Scene& s, std::vector<float> o, std::vector<float> d, float tmax) -> py::object {
            // World space in and out; the core works in render space (Scene::render_origin).
            Ray r{to_render_space(s, to_vec3(o, "origin")), glm::normalize(to_vec3(d, "direction")), tmax};
            Hit h;
            if (!s.intersect(r, h)) return py::none();
            SurfaceInteraction si = s.interaction(r, h);
            const glm::dvec3 p = glm::dvec3(si.p) + glm::dvec3(s.render_origin);
            return py::make_tuple(h.t, h.instance, s.meshes[s.instances[h.instance].mesh].prim_ids[h.prim],
                                  std::vector<double>{p.x, p.y, p.z}, std::vector<float>{si.ng.x, si.ng.y, si.ng.z},
                                  si.back_face);
          },
          py::arg("origin"), py::arg("direction"), py::arg("tmax") = kInf,
          "Closest hit after commit(): (t, instance, Blender triangle index, point, normal, back_face) or None.")
      .def(
          "occluded",
          [](const Scene& s, std::vector<float> o, std::vector<float> d, float tmax) {
            return s.occluded(to_render_space(s, to_vec3(o, "origin")), glm::normalize(to_vec3(d, "direction")), tmax);
          },
          py::arg("origin"), py::arg("direction"), py::arg("tmax") = kInf)
      .def_property_readonly("num_triangles", &Scene::num_triangles)
      .def_property_readonly("num_instanced_triangles", &Scene::num_instanced_triangles)
      .def_property_readonly("num_instances", [](const Scene& s) { return s.instances.size(); })
      .def_property_readonly("num_meshes", [](const Scene& s) { return s.meshes.size(); })
      .def_property_readonly("num_lights", [](const Scene& s) { return s.light_sampler().lights().size(); })
      // Emissive triangles as light sampling has them: a rectangle counts its two.
      .def_property_readonly("num_emissive_triangles",
                             [](const Scene& s) {
                               size_t n = 0;
                               for (const EmissiveTriangle& t : s.light_sampler().triangles()) n += t.rectangle() ? 2 : 1;
                               return n;
                             })
      .def_property_readonly("memory_bytes", &Scene::memory_bytes)
      .def_property_readonly("tlas_build_seconds", [](const Scene& s) { return s.build_seconds; });

  py::class_<PySession>(m, "Session")
      .def(py::init<std::shared_ptr<Scene>, const RenderOptions&>(), py::arg("scene"), py::arg("options"))
      .def("start", &PySession::start, "Starts rendering on a background thread.")
      .def("wait", &PySession::wait, py::arg("timeout"), "Waits up to timeout seconds; True when finished.")
      .def("render", &PySession::render, "Renders to completion on the calling thread (GIL released).")
      .def("cancel", &PySession::cancel)
      .def("pixels", &PySession::pixels, "RGBA float32 array (height, width, 4), rows bottom to top.")
      .def("pass_pixels", &PySession::pass_pixels, py::arg("name"),
           "An enabled data pass by its Blender name: float32 (height, width, channels), rows bottom to top.")
      .def("stats", &PySession::stats)
      .def_property_readonly("samples_done", [](PySession& p) { return p.session().samples_done(); })
      .def_property_readonly("samples_total", [](PySession& p) { return p.session().samples_total(); })
      .def_property_readonly("elapsed_seconds", [](PySession& p) { return p.session().elapsed_seconds(); })
      .def_property_readonly("update_seconds", [](PySession& p) { return p.session().update_seconds(); })
      .def_property_readonly("remaining_seconds", [](PySession& p) { return p.session().remaining_seconds(); })
      .def_property_readonly("progress", [](PySession& p) { return p.session().progress(); })
      .def_property_readonly("estimated_error", [](PySession& p) { return p.session().estimated_error(); })
      .def_property_readonly("pixel_samples", [](PySession& p) { return p.session().pixel_samples(); })
      .def_property_readonly("rays", [](PySession& p) { return p.session().rays(); });
}
