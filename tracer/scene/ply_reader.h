// PLY meshes (Stanford polygon files), ASCII and binary of either byte order, through a small
// reader of our own that checks every count in the header against the file before allocating.
#pragma once

#include <string>

#include "scene/loader_util.h"

namespace tracer {

// What read_ply() finds: positions, normals and texture coordinates when the file has them (uv
// (0, 0) is the image's top-left corner, so a file's v is flipped as for OBJ), triangles (polygons
// fan-triangulated); part.materials is left empty for the caller to fill.
struct PlyMesh {
  MeshPart part;
  size_t skipped_faces = 0;  // faces with fewer than 3 corners
};

// Reads a PLY file's vertices ("x", "y", "z"; "nx", "ny", "nz"; "u"/"v", "s"/"t", "texture_u"/
// "texture_v" or "texture_s"/"texture_t") and faces ("vertex_indices" or "vertex_index" lists of
// any integer types); other elements and properties are skipped by their sizes. A truncated file,
// a count larger than the file can hold, an index out of range or a non-finite number throws
// InputError naming `path` (and, in ASCII files, the line). `suffix` is appended to every message,
// e.g. " (mesh referenced at scene.pbrt:12)".
PlyMesh read_ply(const std::string& path, const SourceLoc& from, const std::string& suffix = "");
// The same on bytes already in memory (`path` names them in messages).
PlyMesh parse_ply(const std::string& bytes, const std::string& path,
                  const std::string& suffix = "");

// append_mesh_file's reader for .ply: every triangle gets `material_override`, or a grey diffuse
// material when it is kInvalid (PLY files carry no materials).
void append_ply_file(Scene& scene, const std::string& path, const mat4& xform,
                     uint32_t material_override, const SourceLoc& from);

}  // namespace tracer
