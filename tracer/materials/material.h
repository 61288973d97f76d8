// The one tagged material struct every backend evaluates with a switch (no virtual calls in
// device code). Host code fills it from scene files; the BSDF routines live in bsdf.h.
#pragma once

#include "core/hd.h"

namespace tracer {

enum class MaterialType : uint32_t {
  kDiffuse = 0,     // Lambertian, reflectance `albedo`
  kMirror = 1,      // perfect specular reflection tinted by `albedo`
  kDielectric = 2,  // glass: Fresnel reflection and refraction, `ior`, Beer-Lambert `absorption`;
                    // smooth when `roughness` is 0, GGX microfacets otherwise
  kConductor = 3,   // metal, GGX `roughness` (u) and `roughness_v` (0: smooth); Fresnel: Schlick
                    // with F0 = `albedo`, or with kMaterialConductorIor the exact equations of the
                    // complex index `eta` + i `k`, tinted by `albedo`
  kSubsurface = 4,  // smooth dielectric boundary (`ior`) around a homogeneous medium that
                    // scatters (`scattering`) and absorbs (`absorption`) per unit length, with
                    // Henyey-Greenstein anisotropy `g`; light random-walks inside
  kCoatedDiffuse = 5,  // "plastic": a dielectric coat (`ior`, GGX `roughness`, `absorption` per
                       // unit length x `thickness`) over a Lambertian base of reflectance `albedo`
  kDiffuseTransmission = 6,  // thin sheet: Lambertian reflection `albedo` on the side of the
                             // viewer, Lambertian transmission `transmittance` to the other side
};
constexpr int kMaterialTypeCount = 7;

enum MaterialFlags : uint32_t {
  kMaterialSchlickFresnel = 1u << 0,    // Schlick's approximation instead of the exact equations
  kMaterialTwoSidedEmission = 1u << 1,  // emit from both faces, not only the front face
  kMaterialConductorIor = 1u << 2,      // conductor: exact Fresnel of eta + i k, not Schlick's F0
  // Subsurface: a random walk leaves through the smooth dielectric boundary (refraction; no light
  // sampling at the exit) instead of the default diffuse exit (integrator/path.h,
  // subsurface_exit_material).
  kMaterialSmoothExit = 1u << 3,
};

struct alignas(16) Material {
  vec3 albedo = vec3(0.8f);
  MaterialType type = MaterialType::kDiffuse;
  vec3 emission = vec3(0.0f);  // emitted radiance (colour x strength already multiplied)
  float ior = 1.5f;
  vec3 absorption = vec3(0.0f);  // Beer-Lambert coefficient per unit length inside a dielectric
                                 // (and in a coated diffuse's coat)
  uint32_t flags = 0;
  vec3 scattering = vec3(0.0f);  // subsurface: scattering coefficient per unit length
  float roughness = 0.0f;        // perceptual roughness; the GGX alpha is roughness^2
  vec3 eta = vec3(1.0f);         // conductor with kMaterialConductorIor: complex index eta + i k
  float roughness_v = -1.0f;     // conductor: roughness along the bitangent; < 0: = roughness
  vec3 k = vec3(0.0f);
  float thickness = 1.0f;           // coated diffuse: the coat's thickness (x absorption)
  vec3 transmittance = vec3(0.0f);  // diffuse transmission: Lambertian transmittance
  float g = 0.0f;                   // subsurface: Henyey-Greenstein mean cosine, (-1, 1)
  // Texture indices into the scene's texture list (kInvalid: none), glTF semantics: the base
  // colour texel multiplies `albedo`, the emissive one `emission`; metallic-roughness reads
  // roughness from G and metallic from B, scaled by `roughness` and `metallic`.
  uint32_t base_color_tex = kInvalid;
  uint32_t metal_rough_tex = kInvalid;
  uint32_t emissive_tex = kInvalid;
  uint32_t normal_tex = kInvalid;
  float metallic = 0.0f;      // glTF metallicFactor; used only with metal_rough_tex
  float normal_scale = 1.0f;  // glTF normalTexture.scale
  uint32_t pad[2] = {0, 0};

  TRACER_HD bool has_textures() const {
    return (base_color_tex & metal_rough_tex & emissive_tex & normal_tex) != kInvalid;
  }

  TRACER_HD bool is_emissive() const {
    return emission.x > 0.0f || emission.y > 0.0f || emission.z > 0.0f;
  }
  TRACER_HD bool is_specular() const { return type != MaterialType::kDiffuse; }
  // Anisotropic roughness: the lobe depends on the azimuth, so the shading frame's tangent
  // matters (bsdf_frame in bsdf.h). Only conductors read roughness_v.
  // A conductor's roughness along the bitangent (roughness_v, or roughness where it is < 0).
  TRACER_HD float roughness_bitangent() const {
    return roughness_v >= 0.0f ? roughness_v : roughness;
  }
  TRACER_HD bool is_anisotropic() const {
    return type == MaterialType::kConductor && roughness_v >= 0.0f && roughness_v != roughness;
  }
};
// 144 bytes since the complex-IOR conductor, the anisotropic roughness, the coat's thickness and
// the diffuse transmittance (96 before): uploaded once per scene; a shader loads only the fields
// its material type reads.
static_assert(sizeof(Material) == 144, "Material is uploaded as plain bytes");

inline const char* material_type_name(MaterialType t) {
  switch (t) {
    case MaterialType::kDiffuse: return "diffuse";
    case MaterialType::kMirror: return "mirror";
    case MaterialType::kDielectric: return "dielectric";
    case MaterialType::kConductor: return "conductor";
    case MaterialType::kSubsurface: return "subsurface";
    case MaterialType::kCoatedDiffuse: return "coated_diffuse";
    case MaterialType::kDiffuseTransmission: return "diffuse_transmission";
  }
  return "unknown";
}

}  // namespace tracer
