// load_scene and append_mesh_file: pick the reader by file extension. A mesh file opened as a
// scene becomes one object with a framing camera and, if needed, a default light.
#include "scene/loader.h"

#include "scene/loader_util.h"
#include "scene/pbrt_loader.h"
#include "scene/ply_reader.h"

namespace tracer {

void append_mesh_file(Scene& scene, const std::string& path, const glm::mat4& xform,
                      uint32_t material_override, const SourceLoc& from) {
  const std::string ext = path_extension_lower(path);
  if (ext == ".obj") {
    append_obj_file(scene, path, xform, material_override, from);
  } else if (ext == ".gltf" || ext == ".glb") {
    append_gltf_file(scene, path, xform, material_override, from, nullptr, nullptr);
  } else if (ext == ".ply") {
    append_ply_file(scene, path, xform, material_override, from);
  } else {
    throw InputError(from, "unsupported mesh file type \"" + ext + "\" for \"" + path +
                               "\" (expected .obj, .gltf, .glb or .ply)");
  }
}

Scene load_scene(const std::string& path) {
  const std::string ext = path_extension_lower(path);
  const SourceLoc file{path, 0};
  if (ext == ".json") return load_scene_from_json(read_file_text(path, file), path);
  if (ext == ".pbrt") return load_pbrt_scene(path);
  if (ext != ".obj" && ext != ".gltf" && ext != ".glb" && ext != ".ply") {
    throw InputError(file, "unknown scene file type \"" + ext +
                               "\" (expected .json, .pbrt, .obj, .gltf, .glb or .ply)");
  }
  if (!file_exists(path)) read_file_text(path, file);  // throws the precise reason
  Scene scene;
  scene.source = path;
  bool has_camera = false;
  const uint32_t before = uint32_t(scene.mesh.indices.size());
  if (ext == ".obj")
    append_obj_file(scene, path, mat4(1.0f), kInvalid, file);
  else if (ext == ".ply")
    append_ply_file(scene, path, mat4(1.0f), kInvalid, file);
  else
    append_gltf_file(scene, path, mat4(1.0f), kInvalid, file, &scene.camera, &has_camera);
  if (scene.mesh.indices.size() == before && scene.instances.empty()) {
    // Say why, rather than a bare "no geometry": the reader's warnings usually hold the reason.
    std::string why;
    for (const std::string& w : scene.diagnostics.warnings) why += (why.empty() ? " (" : " | ") + w;
    throw InputError(file, "the file contains no triangles" + (why.empty() ? "" : why + ")"));
  }
  // A file of only degenerate triangles is as empty as one without any (and would otherwise
  // render its default light alone): checked before framing adds that light.
  uint32_t degenerate = 0;
  for (uint32_t t = before; t < scene.mesh.indices.size(); ++t)
    degenerate += is_zero_area_triangle(scene.mesh, scene.mesh.indices[t]) ? 1u : 0u;
  if (degenerate == scene.mesh.indices.size() - before && scene.instances.empty()) {
    throw InputError(file, (degenerate == 1 ? std::string("the file's only triangle has")
                                            : "all " + std::to_string(degenerate) +
                                                  " triangles of the file have") +
                               " zero area (degenerate: collinear or repeated vertices), so it "
                               "has no geometry to render");
  }
  ObjectInfo info;
  const size_t slash = path.find_last_of('/');
  info.name = slash == std::string::npos ? path : path.substr(slash + 1);
  info.kind = "mesh";
  info.first = before;
  info.count = uint32_t(scene.mesh.indices.size()) - before;
  info.loc = file;
  // A glTF whose meshes are all instanced (each used by several nodes) leaves no triangles here;
  // its objects are the instances.
  if (info.count > 0 || scene.instances.empty()) scene.objects.push_back(info);
  frame_mesh_scene(scene, has_camera);
  validate_scene(scene);
  return scene;
}

}  // namespace tracer
