// Helpers shared by the scene loaders: mesh appending with consistent normals, file access, and
// the default camera and light for meshes opened directly.
#include "scene/loader_util.h"

#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/math.h"

namespace tracer {

uint32_t append_part(Scene& scene, const MeshPart& part, const mat4& xform) {
  TriangleMesh& mesh = scene.mesh;
  const uint32_t first_tri = uint32_t(mesh.indices.size());
  const bool part_normals = !part.normals.empty();
  // One normals array covers the whole scene mesh, so it is all or nothing: when the first smooth
  // object arrives, the flat ones before it get their exact geometric normal.
  if (part_normals && mesh.normals.empty() && !mesh.indices.empty())
    set_flat_normals(mesh, 0, first_tri);
  // After set_flat_normals, which may append duplicated vertices.
  const uint32_t base = uint32_t(mesh.positions.size());

  const mat3 m(xform);
  const mat3 normal_m = glm::transpose(glm::inverse(m));
  const bool mirrored = glm::determinant(m) < 0.0f;
  for (const vec3& p : part.positions) mesh.positions.push_back(vec3(xform * vec4(p, 1.0f)));
  if (part_normals) {
    mesh.normals.resize(base);
    for (const vec3& n : part.normals) {
      const vec3 t = normal_m * n;
      const float len = glm::length(t);
      // Zero-length normals stay zero so that validate_scene can report and replace them.
      mesh.normals.push_back(len > 0.0f && is_finite(len) ? t / len : t);
    }
  }
  // Texture coordinates, like normals, cover all positions or none; parts without get (0, 0).
  const bool part_uvs = part.uvs.size() == part.positions.size() && !part.uvs.empty();
  if (part_uvs || !mesh.uvs.empty()) {
    mesh.uvs.resize(base, vec2(0.0f));
    if (part_uvs)
      mesh.uvs.insert(mesh.uvs.end(), part.uvs.begin(), part.uvs.end());
    else
      mesh.uvs.resize(mesh.positions.size(), vec2(0.0f));
  }
  for (size_t i = 0; i < part.indices.size(); ++i) {
    uvec3 t = part.indices[i] + uvec3(base);
    if (mirrored) std::swap(t.y, t.z);
    mesh.indices.push_back(t);
    mesh.materials.push_back(part.materials[i]);
  }
  if (!part_normals && !mesh.normals.empty())
    set_flat_normals(mesh, first_tri, uint32_t(part.indices.size()));
  return first_tri;
}

void set_flat_normals(TriangleMesh& mesh, uint32_t first, uint32_t count) {
  if (mesh.normals.size() < mesh.positions.size()) mesh.normals.resize(mesh.positions.size());
  std::vector<uint8_t> assigned(mesh.positions.size(), 0);
  for (uint32_t t = first; t < first + count; ++t) {
    uvec3& tri = mesh.indices[t];
    const vec3 p0 = mesh.positions[tri.x], p1 = mesh.positions[tri.y], p2 = mesh.positions[tri.z];
    const vec3 c = glm::cross(p1 - p0, p2 - p0);
    const float len = glm::length(c);
    // A degenerate triangle gets any unit normal; validate_scene removes it anyway.
    const vec3 n = len > 0.0f && is_finite(len) ? c / len : vec3(0.0f, 0.0f, 1.0f);
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = tri[k];
      if (v < assigned.size() && !assigned[v]) {
        assigned[v] = 1;
        mesh.normals[v] = n;
      } else if (glm::dot(mesh.normals[v], n) < 1.0f - 1e-6f) {
        mesh.positions.push_back(mesh.positions[v]);
        mesh.normals.push_back(n);
        if (!mesh.uvs.empty()) mesh.uvs.push_back(mesh.uvs[v]);
        tri[k] = uint32_t(mesh.positions.size() - 1);
      }
    }
  }
}

bool file_exists(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::string read_file_text(const std::string& path, const SourceLoc& from) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0)
    throw InputError(from, "cannot open \"" + path + "\": " + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) throw InputError(from, "\"" + path + "\" is a directory, not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(from, "cannot open \"" + path + "\": " + std::strerror(errno));
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string path_extension_lower(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot);
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

std::string path_directory(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? "" : path.substr(0, slash + 1);
}

std::string path_join(const std::string& dir, const std::string& rel) {
  if (rel.empty() || rel[0] == '/' || dir.empty()) return rel;
  return dir.back() == '/' ? dir + rel : dir + "/" + rel;
}

std::string vec3_str(vec3 v) {
  std::ostringstream ss;
  ss << "[" << v.x << ", " << v.y << ", " << v.z << "]";
  return ss.str();
}

void frame_mesh_scene(Scene& scene, bool keep_camera) {
  vec3 lo(kInfinity), hi(-kInfinity);
  for (const uvec3& t : scene.mesh.indices) {
    for (int k = 0; k < 3; ++k) {
      if (t[k] >= scene.mesh.positions.size()) continue;
      const vec3 p = scene.mesh.positions[t[k]];
      if (!is_finite(p)) continue;
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
  }
  if (!(lo.x <= hi.x)) return;  // nothing to frame; validate_scene reports the empty scene
  const vec3 centre = 0.5f * (lo + hi);
  const float radius = std::max(0.5f * glm::length(hi - lo), 1e-3f);
  if (!keep_camera) {
    // Fit the bounding sphere into a 40 degree field of view, with a little margin.
    scene.camera = CameraDesc();
    scene.camera.vfov_deg = 40.0f;
    const float dist = 1.1f * radius / std::sin(glm::radians(0.5f * scene.camera.vfov_deg));
    scene.camera.look_at = centre;
    scene.camera.position = centre + vec3(0.0f, 0.0f, dist);
  }
  bool lit = false;
  for (const NamedMaterial& m : scene.materials) lit |= m.material.is_emissive();
  if (lit) return;
  // A horizontal square light of side 2r, r above the top of the bounds and shifted towards the
  // camera, facing down. Radiance 4 gives an irradiance of about 3 at the model, so a white
  // diffuse surface shows up near 0.8 before tone mapping.
  Material light;
  light.albedo = vec3(0.0f);
  light.emission = vec3(4.0f);
  const uint32_t mat = scene.add_material("default light", light);
  const float side = 2.0f * radius;
  const vec3 corner(centre.x - radius, hi.y + radius, centre.z - 0.5f * radius);
  MeshPart quad;
  // Edges (side,0,0) then (0,0,side): cross((1,0,0),(0,0,1)) = (0,-1,0), so the front faces down.
  quad.positions = {corner, corner + vec3(side, 0, 0), corner + vec3(side, 0, side),
                    corner + vec3(0, 0, side)};
  quad.indices = {uvec3(0, 1, 2), uvec3(0, 2, 3)};
  quad.materials = {mat, mat};
  ObjectInfo info;
  info.name = "default light";
  info.kind = "quad";
  info.first = append_part(scene, quad, mat4(1.0f));
  info.count = 2;
  info.loc = {scene.source, 0};
  scene.objects.push_back(info);
  scene.diagnostics.warn({scene.source, 0}, "no light in file",
                         "added a default area light above the model");
}

}  // namespace tracer
