// Scene feature flags. A scene records which it needs; shared code takes a compile-time mask F of
// the features it must support, so the CUDA backend can instantiate kernels that leave out lens
// sampling, refraction or sphere tests for scenes that have none. kAllFeatures is the general case.
#pragma once

#include "core/hd.h"

namespace tracer {

enum SceneFeature : uint32_t {
  kFeatureDepthOfField = 1u << 0,
  kFeatureDielectric = 1u << 1,
  kFeatureSubsurface = 1u << 2,
  kFeatureTextures = 1u << 3,
  kFeatureEmissiveMeshes = 1u << 4,
  kFeatureSpheres = 1u << 5,
  kFeatureMirror = 1u << 6,  // also coated diffuse and diffuse transmission (specular code)
  kFeatureAbsorption = 1u << 7,
  kFeatureShadingNormals = 1u << 8,
  // Not a scene feature: code compiled with it honours SceneView::use_flat (the flat primitive
  // list of small scenes, bvh/flat_list.h); without it, queries always walk the BVH.
  kFeatureFlatList = 1u << 9,
  // Lights at infinity: an environment (map or constant colour) or distant lights (suns), or a
  // background colour that replaces the environment for camera rays.
  kFeatureInfiniteLights = 1u << 10,
  // Point and spot lights (delta lights at a position, SceneView::point_lights).
  kFeaturePointLights = 1u << 11,
  // The light tree (SceneView::light_tree has nodes: more than one leaf of lights), which
  // render.light_sampler bvh descends.
  kFeatureLightTree = 1u << 12,
};

constexpr uint32_t kAllFeatures = 0xffffffffu;
// Materials other than Lambertian diffuse.
// (Subsurface is grouped with them: its boundary is a dielectric. Textures too: a
// metallic-roughness map turns diffuse into metal per texel, and grouping them keeps the CUDA
// specialisations at three bits, so diffuse-only untextured kernels compile no texture code.
// Infinite lights as well: a fourth bit would double the kernels compiled (the megakernels alone
// from 32 to 64), for scenes that are rarely diffuse-only; grouped, the diffuse kernels of
// closed rooms compile neither the environment's lookups nor its sampling, and a diffuse scene
// under a sky runs the specular kernels, which test the material type it does not need. Point and
// spot lights join them for the same reason, and the light tree: its descent doubles the diffuse
// megakernels' spills, and a scene of one lamp, such as the Cornell box, has no tree.)
constexpr uint32_t kFeatureSpecular = kFeatureDielectric | kFeatureMirror | kFeatureAbsorption |
                                      kFeatureSubsurface | kFeatureTextures |
                                      kFeatureInfiniteLights | kFeaturePointLights |
                                      kFeatureLightTree;

// Specialisations: three bits (1 spheres, 2 depth of field, 4 specular materials, textures,
// subsurface, infinite lights, point lights or a light tree) name the eight
// compiled variants both backends run; kGeneralSpec is the one for all features.
constexpr uint32_t kSpecSpheres = 1, kSpecDepthOfField = 2, kSpecSpecular = 4;
constexpr uint32_t kGeneralSpec = 7;

template <uint32_t Spec>
constexpr uint32_t features_of() {
  return kFeatureEmissiveMeshes | kFeatureShadingNormals |
         ((Spec & kSpecSpheres) ? kFeatureSpheres : 0u) |
         ((Spec & kSpecDepthOfField) ? kFeatureDepthOfField : 0u) |
         ((Spec & kSpecSpecular) ? kFeatureSpecular : 0u);
}

// The smallest specialisation that covers a scene's features.
constexpr uint32_t spec_for_features(uint32_t f) {
  return ((f & kFeatureSpheres) ? kSpecSpheres : 0u) |
         ((f & kFeatureDepthOfField) ? kSpecDepthOfField : 0u) |
         ((f & kFeatureSpecular) ? kSpecSpecular : 0u);
}

// The name of a specialisation, as `pathtracer info`, the bench and the sidecar print it.
inline const char* spec_label(uint32_t spec) {
  static const char* kNames[8] = {
      "triangles, pinhole, diffuse only",      "spheres+triangles, pinhole, diffuse only",
      "triangles, thin lens, diffuse only",    "spheres+triangles, thin lens, diffuse only",
      "triangles, pinhole, specular",          "spheres+triangles, pinhole, specular",
      "triangles, thin lens, specular",        "general (all features)"};
  return kNames[spec & 7];
}
inline const char* spec_name_for_features(uint32_t f) { return spec_label(spec_for_features(f)); }

}  // namespace tracer
