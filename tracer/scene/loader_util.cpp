// Helpers shared by the scene loaders: mesh appending with consistent normals, file access, and
// the default camera and light for meshes opened directly.
#include "scene/loader_util.h"

#include <stb_image.h>
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "core/math.h"
#include "scene/loader.h"

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

MeshPart mesh_part_of(const TriangleMesh& mesh) {
  MeshPart part;
  part.positions = mesh.positions;
  if (mesh.normals.size() == mesh.positions.size()) part.normals = mesh.normals;
  if (mesh.uvs.size() == mesh.positions.size()) part.uvs = mesh.uvs;
  part.indices = mesh.indices;
  part.materials = mesh.materials;
  return part;
}

TriangleMesh triangle_mesh_of(MeshPart part) {
  TriangleMesh mesh;
  mesh.positions = std::move(part.positions);
  if (part.normals.size() == mesh.positions.size()) mesh.normals = std::move(part.normals);
  if (part.uvs.size() == mesh.positions.size()) mesh.uvs = std::move(part.uvs);
  mesh.indices = std::move(part.indices);
  mesh.materials = std::move(part.materials);
  return mesh;
}

bool uses_emissive_material(const Scene& scene, const TriangleMesh& mesh) {
  std::vector<uint8_t> seen(scene.materials.size(), 0);
  for (uint32_t m : mesh.materials) {
    if (m >= seen.size() || seen[m]) continue;
    seen[m] = 1;
    if (scene.materials[m].material.is_emissive()) return true;
  }
  return false;
}

std::string instance_transform_problem(const mat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return "is not finite";
  if (m[0][3] != 0.0f || m[1][3] != 0.0f || m[2][3] != 0.0f || m[3][3] != 1.0f)
    return "is not affine (its last row is not 0, 0, 0, 1)";
  // In double: the product of three tiny scales underflows a float's determinant to zero, and the
  // renderer inverts the matrix in float, which needs a normal determinant.
  const glm::dmat3 a{glm::dvec3(m[0]), glm::dvec3(m[1]), glm::dvec3(m[2])};
  const double det = glm::determinant(a);
  if (!(std::fabs(det) >= double(std::numeric_limits<float>::min())) || !std::isfinite(det))
    return "is singular (it flattens the mesh; determinant " + std::to_string(det) + ")";
  return "";
}

void add_instanced_object(Scene& scene, ObjectInfo info, TriangleMesh mesh,
                          const std::vector<mat4>& placements) {
  if (uses_emissive_material(scene, mesh)) {
    const MeshPart part = mesh_part_of(mesh);
    info.first = uint32_t(scene.mesh.indices.size());
    for (const mat4& m : placements) append_part(scene, part, m);
    info.count = uint32_t(scene.mesh.indices.size()) - info.first;
    scene.diagnostics.note(info.loc, "object \"" + info.name + "\" emits light, so its " +
                                         std::to_string(placements.size()) +
                                         " instance(s) are flattened into world-space triangles "
                                         "(instances of emissive meshes are not instanced)");
    scene.objects.push_back(info);
    return;
  }
  const uint32_t index = uint32_t(scene.instanced_meshes.size());
  scene.instanced_meshes.push_back({info.name, std::move(mesh)});
  info.kind = "instances";
  info.is_instances = true;
  info.first = uint32_t(scene.instances.size());
  info.count = uint32_t(placements.size());
  for (const mat4& m : placements) scene.instances.push_back({index, m});
  scene.objects.push_back(info);
}

