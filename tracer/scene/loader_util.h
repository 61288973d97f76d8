// Internal to the scene loaders: appending transformed triangles to the scene mesh, file and path
// helpers, framing a camera and light for a mesh opened on its own, and the per-format readers.
#pragma once

#include <string>
#include <vector>

#include "scene/scene.h"

namespace tracer {

// Triangles in object space, as a mesh reader produces them.
struct MeshPart {
  std::vector<vec3> positions;
  std::vector<vec3> normals;  // empty, or one per position
  std::vector<vec2> uvs;      // empty, or one per position; (0, 0) is the image's top-left
  std::vector<uvec3> indices;
  std::vector<uint32_t> materials;  // one per triangle
};

// A procedural terrain: a resolution x resolution grid of cells over [0, size.x] x [0, size.y]
// in x and z, displaced in y by fractal value noise (six octaves, amplitude `height`, the same
// for the same seed on every machine), two triangles per cell and smooth vertex normals. It
// makes benchmark scenes of any size without shipping their files (2 resolution^2 triangles:
// 2,237 gives 10 million).
MeshPart terrain_mesh(vec2 size, uint32_t resolution, float height, uint32_t seed);

// Transforms `part` by `xform` (normals by its inverse transpose; winding flipped for a mirroring
// transform so the geometric normal keeps facing out) and appends it to scene.mesh. Keeps
// scene.mesh.normals either empty or one per position by giving triangles that have none their
// flat geometric normal. Returns the index of the first appended triangle.
uint32_t append_part(Scene& scene, const MeshPart& part, const mat4& xform);

// A mesh's triangles as a part (normals and uvs kept where they cover every position).
MeshPart mesh_part_of(const TriangleMesh& mesh);
// The triangles of `part` as an instanced mesh's, untransformed.
TriangleMesh triangle_mesh_of(MeshPart part);

// Whether any triangle of `mesh` uses an emissive material of `scene` (such a mesh is flattened:
// emitters are world-space triangles).
bool uses_emissive_material(const Scene& scene, const TriangleMesh& mesh);

// Why `world_from_object` cannot place an instance ("" when it can): not finite, not affine, or
// singular (a zero determinant, also one that underflows a float).
std::string instance_transform_problem(const mat4& world_from_object);

// Adds `mesh` (object space) once with one instance per placement, as one object of kind
// "instances" named `info`'s name. When a material of the mesh emits, appends each placement's
// triangles to scene.mesh instead (an object of `info`'s kind) and says so in a note at `info.loc`.
void add_instanced_object(Scene& scene, ObjectInfo info, TriangleMesh mesh,
                          const std::vector<mat4>& placements);

// Reads a mesh file's triangles in the file's own space (append_mesh_file without a transform)
// into a mesh of their own; the file's materials and textures are added to `scene` and its
// warnings to scene.diagnostics, so material indices refer to scene.materials.
TriangleMesh read_mesh_file_local(Scene& scene, const std::string& path, uint32_t material_override,
                                  const SourceLoc& from);

// Gives triangles [first, first + count) their geometric normal as vertex normals (so shading is
// exactly flat), duplicating a vertex where faces with different normals share it.
void set_flat_normals(TriangleMesh& mesh, uint32_t first, uint32_t count);

// Reads a whole file; a missing or unreadable file throws InputError at `from`.
std::string read_file_text(const std::string& path, const SourceLoc& from);
bool file_exists(const std::string& path);
std::string path_extension_lower(const std::string& path);  // ".obj"; "" when there is none
std::string path_directory(const std::string& path);        // "" for a bare file name
std::string path_join(const std::string& dir, const std::string& rel);

// Decodes an image file (PNG, JPEG, ... through stb_image) into t's size and RGBA8 texels.
// Returns false when stb_image cannot decode it; one larger than 16384 texels a side throws
// InputError at the image, with `context` appended (where it was used).
bool decode_texture_file(const std::string& path, TextureImage* t, const std::string& context);

// For a mesh file opened as a scene: a camera framing the bounds unless `keep_camera`, and a
// default area light (with a warning) when no material emits.
void frame_mesh_scene(Scene& scene, bool keep_camera);


// The format readers behind append_mesh_file. The glTF reader also returns the file's first
// camera, placed by its node transform and `xform`, when `camera` is non-null.
void append_obj_file(Scene& scene, const std::string& path, const mat4& xform,
                     uint32_t material_override, const SourceLoc& from);
void append_gltf_file(Scene& scene, const std::string& path, const mat4& xform,
                      uint32_t material_override, const SourceLoc& from, CameraDesc* camera,
                      bool* has_camera);

}  // namespace tracer
