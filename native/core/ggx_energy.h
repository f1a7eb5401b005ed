// Albedo tables of the GGX microfacet BSDF, for the energy compensation of
// Cycles 4.x's "Multiscatter GGX" (Kulla and Conty 2017, "Revisiting
// Physically Based Shading at Imageworks": the single-scattering lobe is
// scaled by 1 / E(mu), and coloured Fresnel darkens it by
// (1 + Fms (1 - E) / E) E, Fms = Fss E_avg / (1 - Fss (1 - E_avg))).
//
// The tables have Cycles' axes and sizes (intern/cycles/app/
// cycles_precompute.cpp) and are read with its linear interpolation
// (kernel/util/lookup_table.h), so that a lookup between grid points returns
// what Cycles' returns:
//   x  roughness r = sqrt(alpha), grid points clamp(i / (n - 1), 1e-4, 1)
//   y  mu = cos(view, N), grid points clamp(j / (n - 1), 1e-4, 1)
//   z  z = sqrt(|(ior - 1) / (ior + 1)|), grid points clamp(k / (n - 1), 1e-4, 0.99),
//      i.e. F0 = z^4: most of the table covers the usual IORs 1 to 2
// They are computed here, once, on first use, by integrating over visible
// normals (Heitz 2018) with stratified samples instead of Cycles' Sobol
// points: each entry is within ~1e-3 of Cycles' table.
#pragma once
#include <functional>
#include <vector>

namespace tessera::ggx_energy {

// Directional albedo E(r, mu) of the GGX reflection lobe with Fresnel 1
// (height-correlated Smith masking-shadowing, the Cycles 4.x lobe); 32 x 32.
float E(float roughness, float mu);
// Its cosine-weighted average over view directions, 2 int_0^1 E(r, mu) mu dmu; 32.
float E_avg(float roughness);

// Directional albedo of the GGX glass lobe (reflection F + refraction 1 - F,
// real dielectric Fresnel at the microfacet) for relative IOR eta (eta < 1:
// leaving the medium, Cycles' "inv" tables); 16 x 16 x 16.
float glass_E(float roughness, float mu, float eta);
float glass_E_avg(float roughness, float eta);  // 16 x 16

// Mean interpolation factor s between F0 and F90 of the "real Fresnel
// remapped to F0..F90" generalised Schlick Fresnel (Principled specular) over
// visible normals: the lobe's albedo is then mix(F0, F90, s) (Cycles'
// ggx_gen_schlick_ior_s, used by bsdf_microfacet_estimate_albedo); 16^3.
float gen_schlick_ior_s(float roughness, float mu, float eta);
// The same for Schlick's (1 - cos)^5, read as Cycles reads its
// ggx_gen_schlick_s table for the metallic F82-tint Fresnel (at z = 0.5,
// halfway between its slices of exponents 40/7 and 35/8); 16 x 16.
float schlick_s(float roughness, float mu);

// entry(0) .. entry(n - 1), computed in parallel; safe inside the
// initialiser of a function-local static reached from TBB tasks.
std::vector<float> tabulate(int n, const std::function<float(int)>& entry);

// Cycles' F0 <-> IOR conversions (bsdf_util.h).
float F0_from_ior(float ior);
float ior_from_F0(float f0);

}  // namespace tessera::ggx_energy