TriangleMesh read_mesh_file_local(Scene& scene, const std::string& path, uint32_t material_override,
                                  const SourceLoc& from) {
  // The readers append to a scene: give them one whose materials, textures and diagnostics are
  // the real scene's (moved in and back, not copied) and whose mesh starts empty.
  Scene local;
  local.source = scene.source;
  std::swap(local.materials, scene.materials);
  std::swap(local.textures, scene.textures);
  std::swap(local.diagnostics, scene.diagnostics);
  auto give_back = [&] {
    std::swap(local.materials, scene.materials);
    std::swap(local.textures, scene.textures);
    std::swap(local.diagnostics, scene.diagnostics);
  };
  try {
    append_mesh_file(local, path, mat4(1.0f), material_override, from);
  } catch (...) {
    give_back();
    throw;
  }
  give_back();
  // A glTF's own instances (a mesh that several nodes use) become part of this mesh: instances
  // do not nest.
  flatten_instances(local);
  return std::move(local.mesh);
}

void flatten_instances(Scene& scene) {
  if (scene.instances.empty()) return;
  std::vector<MeshPart> parts(scene.instanced_meshes.size());
  for (size_t m = 0; m < parts.size(); ++m) parts[m] = mesh_part_of(scene.instanced_meshes[m].mesh);
  std::vector<uint32_t> first_tri(scene.instances.size());
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const MeshInstance& inst = scene.instances[i];
    first_tri[i] = append_part(scene, parts[inst.mesh], inst.world_from_object);
  }
  const uint32_t total = uint32_t(scene.mesh.indices.size());
  for (ObjectInfo& o : scene.objects) {
    if (!o.is_instances) continue;
    const size_t end = size_t(o.first) + o.count;
    const uint32_t begin_tri = o.first < first_tri.size() ? first_tri[o.first] : total;
    const uint32_t end_tri = end < first_tri.size() ? first_tri[end] : total;
    o.is_instances = false;
    o.kind = "mesh";
    o.first = begin_tri;
    o.count = end_tri - begin_tri;
  }
  scene.instances.clear();
  scene.instanced_meshes.clear();
}

