// The host-side scene: what loaders produce and the UI edits. Plain std containers; flattened into
// the device-friendly SceneView by CompiledScene (compiled_scene.h).
#pragma once

#include <string>
#include <vector>

#include "camera/filter.h"
#include "core/diagnostics.h"
#include "core/sobol.h"
#include "materials/material.h"
#include "materials/texture.h"
#include "scene/environment.h"
#include "scene/point_lights.h"
#include "scene/light_tree_view.h"
#include "scene/settings.h"

namespace tracer {

struct CameraDesc {
  vec3 position = vec3(0.0f, 0.0f, 5.0f);
  vec3 look_at = vec3(0.0f);
  vec3 up = vec3(0.0f, 1.0f, 0.0f);
  float vfov_deg = 40.0f;
  float aperture_radius = 0.0f;  // 0: pinhole
  float focus_distance = 0.0f;   // 0: the distance from position to look_at
};

struct RenderSettings {
  int width = 512;
  int height = 512;
  int spp = 64;
  double time_limit_s = 0.0;  // > 0: render until this much time has passed instead of spp
  int max_depth = 8;          // maximum number of path segments (the camera ray is the first)
  bool nee = true;            // next-event estimation (light sampling)
  bool mis = true;            // combine NEE and BSDF sampling with the power heuristic
  bool russian_roulette = true;
  int rr_start_depth = 4;  // roulette applies from this path depth on
  uint32_t seed = 0;
  bool jitter = true;  // jitter samples inside each pixel (antialiasing)
  float clamp = 0.0f;  // > 0: clamp each sample's radiance to this (removes fireflies; biased)
  uint32_t sampler = kSamplerSobol;  // kSamplerRandom, kSamplerSobol, kSamplerSobolPairs
  BackendChoice backend = BackendChoice::kAuto;
  int threads = 0;            // CPU backend threads (0: all cores)
  int samples_per_frame = 0;  // workbench on the GPU: samples per window frame (0: adapted)
  bool strict = false;        // every warning about the input is an error (headless: exit 1)
  PixelFilter filter = PixelFilter::kBox;
  float filter_radius = 0.0f;  // pixels; 0: the filter's default (camera/filter.h)
  // How next-event estimation chooses a light: kLightSamplerUniform, kLightSamplerPower or
  // kLightSamplerBvh (the light tree; scene/light_tree_view.h)
  uint32_t light_sampler = kLightSamplerBvh;
  bool guiding = false;  // path guiding (integrator/guide.h)
  bool mnee = false;     // manifold next-event estimation through glass (integrator/manifold.h)
  bool light_tracing = false;  // light tracing of caustics (integrator/light_path.h)
};

// "random" / "sobol" / "sobol-pairs", as the scene format, the CLI and the workbench spell
// RenderSettings::sampler.
inline const char* sampler_name(uint32_t sampler) {
  return sampler == kSamplerRandom ? "random"
         : sampler == kSamplerSobolPairs ? "sobol-pairs"
                                         : "sobol";
}
// false for an unknown name, leaving *sampler as it was.
inline bool parse_sampler(const std::string& name, uint32_t* sampler) {
  if (name == "random")
    *sampler = kSamplerRandom;
  else if (name == "sobol")
    *sampler = kSamplerSobol;
  else if (name == "sobol-pairs")
    *sampler = kSamplerSobolPairs;
  else
    return false;
  return true;
}

struct NamedMaterial {
  std::string name;
  Material material;
};

struct SphereDesc {
  vec3 center = vec3(0.0f);
  float radius = 1.0f;
  uint32_t material = 0;
};

// Indexed triangles with optional per-vertex normals and texture coordinates (each empty or one
// per position). uv (0, 0) is the top-left corner of an image (glTF convention).
struct TriangleMesh {
  std::vector<vec3> positions;
  std::vector<vec3> normals;
  std::vector<vec2> uvs;
  std::vector<uvec3> indices;
  std::vector<uint32_t> materials;  // one per triangle
};

// A decoded image plus how it is sampled. RGBA8, as in the file: a quarter of the memory of
// linear floats; colour maps keep their sRGB encoding and are decoded per texel at lookup.
struct TextureImage {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba8;  // width * height * 4 bytes, rows top to bottom
  bool srgb = false;           // base colour and emissive maps; not metallic-roughness or normal
  TextureWrap wrap_s = TextureWrap::kRepeat, wrap_t = TextureWrap::kRepeat;
  glm::mat3x2 uv_transform = glm::mat3x2(1.0f);  // TextureDesc::uv_transform
  std::string source;  // file it came from, for messages
};

// A mesh drawn by instances (pbrt's ObjectBegin/ObjectInstance, a glTF mesh that several nodes
// use, a JSON object with "instances"): its triangles in its own space, stored once however many
// instances place it. Materials per triangle, as in the scene's mesh. Never emissive: emitters are
// lights, which are world-space triangles, so loaders flatten an emissive mesh's instances.
struct InstancedMesh {
  std::string name;
  TriangleMesh mesh;
};

// One placement of an instanced mesh: an affine map from the mesh's space to the world.
struct MeshInstance {
  uint32_t mesh = 0;  // index into Scene::instanced_meshes
  glm::mat4 world_from_object = glm::mat4(1.0f);
};

// What the user sees in the object list: a sphere, a range of the mesh's triangles or a range of
// instances.
struct ObjectInfo {
  std::string name;
  std::string kind;  // "sphere", "box", "quad", "mesh", "instances"
  bool is_sphere = false;
  bool is_instances = false;
  uint32_t first = 0;  // sphere index, first triangle, or first instance
  uint32_t count = 0;  // number of triangles (1 for a sphere), or of instances
  SourceLoc loc;
  bool is_triangles() const { return !is_sphere && !is_instances; }
};

struct Scene {
  std::string source;  // path it was loaded from, or "<built-in>"
  CameraDesc camera;
  RenderSettings settings;
  GpuOptions gpu;
  DisplaySettings display;
  std::vector<NamedMaterial> materials;
  std::vector<SphereDesc> spheres;
  std::vector<TextureImage> textures;  // Material::*_tex index into this
  TriangleMesh mesh;                   // every triangle of every object, in world space
  // Meshes drawn by instances, and the instances (their triangles are not in `mesh`).
  std::vector<InstancedMesh> instanced_meshes;
  std::vector<MeshInstance> instances;
  std::vector<ObjectInfo> objects;
  // The lights at infinity: the environment's settings (the table's "environment" section),
  // the map read from environment.file (shared by copies of the scene; set by the setting's
  // load hook, refresh_environment), and the distant lights (the scene file's "lights").
  EnvironmentDesc environment;
  std::shared_ptr<const EnvironmentImage> environment_image;
  std::vector<DistantLightDesc> distant_lights;
  // Point and spot lights (the scene file's "lights" of type "point" and "spot", pbrt's
  // LightSource "point" and "spot").
  std::vector<PointLightDesc> point_lights;
  Diagnostics diagnostics;

