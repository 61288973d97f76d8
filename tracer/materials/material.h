// The one tagged material struct every backend evaluates with a switch (no virtual calls in
// device code). Host code fills it from scene files; the BSDF routines live in bsdf.h.
#pragma once

#include "core/hd.h"

namespace tracer {

enum class MaterialType : uint32_t {
  kDiffuse = 0,     // Lambertian, reflectance `albedo`
  kMirror = 1,      // perfect specular reflection tinted by `albedo`
  kDielectric = 2,  // smooth glass: Fresnel-weighted reflection and refraction, `ior`, Beer-Lambert
};
constexpr int kMaterialTypeCount = 3;

enum MaterialFlags : uint32_t {
  kMaterialSchlickFresnel = 1u << 0,    // Schlick's approximation instead of the exact equations
  kMaterialTwoSidedEmission = 1u << 1,  // emit from both faces, not only the front face
};

struct alignas(16) Material {
  vec3 albedo = vec3(0.8f);
  MaterialType type = MaterialType::kDiffuse;
  vec3 emission = vec3(0.0f);  // emitted radiance (colour x strength already multiplied)
  float ior = 1.5f;
  vec3 absorption = vec3(0.0f);  // Beer-Lambert coefficient per unit length inside a dielectric
  uint32_t flags = 0;

  TRACER_HD bool is_emissive() const {
    return emission.x > 0.0f || emission.y > 0.0f || emission.z > 0.0f;
  }
  TRACER_HD bool is_specular() const { return type != MaterialType::kDiffuse; }
};
static_assert(sizeof(Material) == 48, "Material is uploaded as plain bytes");

inline const char* material_type_name(MaterialType t) {
  switch (t) {
    case MaterialType::kDiffuse: return "diffuse";
    case MaterialType::kMirror: return "mirror";
    case MaterialType::kDielectric: return "dielectric";
  }
  return "unknown";
}

}  // namespace tracer
