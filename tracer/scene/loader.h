// Scene loading entry points: JSON scenes, OBJ/glTF meshes (inside a scene or opened directly),
// the built-in Cornell box, and the validation every loaded scene passes through.
#pragma once

#include <string>

#include "scene/scene.h"

namespace tracer {

// Loads .json scenes, or .obj / .gltf / .glb files opened directly as scenes. Throws InputError.
Scene load_scene(const std::string& path);
// Parses JSON scene text; `path` is used in messages and to resolve relative mesh paths.
Scene load_scene_from_json(const std::string& text, const std::string& path);
// The built-in Cornell box (kBuiltinSceneJson), source "<built-in>".
Scene builtin_default_scene();
// Appends an OBJ/glTF file's triangles (transformed by `xform`) to `scene`. When
// `material_override` != kInvalid every triangle gets that material; otherwise the file's own
// materials are added to the scene. `from` is where the file was referenced (for messages).
void append_mesh_file(Scene& scene, const std::string& path, const glm::mat4& xform,
                      uint32_t material_override, const SourceLoc& from);
// Checks the assembled scene (NaN/Inf, zero-area triangles, index ranges, parameter ranges,
// image size vs memory), fixes what can be fixed with a warning, throws InputError otherwise.
void validate_scene(Scene& scene);
// Whether validate_scene removes triangle `tri` of `mesh` as degenerate (zero area relative to
// its longest edge). False for indices out of range, which validate_scene reports.
bool is_zero_area_triangle(const TriangleMesh& mesh, uvec3 tri);

}  // namespace tracer