  uint32_t add_material(const std::string& name, const Material& m);
  // Triangles the instances place (each instance's mesh counted once per instance).
  uint64_t instanced_triangle_count() const;
  // Index of the named material, or kInvalid.
  uint32_t find_material(const std::string& name) const;
};

// Copies every instance's triangles into the scene's mesh in world space and drops the
// instances (their objects become mesh objects): the flattened scene renders the same image. For
// comparisons and for emissive meshes.
void flatten_instances(Scene& scene);

// Instances are kept where they save memory that matters: scenes whose instances place fewer
// than kKeepInstancesFrom triangles in all are flattened, with a note (rays through the second
// level cost about twice those through world-space triangles: docs/PERFORMANCE.md, row 95, while
// 4 million triangles take about 0.5 GB written out). The commands and the workbench call it
// after loading a scene; the loaders themselves keep what the file says. True when it flattened.
constexpr uint64_t kKeepInstancesFrom = 4000000;
bool flatten_small_instances(Scene& scene);

// Brings environment_image up to date with environment.file (reads the file when it names
// another one; drops the image when it is ""; warns once about clamped negative texels) and
// checks the map's shape against environment.mapping. "" or the problem (the file's own
// "path[:line]: what"); the scene's image is unchanged on a problem. The load hook of the
// environment.file and environment.mapping settings.
std::string refresh_environment(Scene& scene);

// "sunrise.exr, 1024x512 equirect (auto), strength 1, rotation 0 deg, 596 negative texels
// clamped; 1 distant light", "constant colour [...]" or "none", for `info` and the workbench.
std::string describe_environment(const Scene& scene);

}  // namespace tracer
