// The glTF JSON as written, read beside tinygltf. tinygltf reports glTF 1.0 and compressed
// meshes as broken accessors, and drops members of the wrong type without a word; this pass
// finds the version and the compression extensions first, and reads the material members the
// glTF loader uses, warning (path, line, JSON pointer) about each one it cannot use.
#pragma once

#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/diagnostics.h"
#include "core/hd.h"
#include "scene/json_lines.h"

namespace tracer {

// KHR_texture_transform: uv' = T(offset) R(rotation) S(scale) uv as a 2x3 matrix (its columns
// are the images of u, of v and the offset). The rotation turns the uvs counter-clockwise as
// the image is seen (v runs down it), so u' = cos*sx*u + sin*sy*v + ox and
// v' = -sin*sx*u + cos*sy*v + oy; this is the matrix of the extension's worked example ("the
// lower left quadrant of the image, rotated clockwise 90 degrees") and of its sample model.
glm::mat3x2 khr_texture_transform(vec2 offset, float rotation, vec2 scale);

// The texture slots of a material that the loader reads.
enum class GltfSlot { kBaseColor, kMetallicRoughness, kEmissive, kNormal };

// One textureInfo as the file writes it.
struct GltfTextureRef {
  int index = -1;     // glTF texture; -1 when absent or unusable (the latter warned)
  int tex_coord = 0;  // TEXCOORD_n, after KHR_texture_transform's override
  glm::mat3x2 transform = glm::mat3x2(1.0f);
  std::string pointer;  // "/materials/0/pbrMetallicRoughness/baseColorTexture"
  std::vector<std::string> ignored_extensions;  // textureInfo extensions other than the transform
};

class GltfJson {
 public:
  // Reads the JSON of `path` (a .gltf, or a .glb's JSON chunk), keeping only the members it
  // checks. Throws InputError (`suffix` appended) for glTF 1.0 and for a required compression
  // extension. JSON it cannot read is left for tinygltf to report.
  GltfJson(const std::string& path, const std::string& suffix);

  // The unsupported compression extension the file uses without requiring it, "" if none, and
  // what it compresses ("Draco-compressed geometry").
  const std::string& compression() const { return compression_; }
  static std::string compression_what(const std::string& extension);

  // How many materials the JSON holds (0 where it could not be read).
  size_t material_count() const;

  // Material `m`'s textureInfo in `slot`; `textures` is the file's texture count. Members of the
  // wrong type and texture indices out of range are warned in `diag`.
  GltfTextureRef texture(size_t m, GltfSlot slot, size_t textures, Diagnostics& diag) const;
  // Warns about the wrongly typed members of material `m` that the loader reads (tinygltf
  // uses the defaults for them): call once per material.
  void check_material(size_t m, Diagnostics& diag) const;
  // Warns about wrongly typed members of the meshes and their primitives: call once.
  void check_meshes(Diagnostics& diag) const;

 private:
  const nlohmann::json* material(size_t m) const;
  SourceLoc loc(const std::string& pointer) const;
  void warn(Diagnostics& diag, const std::string& pointer, const std::string& problem,
            const std::string& action) const;

  std::string path_, suffix_;
  bool binary_ = false;
  nlohmann::json root_;  // asset, extensionsUsed, extensionsRequired, materials, meshes only
  std::map<std::string, std::string> top_types_;  // top-level member -> JSON type name
  std::string compression_;
  mutable std::unique_ptr<JsonDocument> lines_;  // parsed on the first warning (.gltf only)
  mutable bool lines_tried_ = false;
};

}  // namespace tracer
