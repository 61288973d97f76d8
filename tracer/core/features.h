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
  // Instances of meshes (the BVH's second level, bvh/instance.h).
  kFeatureInstances = 1u << 13,
  // Not a scene feature: path guiding (integrator/guide.h), compiled into the CPU's code and
  // the wavefront's guided shade kernel only (kSpecGuiding); live where IntegratorSettings::guide
  // has a guide.
  kFeatureGuiding = 1u << 14,
  // Not a scene feature: manifold next-event estimation through smooth glass (render.mnee,
  // integrator/path.h), compiled into the CPU's code and the wavefront's caustic shade kernels
  // only (kSpecCaustics); live where IntegratorSettings::mnee is set.
  kFeatureCaustics = 1u << 15,
  // Not a scene feature: light tracing's camera connections through windows (SceneView::
  // window_planes, integrator/light_path.h), compiled into the CPU's code and the light
  // kernel's variants for scenes that list windows only (their code slows the others' kernel).
  kFeatureWindows = 1u << 16,
  // Not a scene feature: manifold NEE's one-refraction chain (integrator/path.h), compiled into
  // the CPU's code and the mnee kernel's variant for scenes with open glass only
  // (SceneView::open_glass; its code slows the others' stage by 15-40%).
  kFeatureSingleRefraction = 1u << 17,
};

constexpr uint32_t kAllFeatures = 0xffffffffu;
// Materials other than Lambertian diffuse.
// (Subsurface is grouped with them: its boundary is a dielectric. Textures too: a
// metallic-roughness map turns diffuse into metal per texel, and grouping them keeps the diffuse
// kernels free of texture code.)
constexpr uint32_t kFeatureSpecular = kFeatureDielectric | kFeatureMirror | kFeatureAbsorption |
                                      kFeatureSubsurface | kFeatureTextures;
// Lights beyond emissive surfaces: lights at infinity, point and spot lights and the light
// tree's descent. Their sampling code doubled the diffuse megakernels' spills and slowed the
// specular scenes that have none of them by a third (PERFORMANCE.md, rows 90-91), so they have
// their own specialisation bit. It implies the specular one: a scene with these lights compiles
// the kernels of every material, so the bit adds 4 variants (12 in all), not 8.
constexpr uint32_t kFeatureLights = kFeatureInfiniteLights | kFeaturePointLights |
                                    kFeatureLightTree;

// Specialisations: four bits (1 spheres, 2 depth of field, 4 specular materials, textures or
// subsurface, 8 lights beyond emitters: always with 4) name twelve compiled variants;
// kGeneralSpec is the one for all features but instances. A fifth bit, 16, adds the BVH's second level (instances) to the general variant: the call into
// an instance's tree slowed the spheres' kernels of scenes without instances by up to 2.5x
// (PERFORMANCE.md, row 94), and scenes of instances are large scenes that pay for the general
// kernels' code little. 13 variants in all.
constexpr uint32_t kSpecSpheres = 1, kSpecDepthOfField = 2, kSpecSpecular = 4, kSpecLights = 8,
                   kSpecInstances = 16, kSpecGuiding = 32, kSpecCaustics = 64;
constexpr uint32_t kGeneralSpec = 15;                      // every feature but instances
constexpr uint32_t kInstancesSpec = kGeneralSpec | kSpecInstances;  // every scene feature
// Path guiding's shade kernels (the only kernels that guide): the bit 32 on the spheres and
// specular bits of a scene's variant (4 variants), and the general one with instances for scenes
// with lights beyond emitters or instances (kGuidedSpec). guided_shade_spec() picks one.
constexpr uint32_t kGuidedSpec = kInstancesSpec | kSpecGuiding;
constexpr uint32_t guided_shade_spec(uint32_t spec) {
  return (spec & (kSpecLights | kSpecInstances))
             ? kGuidedSpec
             : ((spec & (kSpecSpheres | kSpecSpecular)) | kSpecGuiding);
}
// Manifold NEE's shade kernels (render.mnee; the only kernels that compile it): the bit 64 on a
// guided variant of a scene with glass (so specular: 3 variants), whose guiding is live only
// where a guide is. caustic_shade_spec() picks one.
constexpr uint32_t caustic_shade_spec(uint32_t spec) {
  return guided_shade_spec(spec | kSpecSpecular) | kSpecCaustics;
}
// Indices 0..127; 0..7, 12..15, 31, 32..37, 63, 100, 101 and 127 are used.
constexpr uint32_t kSpecCount = 128;

