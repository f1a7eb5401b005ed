// The BSDF at a hit: the material's closures (material.h) expanded into a
// fixed-size list of lobes, each with its weight, as Cycles' closure list.
// Each closure follows the Cycles of its ShadingModel. Cycles 3.x:
//   Principled (principled v1), with its Cycles weights:
//     diffuse   (1 - metallic)(1 - transmission) base  Burley diffuse with retro-reflection
//     specular  1 - (1 - metallic) transmission         GGX, Fresnel interpolated from cspec0
//     glass     (1 - metallic) transmission             GGX reflection F(wo) + refraction base (1 - F(wo))
//   Diffuse      Lambert, or Oren-Nayar (Cycles' bsdf_oren_nayar) when rough
//   Glossy       GGX reflection with Fresnel 1, tinted by the colour
//   Glass        GGX reflection F(wo) + refraction (1 - F(wo)), both tinted
//   Transparent  the ray goes on unchanged (a delta lobe), tinted
// Cycles 4.x (svm_node_closure_bsdf, bsdf_microfacet.h): GGX lobes with
// height-correlated masking and the Fresnel factor at the microfacet;
// Multiscatter GGX scales them by 1 / E(mu) (ggx_energy.h):
//   Principled (principled v2), layer by layer from the top, each layer's
//     albedo estimate taken off the weight of those below (closure_layering_weight):
//     coat      GGX, dielectric Fresnel of the coat IOR, always energy-compensated; coat tint
//     metal     metallic x: GGX, F82-tint Fresnel (F0 base colour, tint the specular tint)
//     glass     (1 - metallic) transmission: GGX glass, reflection F, refraction (1 - F) sqrt(base)
//     specular  GGX, real Fresnel remapped to F0 = F0(IOR) x 2 level x specular tint
//     diffuse   the rest x base colour: Lambert, or Oren-Nayar with Diffuse Roughness
//   Diffuse      Lambert, or Oren-Nayar (4.3 on: with its multiple-scattering term)
//   Glossy       GGX reflection, Fresnel 1, tinted by the colour
//   Glass        GGX glass: reflection F(wo.wm) + refraction 1 - F(wo.wm), both tinted
// every closure scaled by its Mix/Add Shader weight. f and pdf are sums over
// the lobes; one lobe is sampled per bounce, chosen by its weight times an
// albedo estimate, so the lobes are combined by one-sample MIS (pbrt-v4, 9.x;
// Cycles' shader_bsdf_sample_closure and _shader_bsdf_multi_eval). Local
// directions are in the shading frame, whose z points to wo's side.
#pragma once
#include "material.h"
#include "microfacet.h"
#include "sampling.h"
#include "visibility.h"

namespace tessera {

struct BSDFSample {
  vec3 wi;     // world space
  vec3 f;      // BSDF value (for a delta lobe: its weight / |cos wi|)
  float pdf;   // solid-angle density (for a delta lobe: the lobe's probability)
  bool delta;  // specular: no MIS with light sampling
  // Of the sampled lobe (bounce limits). A transparent sample continues the
  // path straight on: not a bounce (Cycles' separate transparent limit).
  enum Kind : uint8_t { kDiffuse, kGlossy, kTransmission, kTransparent } kind = kDiffuse;
};

class BSDF {
 public:
  // At most: two Principled closures (4 lobes each) or eight simple ones,
  // plus the transparent lobe of a textured alpha.
  static constexpr int kMaxLobes = 4 * kMaxClosures + 1;

  // ns, ng: shading and geometric normals, both on wo's side; back_face: wo
  // is on the back of the surface (glass is then left, not entered).
  BSDF(const vec3& ns, const vec3& ng, const Material& m, bool back_face, const vec3& wo_world);

  // The BSDF value for wi and, in *pdf, the solid-angle density with which
  // sample_f draws wi (next-event estimation needs both: one pass over the
  // lobes, one half vector per lobe). f and pdf alone are the same pass.
  vec3 eval(const vec3& wi_world, float* pdf) const;
  // eval() for light sampling of a light that rays of the kinds in
  // `excluded` (visibility.h, not 0) do not see: those kinds' lobes add neither f
  // nor pdf (Cycles' _surface_shader_exclude). Diffuse lobes are of the
  // diffuse kind, glossy reflection of the glossy kind, refraction of the
  // transmission kind, and a glass lobe (Cycles 4.x) of both of the last two:
  // it is left out only when both are.
  vec3 eval(const vec3& wi_world, float* pdf, uint8_t excluded) const;
  vec3 f(const vec3& wi_world) const {
    float p;
    return eval(wi_world, &p);
  }
  float pdf(const vec3& wi_world) const {
    float p;
    eval(wi_world, &p);
    return p;
  }
  bool sample_f(float u_lobe, vec2 u, BSDFSample& s) const;
  // |cos theta| of w against the normal the lobes are evaluated and sampled
  // about: the shading normal, bent where Cycles bends it
  // (ensure_valid_reflection). The scattering integral's cosine must be this
  // one: f and pdf come from the same frame, so f |cos| / pdf stays the
  // lobe's weight. With the unbent normal instead, a direction almost in the
  // bent frame's plane (glass refracting near its critical angle on a smooth
  // mesh) had f |cos| / pdf in the hundreds: the glass bunny's fireflies.
  float abs_cos(const vec3& w_world) const { return std::abs(glm::dot(w_world, frame_.n)); }
  // False when every lobe is a delta: light sampling cannot contribute.
  bool has_smooth_lobes() const { return has_smooth_; }
  // The geometric normal when eval() is 0 for every direction behind it (no
  // smooth lobe transmits: the geometric side decides, eval_lobes), else
  // null.
  const vec3* reflects_only_above() const { return has_smooth_transmission_ ? nullptr : &ng_; }
  int num_lobes() const { return num_lobes_; }