bool flatten_small_instances(Scene& scene) {
  if (scene.instances.empty()) return false;
  const uint64_t placed = scene.instanced_triangle_count();
  if (placed >= kKeepInstancesFrom) return false;
  const size_t count = scene.instances.size();
  flatten_instances(scene);
  scene.diagnostics.note(SourceLoc{scene.source, 0},
                         std::to_string(count) + " instances written out as " +
                             std::to_string(placed) +
                             " triangles (instances are kept from " +
                             std::to_string(kKeepInstancesFrom / 1000000) +
                             " million placed triangles on: below that, world-space triangles "
                             "trace about twice as fast for little memory)");
  return true;
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

bool decode_texture_file(const std::string& path, TextureImage* t, const std::string& context) {
  int w = 0, h = 0, comp = 0;
  if (!stbi_info(path.c_str(), &w, &h, &comp)) return false;
  if (w > 16384 || h > 16384)
    throw InputError({path, 0}, "texture is " + std::to_string(w) + "x" + std::to_string(h) +
                                    ", larger than 16384x16384" + context);
  unsigned char* data = stbi_load(path.c_str(), &w, &h, &comp, 4);
  if (!data) return false;
  t->width = w;
  t->height = h;
  t->rgba8.assign(data, data + size_t(w) * size_t(h) * 4);
  stbi_image_free(data);
  return true;
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

namespace {

std::string fmt(float x) {
  std::ostringstream ss;
  ss.precision(3);
  ss << x;
  return ss.str();
}

// The bounds, total area, area-weighted normal sum and emitted power of the scene's triangles.
struct MeshSurvey {
  vec3 lo = vec3(kInfinity), hi = vec3(-kInfinity);
  double area = 0.0;
  glm::dvec3 normal_sum = glm::dvec3(0.0);  // sum of area * unit normal, by winding
  double power = 0.0;             // emitted flux, from the materials' emission factors
};

// The mean linear luminance of a texture's texels (an emissive map scales the emission factor).
double mean_luminance(const TextureImage& t) {
  if (t.rgba8.empty()) return 1.0;
  double sum = 0.0;
  for (size_t i = 0; i + 3 < t.rgba8.size(); i += 4) {
    vec3 c(t.rgba8[i] / 255.0f, t.rgba8[i + 1] / 255.0f, t.rgba8[i + 2] / 255.0f);
    if (t.srgb) c = vec3(srgb_to_linear(c.x), srgb_to_linear(c.y), srgb_to_linear(c.z));
    sum += double(luminance(c));
  }
  return sum / double(t.rgba8.size() / 4);
}

MeshSurvey survey(const Scene& scene) {
  MeshSurvey s;
  const TriangleMesh& mesh = scene.mesh;
  std::vector<double> emission(scene.materials.size(), 0.0);  // per material, per unit area
  for (size_t i = 0; i < scene.materials.size(); ++i) {
    const Material& m = scene.materials[i].material;
    emission[i] = kPi * double(luminance(m.emission)) *
                  ((m.flags & kMaterialTwoSidedEmission) ? 2.0 : 1.0);
    if (emission[i] > 0.0 && m.emissive_tex < scene.textures.size())
      emission[i] *= mean_luminance(scene.textures[m.emissive_tex]);
  }
  // Triangle t of `m`, placed by `xform`; instanced meshes never emit.
  auto add = [&](const TriangleMesh& m, size_t t, const mat4& xform, bool emits) {
    const uvec3 tri = m.indices[t];
    if (tri.x >= m.positions.size() || tri.y >= m.positions.size() || tri.z >= m.positions.size())
      return;  // validate_scene reports it
    const vec3 p0 = vec3(xform * vec4(m.positions[tri.x], 1.0f));
    const vec3 p1 = vec3(xform * vec4(m.positions[tri.y], 1.0f));
    const vec3 p2 = vec3(xform * vec4(m.positions[tri.z], 1.0f));
    if (!is_finite(p0) || !is_finite(p1) || !is_finite(p2)) return;
    s.lo = glm::min(s.lo, glm::min(p0, glm::min(p1, p2)));
    s.hi = glm::max(s.hi, glm::max(p0, glm::max(p1, p2)));
    const glm::dvec3 c = 0.5 * glm::cross(glm::dvec3(p1 - p0), glm::dvec3(p2 - p0));
    const double a = glm::length(c);
    if (!(a > 0.0) || !std::isfinite(a)) return;
    s.area += a;
    s.normal_sum += c;
    if (emits && m.materials[t] < emission.size()) s.power += a * emission[m.materials[t]];
  };
  for (size_t t = 0; t < mesh.indices.size(); ++t) add(mesh, t, mat4(1.0f), true);
  for (const MeshInstance& inst : scene.instances) {
    if (inst.mesh >= scene.instanced_meshes.size()) continue;
    const TriangleMesh& m = scene.instanced_meshes[inst.mesh].mesh;
    for (size_t t = 0; t < m.indices.size(); ++t) add(m, t, inst.world_from_object, false);
  }
  return s;
}

// A unit vector at `deg` degrees from `axis`, tilted towards `towards` (or any perpendicular).
vec3 tilt(vec3 axis, vec3 towards, float deg) {
  vec3 t = towards - glm::dot(towards, axis) * axis;
  if (glm::length(t) < 1e-3f) t = std::abs(axis.y) < 0.9f ? vec3(0, 1, 0) : vec3(1, 0, 0);
  t = glm::normalize(t - glm::dot(t, axis) * axis);
  const float r = glm::radians(deg);
  return glm::normalize(std::cos(r) * axis + std::sin(r) * t);
}

}  // namespace

void frame_mesh_scene(Scene& scene, bool keep_camera) {
  const MeshSurvey s = survey(scene);
  if (!(s.lo.x <= s.hi.x)) return;  // nothing to frame; validate_scene reports the empty scene
  const vec3 centre = 0.5f * (s.lo + s.hi);
  const float radius = std::max(0.5f * glm::length(s.hi - s.lo), 1e-3f);
  const SourceLoc file{scene.source, 0};

  // The view direction (from the model towards the camera). A model viewer's default: a
  // three-quarter view from above the front (+z is the front in glTF, and by convention in OBJ),
  // which shows three sides of a closed model. When the surface is open to one side (its
  // area-weighted normals do not cancel: a room without its front wall, a single plane, an
  // edge-on polygon), the faces point to where the model is meant to be seen from, so the camera
  // looks from that side instead, 20 degrees off the axis so that depth still shows.
  const vec3 three_quarter = glm::normalize(vec3(std::sin(glm::radians(35.0f)), std::tan(glm::radians(25.0f)), std::cos(glm::radians(35.0f))));
  vec3 view = three_quarter;
  std::string why = "no camera in the file: a three-quarter view from above the front (+z)";
  const double openness = s.area > 0.0 ? glm::length(s.normal_sum) / s.area : 0.0;
  if (openness > 0.1) {
    const vec3 facing = vec3(glm::normalize(s.normal_sum));
    view = tilt(facing, three_quarter, 20.0f);
    why = "no camera in the file; " + fmt(float(100.0 * openness)) +
          "% of the surface's area-weighted normals point to " + vec3_str(facing) +
          " (an open or one-sided model), so the camera looks from that side";
  }
  if (keep_camera) {
    view = glm::normalize(scene.camera.position - centre);
    if (!is_finite(view)) view = three_quarter;
  }
  // World up, unless the view looks (nearly) straight down or up.
  const vec3 up = std::abs(view.y) > 0.98f ? vec3(0.0f, 0.0f, view.y > 0.0f ? -1.0f : 1.0f)
                                           : vec3(0.0f, 1.0f, 0.0f);
  if (!keep_camera) {
    // Fit the bounding sphere into the narrower of the two fields of view, with a margin.
    scene.camera = CameraDesc();
    scene.camera.vfov_deg = 40.0f;
    const float aspect = float(scene.settings.width) / float(std::max(scene.settings.height, 1));
    float half = glm::radians(0.5f * scene.camera.vfov_deg);
    if (aspect < 1.0f) half = std::atan(aspect * std::tan(half));
    const float dist = 1.1f * radius / std::sin(half);
    scene.camera.look_at = centre;
    scene.camera.position = centre + dist * view;
    scene.camera.up = up;
    scene.diagnostics.note(file, why + "; camera at " + vec3_str(scene.camera.position) +
                                     " looking at " + vec3_str(centre) +
                                     " (the bounding sphere, radius " + fmt(radius) +
                                     ", fills the " + fmt(scene.camera.vfov_deg) +
                                     " degree field of view)");
  }

  // The default light is as strong as a 2r x 2r square of radiance 7 at 3r: it lights the model
  // with an irradiance near 3, so white diffuse surfaces show up near 0.8 before tone mapping.
  // The file's own emitters replace it unless their power is under 2% of it (a few tiny
  // emissive labels must not leave the model in the dark).
  const float side = 2.0f * radius, light_radiance = 7.0f;
  const double default_power = kPi * double(light_radiance) * double(side) * double(side);
  if (s.power > 0.02 * default_power) return;
  Material light;
  light.albedo = vec3(0.0f);
  light.emission = vec3(light_radiance);
  const uint32_t mat = scene.add_material("default light", light);
  // Above and to the left of the camera as the camera sees it, facing the model's centre; outside
  // the field of view.
  const vec3 right = glm::normalize(glm::cross(-view, up));
  const vec3 cam_up = glm::cross(right, -view);
  const vec3 dir = glm::normalize(view + 0.8f * cam_up - 0.5f * right);
  const vec3 at = centre + 3.0f * radius * dir;
  const vec3 a = glm::normalize(glm::cross(dir, cam_up)), b = glm::cross(a, dir);
  MeshPart quad;
  // cross(a, b) = cross(a, cross(a, dir)) = -dir: the front faces the model.
  quad.positions = {at - radius * a - radius * b, at + radius * a - radius * b,
                    at + radius * a + radius * b, at - radius * a + radius * b};
  quad.indices = {uvec3(0, 1, 2), uvec3(0, 2, 3)};
  quad.materials = {mat, mat};
  ObjectInfo info;
  info.name = "default light";
  info.kind = "quad";
  info.first = append_part(scene, quad, mat4(1.0f));
  info.count = 2;
  info.loc = file;
  scene.objects.push_back(info);
  if (s.power > 0.0) {
    scene.diagnostics.note(
        file, "the file's emitters give " + fmt(float(100.0 * s.power / default_power)) +
                  "% of the power of a light for a model of this size (under 2%); added a default area "
                  "light above and left of the camera");
  } else {
    scene.diagnostics.note(file, "no light in the file; added a default area light above and left of the camera");
  }
}

}  // namespace tracer

namespace tracer {
namespace {

// Value noise on the integer lattice: a hash of the corner, smoothly interpolated.
float lattice(int32_t x, int32_t z, uint32_t seed) {
  uint32_t h = uint32_t(x) * 0x8da6b343u ^ uint32_t(z) * 0xd8163841u ^ seed * 0xcb1ab31fu;
  h ^= h >> 16;
  h *= 0x7feb352du;
  h ^= h >> 15;
  h *= 0x846ca68bu;
  h ^= h >> 16;
  return float(h >> 8) * (1.0f / 16777216.0f) * 2.0f - 1.0f;
}

float value_noise(float x, float z, uint32_t seed) {
  const float fx = std::floor(x), fz = std::floor(z);
  const int32_t ix = int32_t(fx), iz = int32_t(fz);
  const float tx = x - fx, tz = z - fz;
  const float sx = tx * tx * (3.0f - 2.0f * tx), sz = tz * tz * (3.0f - 2.0f * tz);
  const float a = lattice(ix, iz, seed), b = lattice(ix + 1, iz, seed);
  const float c = lattice(ix, iz + 1, seed), d = lattice(ix + 1, iz + 1, seed);
  return (a + (b - a) * sx) + ((c + (d - c) * sx) - (a + (b - a) * sx)) * sz;
}

}  // namespace

MeshPart terrain_mesh(vec2 size, uint32_t resolution, float height, uint32_t seed) {
  MeshPart m;
  const uint32_t n = resolution + 1;  // vertices per side
  m.positions.resize(size_t(n) * n);
  for (uint32_t j = 0; j < n; ++j)
    for (uint32_t i = 0; i < n; ++i) {
      const float u = float(i) / float(resolution), v = float(j) / float(resolution);
      // Six octaves from 4 to 128 features across, each half as high as the one before.
      float y = 0.0f, amp = 0.5f, freq = 4.0f;
      for (int o = 0; o < 6; ++o) {
        y += amp * value_noise(u * freq, v * freq, seed + uint32_t(o));
        amp *= 0.5f;
        freq *= 2.0f;
      }
      m.positions[size_t(j) * n + i] = vec3(u * size.x, height * y, v * size.y);
    }
  m.indices.reserve(size_t(2) * resolution * resolution);
  for (uint32_t j = 0; j < resolution; ++j)
    for (uint32_t i = 0; i < resolution; ++i) {
      const uint32_t a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      // Counter-clockwise seen from +y, so the geometric normal points up.
      m.indices.push_back(uvec3(a, c, b));
      m.indices.push_back(uvec3(b, c, d));
    }
  // Smooth normals from the grid's central differences.
  m.normals.resize(m.positions.size());
  for (uint32_t j = 0; j < n; ++j)
    for (uint32_t i = 0; i < n; ++i) {
      const vec3& l = m.positions[size_t(j) * n + (i > 0 ? i - 1 : i)];
      const vec3& r = m.positions[size_t(j) * n + (i < resolution ? i + 1 : i)];
      const vec3& dn = m.positions[size_t(j > 0 ? j - 1 : j) * n + i];
      const vec3& up = m.positions[size_t(j < resolution ? j + 1 : j) * n + i];
      m.normals[size_t(j) * n + i] = glm::normalize(glm::cross(up - dn, r - l));
    }
  return m;
}

}  // namespace tracer