template <uint32_t Spec>
constexpr uint32_t features_of() {
  static_assert(!(Spec & kSpecLights) || (Spec & kSpecSpecular), "lights imply specular");
  static_assert(!(Spec & kSpecInstances) ||
                    (Spec & ~(kSpecGuiding | kSpecCaustics)) == kInstancesSpec,
                "instances imply every other feature");
  static_assert(!(Spec & kSpecGuiding) || (Spec & kSpecCaustics) ||
                    Spec == guided_shade_spec(Spec & ~kSpecGuiding),
                "a guided variant is one guided_shade_spec() names");
  static_assert(!(Spec & kSpecCaustics) ||
                    Spec == caustic_shade_spec(Spec & ~(kSpecGuiding | kSpecCaustics)),
                "a caustic variant is one caustic_shade_spec() names");
  return kFeatureEmissiveMeshes | kFeatureShadingNormals |
         ((Spec & kSpecSpheres) ? kFeatureSpheres : 0u) |
         ((Spec & kSpecDepthOfField) ? kFeatureDepthOfField : 0u) |
         ((Spec & kSpecSpecular) ? kFeatureSpecular : 0u) |
         ((Spec & kSpecLights) ? kFeatureLights : 0u) |
         ((Spec & kSpecInstances) ? kFeatureInstances : 0u) |
         ((Spec & kSpecGuiding) ? kFeatureGuiding : 0u) |
         ((Spec & kSpecCaustics) ? kFeatureCaustics : 0u);
}

// The smallest specialisation that covers a scene's features.
constexpr uint32_t spec_for_features(uint32_t f) {
  if (f & kFeatureInstances) return kInstancesSpec;
  return ((f & kFeatureSpheres) ? kSpecSpheres : 0u) |
         ((f & kFeatureDepthOfField) ? kSpecDepthOfField : 0u) |
         ((f & (kFeatureSpecular | kFeatureLights)) ? kSpecSpecular : 0u) |
         ((f & kFeatureLights) ? kSpecLights : 0u);
}

// The name of a specialisation, as `pathtracer info`, the bench and the sidecar print it.
inline const char* spec_label(uint32_t spec) {
  static const char* kNames[8] = {
      "triangles, pinhole, diffuse only",      "spheres+triangles, pinhole, diffuse only",
      "triangles, thin lens, diffuse only",    "spheres+triangles, thin lens, diffuse only",
      "triangles, pinhole, specular",          "spheres+triangles, pinhole, specular",
      "triangles, thin lens, specular",        "spheres+triangles, thin lens, specular"};
  static const char* kWithLights[8] = {
      "", "", "", "",
      "triangles, pinhole, specular, lights",  "spheres+triangles, pinhole, specular, lights",
      "triangles, thin lens, specular, lights", "general (all features)"};
  if (spec == (kGuidedSpec | kSpecCaustics))
    return "general with instances, path guiding and manifold NEE (all features)";
  if (spec & kSpecCaustics)
    return (spec & kSpecSpheres) ? "spheres+triangles, specular, path guiding, manifold NEE"
                                 : "triangles, specular, path guiding, manifold NEE";
  if (spec == kGuidedSpec) return "general with instances and path guiding (all features)";
  if (spec & kSpecGuiding) {
    static const char* kGuided[8] = {"triangles, diffuse only, path guiding",
                                     "spheres+triangles, diffuse only, path guiding",
                                     "",
                                     "",
                                     "triangles, specular, path guiding",
                                     "spheres+triangles, specular, path guiding",
                                     "",
                                     ""};
    return kGuided[spec & 7];
  }
  if (spec & kSpecInstances) return "general with instances (all features)";
  return (spec & kSpecLights) ? kWithLights[spec & 7] : kNames[spec & 7];
}
inline const char* spec_name_for_features(uint32_t f) { return spec_label(spec_for_features(f)); }

}  // namespace tracer
