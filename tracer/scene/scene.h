// The host-side scene: what loaders produce and the UI edits. Plain std containers; flattened into
// the device-friendly SceneView by CompiledScene (compiled_scene.h).
#pragma once

#include <string>
#include <vector>

#include "materials/material.h"
#include "scene/diagnostics.h"

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
  int rr_start_depth = 3;  // roulette applies from this path depth on
  uint32_t seed = 0;
  bool jitter = true;  // jitter samples inside each pixel (antialiasing)
};

struct NamedMaterial {
  std::string name;
  Material material;
};

struct SphereDesc {
  vec3 center = vec3(0.0f);
  float radius = 1.0f;
  uint32_t material = 0;
};

// Indexed triangles with optional per-vertex normals (empty or one per position).
struct TriangleMesh {
  std::vector<vec3> positions;
  std::vector<vec3> normals;
  std::vector<uvec3> indices;
  std::vector<uint32_t> materials;  // one per triangle
};

// What the user sees in the object list; a sphere or a range of the mesh's triangles.
struct ObjectInfo {
  std::string name;
  std::string kind;  // "sphere", "box", "quad", "mesh"
  bool is_sphere = false;
  uint32_t first = 0;  // sphere index, or first triangle
  uint32_t count = 0;  // number of triangles (1 for a sphere)
  SourceLoc loc;
};

struct Scene {
  std::string source;  // path it was loaded from, or "<built-in>"
  CameraDesc camera;
  RenderSettings settings;
  std::vector<NamedMaterial> materials;
  std::vector<SphereDesc> spheres;
  TriangleMesh mesh;  // every triangle of every object, in world space
  std::vector<ObjectInfo> objects;
  Diagnostics diagnostics;

  uint32_t add_material(const std::string& name, const Material& m);
  // Index of the named material, or kInvalid.
  uint32_t find_material(const std::string& name) const;
};

}  // namespace tracer