 private:
  struct Lobe {
    enum Type : uint8_t {
      kBurley,      // Principled diffuse: tint = weight, a = roughness
      kOrenNayar,   // Diffuse BSDF: tint x (a + b t) (Lambert: a = 1/pi, b = 0)
      kSpecular,    // Principled specular: k x interpolated Fresnel(cspec0, spec_ior)
      kReflection,  // GGX reflection: tint x k (a constant Fresnel is folded into k)
      kRefraction,  // GGX refraction with relative IOR eta: tint x k
      kTransparent, // straight on: tint x k
      kMicrofacet,  // Cycles 4.x GGX reflection: tint x F(wo.wm) x energy_scale
      kGlass,       // Cycles 4.x GGX glass: tint x (F tint_r | (1 - F) tint_t) x energy_scale
    } type;
    // The Fresnel factor of kMicrofacet and kGlass (Cycles 4.x microfacet_fresnel).
    enum Fresnel : uint8_t {
      kFresnelOne,      // 1 (Glossy)
      kDielectric,      // real dielectric Fresnel of fresnel_ior (coat)
      kRealRemapped,    // the real Fresnel of fresnel_ior remapped from F0(ior)..1 to f0..1 (generalised Schlick)
      kF82Tint,         // Schlick from f0 less b cos (1 - cos)^6 (Kutz et al., "Novel aspects of the Adobe
                        // Standard Material")
    } fresnel;
    // No default initialisers: the lobe array is left uninitialised and
    // whoever adds a lobe sets the fields its type reads (no cost per hit
    // for the rest): kBurley tint, a; kOrenNayar tint, a, b; kSpecular k,
    // ggx, cspec0, spec_ior; kReflection k, tint, ggx; kRefraction k, tint,
    // ggx, eta; kTransparent k, tint; kOrenNayar also ms; kMicrofacet tint,
    // ggx, fresnel, f0, f82_b, fresnel_ior, energy_scale; kGlass tint, ggx,
    // fresnel (kRealRemapped), f0, fresnel_ior, tint_r, tint_t, eta, energy_scale.
    float prob;
    float k;
    vec3 tint;
    GGX ggx;
    float a, b;
    vec3 cspec0;
    float spec_ior;
    float spec_f0;        // kSpecular: fresnel_dielectric(1, spec_ior), 0.08 specular
    float eta;
    vec3 ms;              // Oren-Nayar's multiple scattering, Ems (1 - E(wo)) (Cycles 4.3 on; else 0)
    vec3 f0, f82_b;       // Fresnel at normal incidence; F82-tint's b
    vec3 tint_r, tint_t;  // glass: reflection and transmission tints
    float fresnel_ior;    // the IOR of kDielectric and kRealRemapped (relative: inverted on back faces for glass)
    float energy_scale;   // Multiscatter GGX: 1 / E(mu) (else 1)
    float lambda_o;       // smooth GGX lobes: Smith's Lambda(wo), shared by every eval
    bool is_delta, is_reflect, is_transmit;  // cached by the constructor for eval()
    uint8_t kinds;  // the ray kinds it scatters into (visibility.h), cached with them
    bool delta() const {
      return type == kTransparent || (type != kBurley && type != kOrenNayar && ggx.alpha <= kSmoothAlpha);
    }
    bool reflects() const { return type != kRefraction && type != kTransparent; }
    bool transmits() const { return type == kRefraction || type == kTransparent || type == kGlass; }
  };

  Lobe& add_lobe(Lobe::Type type, float sample_weight);
  void finish_lobe(Lobe& l, float prob);
  void add_principled(const Closure& c, bool back_face);
  void add_principled_v2(const Closure& c, bool back_face);
  void add_closure(const Closure& c, bool back_face);
  void add_closure_v4(const Closure& c, bool back_face);
  // Cycles 4.x lobes (their weights, energy compensation and albedo estimates).
  Lobe& add_microfacet(Lobe::Fresnel fresnel, const vec3& weight, float alpha, float fresnel_ior, const vec3& f0);
  Lobe& add_glass(const vec3& weight, float alpha, float eta, const vec3& f0, const vec3& tint_r, const vec3& tint_t);
  void preserve_energy(Lobe& l, const vec3& Fss);
  void set_oren_nayar(Lobe& l, float sigma, const vec3& color, bool multiple_scattering) const;
  vec3 fresnel(const Lobe& l, float cos_i) const;
  void glass_fresnel(const Lobe& l, float cos_i, vec3& R, vec3& T) const;
  vec3 albedo_estimate(const Lobe& l) const;
  vec3 eval_lobe(const Lobe& l, const vec3& wi, float* pdf) const;
  template <bool kExcluding>
  vec3 eval_lobes(const vec3& wi_world, float* pdf, uint8_t excluded) const;
  bool same_side(const vec3& wi_world) const { return glm::dot(wi_world, ng_) > 0.0f; }

  Frame frame_;
  vec3 ng_;
  vec3 wo_;             // local
  vec3 wo_world_;
  int num_lobes_ = 0;
  Lobe lobes_[kMaxLobes];
  float sample_weight_[kMaxLobes];
  bool has_smooth_ = false, has_smooth_transmission_ = false;
};

}  // namespace tessera
