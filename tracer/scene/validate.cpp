// validate_scene: the last gate between any loader (or the UI) and the renderer. Repairs what has
// an obvious repair (degenerate triangles, zero normals, albedo out of range) with a warning and
// rejects the rest, so that the backends may assume finite, in-range data.
#include <unistd.h>

#include <cmath>
#include <limits>
#include <sstream>

#include "core/math.h"
#include "scene/loader.h"
#include "scene/loader_util.h"

namespace tracer {

namespace {

// validate_scene may run again after the front end changes settings; do not repeat a warning.
void warn_once(Scene& scene, const SourceLoc& loc, const std::string& problem,
               const std::string& action) {
  const std::string text = loc.str() + ": " + problem + "; " + action;
  for (const std::string& w : scene.diagnostics.warnings)
    if (w == text) return;
  scene.diagnostics.warn(loc, problem, action);
}

// The object that owns triangle t, for messages; objects are appended in triangle order.
const ObjectInfo* owner_of(const Scene& scene, uint32_t t) {
  for (const ObjectInfo& o : scene.objects)
    if (o.is_triangles() && t >= o.first && t - o.first < o.count) return &o;
  return nullptr;
}

SourceLoc where(const Scene& scene, const ObjectInfo* o) {
  return o ? o->loc : SourceLoc{scene.source, 0};
}

std::string object_name(const ObjectInfo* o, const char* unnamed = "an unnamed triangle") {
  return o ? "object \"" + o->name + "\"" : unnamed;
}

void validate_camera_and_settings(const Scene& scene) {
  const SourceLoc loc{scene.source, 0};
  // Whatever made the scene (a loader, a glTF camera, an API caller), its settings pass the
  // settings table's checks, with the table's messages.
  const std::string problem = check_settings(scene);
  if (!problem.empty()) throw InputError(loc, problem);
  const RenderSettings& s = scene.settings;
  // Film, variance and display buffers together take about 64 bytes a pixel.
  const double bytes = double(s.width) * double(s.height) * 64.0;
  const double memory = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGESIZE));
  if (memory > 0.0 && bytes > 0.5 * memory) {
    std::ostringstream gib;
    gib.precision(3);
    gib << bytes / double(1ull << 30);
    throw InputError(loc, "image of " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                              " needs " + gib.str() +
                              " GiB, more than this machine's memory allows");
  }
}

void validate_textures(const Scene& scene) {
  uint64_t total = 0;
  for (const TextureImage& t : scene.textures) {
    const SourceLoc loc{t.source.empty() ? scene.source : t.source, 0};
    if (t.width <= 0 || t.height <= 0 || t.width > 16384 || t.height > 16384 ||
        t.rgba8.size() != size_t(t.width) * size_t(t.height) * 4)
      throw InputError(loc, "texture is " + std::to_string(t.width) + "x" +
                                std::to_string(t.height) + " with " +
                                std::to_string(t.rgba8.size()) +
                                " bytes; expected 1..16384 texels a side, RGBA8");
    total += uint64_t(t.width) * uint64_t(t.height);
  }
  if (total >= uint64_t(kInvalid))
    throw InputError({scene.source, 0}, "textures hold more than 2^32 texels in all");
}

void validate_materials(Scene& scene) {
  const SourceLoc loc{scene.source, 0};
  validate_textures(scene);
  for (NamedMaterial& nm : scene.materials) {
    Material& m = nm.material;
    const std::string name = "material \"" + nm.name + "\"";
    if (uint32_t(m.type) >= uint32_t(kMaterialTypeCount))
      throw InputError(loc, name + " has an unknown type");
    if (!is_finite(m.albedo) || !is_finite(m.emission) || !is_finite(m.absorption) ||
        !is_finite(m.ior))
      throw InputError(loc, name + " has a non-finite parameter");
    const vec3 clamped = glm::clamp(m.albedo, vec3(0.0f), vec3(1.0f));
    if (clamped != m.albedo) {
      warn_once(scene, loc, name + " has albedo " + vec3_str(m.albedo) + " outside [0, 1]",
                "clamped to " + vec3_str(clamped));
      m.albedo = clamped;
    }
    if (glm::any(glm::lessThan(m.emission, vec3(0.0f))))
      throw InputError(loc, name + " has negative emission");
    if (glm::any(glm::lessThan(m.absorption, vec3(0.0f))))
      throw InputError(loc, name + " has negative absorption");
    for (uint32_t tex : {m.base_color_tex, m.metal_rough_tex, m.emissive_tex, m.normal_tex}) {
      if (tex != kInvalid && tex >= scene.textures.size())
        throw InputError(loc, name + " refers to texture " + std::to_string(tex) +
                                  ", but the scene has " + std::to_string(scene.textures.size()));
    }
    if (!std::isfinite(m.metallic) || !std::isfinite(m.normal_scale))
      throw InputError(loc, name + " has a non-finite metallic factor or normal scale");
    if (m.type == MaterialType::kDielectric && !(m.ior > 1.0f && m.ior <= 4.0f))
      throw InputError(loc, name + " has ior " + std::to_string(m.ior) + ", outside (1, 4]");
    if (m.type == MaterialType::kCoatedDiffuse &&
        !(m.ior >= 1.0f && m.ior <= 4.0f && m.thickness >= 0.0f && std::isfinite(m.thickness)))
      throw InputError(loc, name + " has a coat of ior " + std::to_string(m.ior) +
                                " (expected [1, 4]) or thickness " + std::to_string(m.thickness) +
                                " (expected >= 0)");
    if (m.type == MaterialType::kConductor && (m.flags & kMaterialConductorIor) &&
        !(is_finite(m.eta) && is_finite(m.k) && glm::all(glm::greaterThan(m.eta, vec3(0.0f))) &&
          glm::all(glm::greaterThanEqual(m.k, vec3(0.0f)))))
      throw InputError(loc, name + " has a complex index of refraction with eta " +
                                vec3_str(m.eta) + " (expected > 0) and k " + vec3_str(m.k) +
                                " (expected >= 0)");
    if (m.type == MaterialType::kConductor && !(m.roughness_v <= 1.0f))
      throw InputError(
          loc, name + " has roughness v " + std::to_string(m.roughness_v) + ", outside [0, 1]");
    if (m.type == MaterialType::kDiffuseTransmission) {
      if (!is_finite(m.transmittance) || glm::any(glm::lessThan(m.transmittance, vec3(0.0f))))
        throw InputError(
            loc, name + " has transmittance " + vec3_str(m.transmittance) + " (expected >= 0)");
      const float sum = max_component(m.albedo + m.transmittance);
      if (sum > 1.0f) {
        warn_once(scene, loc,
                  name +
                      " reflects and transmits more than it receives (albedo + transmittance "
                      "= " +
                      vec3_str(m.albedo + m.transmittance) + ")",
                  "scaled both by " + std::to_string(1.0f / sum));
        m.albedo /= sum;
        m.transmittance /= sum;
      }
    }
  }
}

// How far from the origin geometry and the camera may reach. Every ray starts at the camera or on
// a surface, so with everything within E of the origin each coordinate difference p - o of the
// watertight triangle test (bvh/geometry.h) is within 2E, the sheared differences within 4E
// (|sx|, |sy| <= 1), the edge functions U, V, W within 2 (4E)^2 = 32 E^2, and
// T = U az + V bz + W cz within 3 * 32 E^2 * 2 sqrt(3) E < 333 E^3 (|sz| <= sqrt(3): a unit
// direction's largest component is at least 1 / sqrt(3)). T must stay below the float maximum
// 3.4e38, hence E <= 1e12; past it hits are lost (inf) and the ray offset of 256 ulps overflows
// into NaN near 3.4e38. Squared distances (light sampling: at most 12 E^2) stay far in range.
constexpr double kMaxReach = 1e12;

std::string number_str(double x) {
  std::ostringstream out;
  out.precision(3);
  out << x;
  return out.str();
}

void check_reach(const SourceLoc& loc, const std::string& what, double reach) {
  if (reach <= kMaxReach) return;
  throw InputError(loc, what + " reaches " + number_str(reach) +
                            " from the origin, beyond the supported " + number_str(kMaxReach) +
                            " (the ray-triangle test multiplies three coordinate differences, "
                            "which would overflow a float); scale the scene down");
}

double reach_of(vec3 p) {
  return std::max(std::fabs(double(p.x)), std::max(std::fabs(double(p.y)), std::fabs(double(p.z))));
}

// Returns the number of zero-area triangles removed.
size_t validate_geometry(Scene& scene) {
  size_t removed = 0;
  TriangleMesh& mesh = scene.mesh;
  const size_t nmat = scene.materials.size();
  for (size_t i = 0; i < scene.spheres.size(); ++i) {
    const SphereDesc& s = scene.spheres[i];
    const ObjectInfo* o = nullptr;
    for (const ObjectInfo& info : scene.objects)
      if (info.is_sphere && info.first == i) o = &info;
    if (!is_finite(s.center) || !is_finite(s.radius) || !(s.radius > 0.0f))
      throw InputError(where(scene, o), "sphere " + object_name(o) +
                                            " has a non-finite centre or a radius that is not > 0");
    if (s.material >= nmat)
      throw InputError(where(scene, o), object_name(o) + " has material index " +
                                            std::to_string(s.material) + " out of range");
    check_reach(where(scene, o), object_name(o, "an unnamed sphere"),
                reach_of(s.center) + double(s.radius));
  }
  if (mesh.materials.size() != mesh.indices.size())
    throw InputError({scene.source, 0}, "triangle mesh has " + std::to_string(mesh.indices.size()) +
                                            " triangles but " +
                                            std::to_string(mesh.materials.size()) +
                                            " material ids");
  if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
    throw InputError({scene.source, 0},
                     "triangle mesh has " + std::to_string(mesh.positions.size()) +
                         " positions but " + std::to_string(mesh.normals.size()) + " normals");
  if (!mesh.uvs.empty() && mesh.uvs.size() != mesh.positions.size())
    throw InputError({scene.source, 0}, "triangle mesh has " +
                                            std::to_string(mesh.positions.size()) +
                                            " positions but " + std::to_string(mesh.uvs.size()) +
                                            " texture coordinates");
  for (const vec2& uv : mesh.uvs)
    if (!std::isfinite(uv.x) || !std::isfinite(uv.y))
      throw InputError({scene.source, 0}, "triangle mesh has a non-finite texture coordinate");
  if (mesh.indices.size() >= size_t(kInvalid))
    throw InputError({scene.source, 0}, "too many triangles for 32-bit indices");

  const size_t nv = mesh.positions.size();
  std::vector<uint8_t> zero_normal_objects(scene.objects.size(), 0);
  for (uint32_t t = 0; t < mesh.indices.size(); ++t) {
    const uvec3 tri = mesh.indices[t];
    if (tri.x >= nv || tri.y >= nv || tri.z >= nv) {
      const ObjectInfo* o = owner_of(scene, t);
      throw InputError(where(scene, o), object_name(o) + " has a vertex index out of range");
    }
    if (mesh.materials[t] >= nmat) {
      const ObjectInfo* o = owner_of(scene, t);
      throw InputError(where(scene, o), object_name(o) + " has a material index out of range");
    }
    for (int k = 0; k < 3; ++k) {
      if (!is_finite(mesh.positions[tri[k]])) {
        const ObjectInfo* o = owner_of(scene, t);
        throw InputError(where(scene, o), object_name(o) + " has a non-finite vertex position " +
                                              vec3_str(mesh.positions[tri[k]]));
      }
      if (reach_of(mesh.positions[tri[k]]) > kMaxReach) {
        const ObjectInfo* o = owner_of(scene, t);
        check_reach(where(scene, o), object_name(o), reach_of(mesh.positions[tri[k]]));
      }
      if (mesh.normals.empty()) continue;
      vec3& n = mesh.normals[tri[k]];
      if (!is_finite(n)) {
        const ObjectInfo* o = owner_of(scene, t);
        throw InputError(where(scene, o), object_name(o) + " has a non-finite vertex normal");
      }
      const float len = glm::length(n);
      if (len == 0.0f) {
        const ObjectInfo* o = owner_of(scene, t);
        if (o) zero_normal_objects[size_t(o - scene.objects.data())] = 1;
      } else {
        n /= len;
      }
    }
  }
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    if (!zero_normal_objects[i]) continue;
    const ObjectInfo& o = scene.objects[i];
    set_flat_normals(mesh, o.first, o.count);
    warn_once(scene, o.loc, "object \"" + o.name + "\" has zero-length vertex normals",
              "dropped its normals (flat shading)");
  }

  // Remove zero-area triangles (is_zero_area_triangle says why).
  std::vector<uint32_t> kept_before(mesh.indices.size() + 1, 0);
  size_t out = 0;
  for (size_t t = 0; t < mesh.indices.size(); ++t) {
    kept_before[t] = uint32_t(out);
    const uvec3 tri = mesh.indices[t];
    if (is_zero_area_triangle(mesh, tri)) continue;
    mesh.indices[out] = tri;
    mesh.materials[out] = mesh.materials[t];
    ++out;
  }
  kept_before[mesh.indices.size()] = uint32_t(out);
  removed = mesh.indices.size() - out;
  if (out != mesh.indices.size()) {
    for (ObjectInfo& o : scene.objects) {
      if (!o.is_triangles()) continue;
      const uint32_t first = kept_before[o.first], last = kept_before[o.first + o.count];
      if (last == first && o.count > 0) {
        warn_once(scene, o.loc,
                  (o.count == 1 ? std::string("the only triangle of object \"") + o.name + "\" has"
                                : "all " + std::to_string(o.count) + " triangles of object \"" +
                                      o.name + "\" have") +
                      " zero area",
                  "removed the object");
      } else if (last - first != o.count) {
        warn_once(scene, o.loc,
                  "object \"" + o.name + "\" has " + std::to_string(o.count - (last - first)) +
                      " zero-area triangle(s)",
                  "removed them");
      }
      o.first = first;
      o.count = last - first;
    }
    mesh.indices.resize(out);
    mesh.materials.resize(out);
  }
  return removed;
}

// The object that places instance i, for messages.
const ObjectInfo* owner_of_instance(const Scene& scene, size_t i) {
  for (const ObjectInfo& o : scene.objects)
    if (o.is_instances && i >= o.first && i - o.first < o.count) return &o;
  return nullptr;
}

// The first object that places instanced mesh m, for messages.
const ObjectInfo* owner_of_instanced_mesh(const Scene& scene, uint32_t m) {
  for (size_t i = 0; i < scene.instances.size(); ++i)
    if (scene.instances[i].mesh == m) return owner_of_instance(scene, i);
  return nullptr;
}

// The object-space bounds of an instanced mesh's triangles.
void instanced_bounds(const TriangleMesh& mesh, vec3* lo, vec3* hi) {
  *lo = vec3(std::numeric_limits<float>::max());
  *hi = -*lo;
  for (const uvec3& tri : mesh.indices)
    for (int k = 0; k < 3; ++k) {
      *lo = glm::min(*lo, mesh.positions[tri[k]]);
      *hi = glm::max(*hi, mesh.positions[tri[k]]);
    }
}

// The world-space corners of instance `inst`'s bounds, given its mesh's object-space bounds.
template <typename F>
void for_each_corner(const MeshInstance& inst, vec3 lo, vec3 hi, F&& f) {
  for (int c = 0; c < 8; ++c) {
    const vec3 p((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
    f(glm::dvec3(glm::dmat4(inst.world_from_object) * glm::dvec4(p, 1.0)));
  }
}

// Instanced meshes (the same checks as the scene's mesh, plus: no emissive material, which must
// be world-space triangles) and their instances (a mesh that exists, a finite invertible affine
// transform). Zero-area triangles are removed; a mesh left without triangles loses its instances.
void validate_instances(Scene& scene) {
  const size_t nmat = scene.materials.size();
  std::vector<uint8_t> empty(scene.instanced_meshes.size(), 0);
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const MeshInstance& inst = scene.instances[i];
    const ObjectInfo* o = owner_of_instance(scene, i);
    if (inst.mesh >= scene.instanced_meshes.size())
      throw InputError(where(scene, o), object_name(o, "an unnamed instance") +
                                            " places instanced mesh " + std::to_string(inst.mesh) +
                                            ", but the scene has " +
                                            std::to_string(scene.instanced_meshes.size()));
    const std::string problem = instance_transform_problem(inst.world_from_object);
    if (!problem.empty())
      throw InputError(where(scene, o), "the transform of instance " + std::to_string(i) + " (" +
                                            object_name(o, "an unnamed object") + ") " + problem);
  }
  for (uint32_t m = 0; m < scene.instanced_meshes.size(); ++m) {
    TriangleMesh& mesh = scene.instanced_meshes[m].mesh;
    const ObjectInfo* o = owner_of_instanced_mesh(scene, m);
    const SourceLoc loc = where(scene, o);
    const std::string name =
        o ? object_name(o) : "instanced mesh \"" + scene.instanced_meshes[m].name + "\"";
    const size_t nv = mesh.positions.size();
    if (mesh.materials.size() != mesh.indices.size() ||
        (!mesh.normals.empty() && mesh.normals.size() != nv) ||
        (!mesh.uvs.empty() && mesh.uvs.size() != nv))
      throw InputError(loc, name + " has " + std::to_string(mesh.indices.size()) + " triangles, " +
                                std::to_string(mesh.materials.size()) + " material ids, " +
                                std::to_string(nv) + " positions, " +
                                std::to_string(mesh.normals.size()) + " normals and " +
                                std::to_string(mesh.uvs.size()) +
                                " texture coordinates (expected one material per triangle and "
                                "normals and texture coordinates empty or one per position)");
    for (const vec3& p : mesh.positions)
      if (!is_finite(p))
        throw InputError(loc, name + " has a non-finite vertex position " + vec3_str(p));
    for (const vec2& uv : mesh.uvs)
      if (!std::isfinite(uv.x) || !std::isfinite(uv.y))
        throw InputError(loc, name + " has a non-finite texture coordinate");
    bool zero_normal = false;
    for (vec3& n : mesh.normals) {
      if (!is_finite(n)) throw InputError(loc, name + " has a non-finite vertex normal");
      const float len = glm::length(n);
      zero_normal |= len == 0.0f;
      if (len > 0.0f) n /= len;
    }
    if (zero_normal) {
      // Without normals the renderer shades the mesh flat, as set_flat_normals would.
      mesh.normals.clear();
      warn_once(scene, loc, name + " has zero-length vertex normals",
                "dropped its normals (flat shading)");
    }
    size_t out = 0;
    for (size_t t = 0; t < mesh.indices.size(); ++t) {
      const uvec3 tri = mesh.indices[t];
      if (tri.x >= nv || tri.y >= nv || tri.z >= nv)
        throw InputError(loc, name + " has a vertex index out of range");
      const uint32_t mat = mesh.materials[t];
      if (mat >= nmat)
        throw InputError(loc, name + " has material index " + std::to_string(mat) +
                                  " out of range (the scene has " + std::to_string(nmat) + ")");
      if (scene.materials[mat].material.is_emissive())
        throw InputError(loc, name + " is instanced but its material \"" +
                                  scene.materials[mat].name +
                                  "\" emits light; emitters must be world-space triangles "
                                  "(flatten_instances, as the loaders do for emissive meshes)");
      if (is_zero_area_triangle(mesh, tri)) continue;
      mesh.indices[out] = tri;
      mesh.materials[out] = mat;
      ++out;
    }
    if (out != mesh.indices.size()) {
      warn_once(scene, loc,
                name + " has " + std::to_string(mesh.indices.size() - out) +
                    " zero-area triangle(s)" + (out == 0 ? " and no others" : ""),
                out == 0 ? "removed its instances" : "removed them");
      mesh.indices.resize(out);
      mesh.materials.resize(out);
    }
    empty[m] = mesh.indices.empty();
  }
  // Drop the instances of meshes without triangles; objects keep their ranges of the rest.
  std::vector<uint32_t> kept_before(scene.instances.size() + 1, 0);
  size_t out = 0;
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    kept_before[i] = uint32_t(out);
    if (!empty[scene.instances[i].mesh]) scene.instances[out++] = scene.instances[i];
  }
  kept_before[scene.instances.size()] = uint32_t(out);
  if (out != scene.instances.size()) {
    for (ObjectInfo& o : scene.objects) {
      if (!o.is_instances) continue;
      const size_t end = std::min(size_t(o.first) + o.count, scene.instances.size());
      const uint32_t first = kept_before[std::min(size_t(o.first), scene.instances.size())];
      o.count = kept_before[end] - first;
      o.first = first;
    }
    scene.instances.resize(out);
  }
  // Primitive ids (triangles of the scene's mesh, instanced triangles, spheres) are signed 32-bit
  // in places; the renderer numbers them together.
  const uint64_t total =
      scene.instanced_triangle_count() + scene.mesh.indices.size() + scene.spheres.size();
  if (total >= (uint64_t(1) << 31))
    throw InputError({scene.source, 0},
                     "the scene has " + std::to_string(total) + " primitives (" +
                         std::to_string(scene.instanced_triangle_count()) +
                         " instanced triangles, " + std::to_string(scene.mesh.indices.size()) +
                         " other triangles and " + std::to_string(scene.spheres.size()) +
                         " spheres), more than the limit of 2^31 - 1 = 2147483647");
  // Reach, by the corners of each instance's bounds.
  std::vector<std::pair<vec3, vec3>> bounds(scene.instanced_meshes.size());
  for (size_t m = 0; m < bounds.size(); ++m)
    instanced_bounds(scene.instanced_meshes[m].mesh, &bounds[m].first, &bounds[m].second);
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const auto& [lo, hi] = bounds[scene.instances[i].mesh];
    double reach = 0.0;
    for_each_corner(scene.instances[i], lo, hi, [&](glm::dvec3 p) {
      reach = std::max(reach, std::max(std::fabs(p.x), std::max(std::fabs(p.y), std::fabs(p.z))));
    });
    if (reach > kMaxReach) {
      const ObjectInfo* o = owner_of_instance(scene, i);
      check_reach(where(scene, o), object_name(o, "an unnamed instance"), reach);
    }
  }
}

// The camera's reach, and the scene's span against the ray offset. offset_ray_origin moves a
// spawned ray's origin by a fixed 2^-16 near the origin and by 256 ulps elsewhere; a scene not
// much larger than that offset is skipped over by its own rays (the Cornell box scaled by 1e-8
// renders black). Require the span of geometry and camera to be at least 64 offsets (the offset at
// most 1.6% of it), the offset taken at the scene's reach: a scene far from the origin needs to be
// larger, a tiny one must sit near the origin.
void validate_extent(const Scene& scene) {
  const CameraDesc& cam = scene.camera;
  const double lens = double(cam.aperture_radius);
  check_reach({scene.source, 0}, "the camera", reach_of(cam.position) + lens);
  glm::dvec3 lo(cam.position), hi(cam.position);
  lo -= lens;
  hi += lens;
  for (const SphereDesc& s : scene.spheres) {
    lo = glm::min(lo, glm::dvec3(s.center) - double(s.radius));
    hi = glm::max(hi, glm::dvec3(s.center) + double(s.radius));
  }
  for (const uvec3& tri : scene.mesh.indices) {
    for (int k = 0; k < 3; ++k) {
      lo = glm::min(lo, glm::dvec3(scene.mesh.positions[tri[k]]));
      hi = glm::max(hi, glm::dvec3(scene.mesh.positions[tri[k]]));
    }
  }
  std::vector<std::pair<vec3, vec3>> bounds(scene.instanced_meshes.size());
  for (size_t m = 0; m < bounds.size(); ++m)
    instanced_bounds(scene.instanced_meshes[m].mesh, &bounds[m].first, &bounds[m].second);
  for (const MeshInstance& inst : scene.instances) {
    for_each_corner(inst, bounds[inst.mesh].first, bounds[inst.mesh].second, [&](glm::dvec3 p) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    });
  }
  const glm::dvec3 size = hi - lo;
  const double span = std::max(size.x, std::max(size.y, size.z));
  const double reach = std::max(std::max(std::fabs(lo.x), std::fabs(hi.x)),
                                std::max(std::max(std::fabs(lo.y), std::fabs(hi.y)),
                                         std::max(std::fabs(lo.z), std::fabs(hi.z))));
  const float at = float(reach);
  const double offset = double(offset_ray_origin(vec3(at), vec3(1.0f, 0.0f, 0.0f)).x) - double(at);
  if (span < 64.0 * offset) {
    throw InputError({scene.source, 0},
                     "the scene (geometry and camera) spans " + number_str(span) +
                         ", less than the supported 64 ray offsets (" + number_str(64.0 * offset) +
                         "): at " + number_str(reach) +
                         " from the origin a ray leaving a surface starts " + number_str(offset) +
                         " from it and would skip the scene's surfaces; scale the scene up" +
                         (reach >= 1.0 / 32.0 ? " or move it nearer the origin" : ""));
  }
}

}  // namespace

// Zero-area triangles can never be hit reliably and make light sampling divide by a zero area.
// Measured in double, relative to the longest edge, so tiny but valid triangles of a small-scale
// model survive.
bool is_zero_area_triangle(const TriangleMesh& mesh, uvec3 tri) {
  const size_t nv = mesh.positions.size();
  if (tri.x >= nv || tri.y >= nv || tri.z >= nv) return false;  // validate_scene reports these
  const glm::dvec3 p0(mesh.positions[tri.x]), p1(mesh.positions[tri.y]), p2(mesh.positions[tri.z]);
  const glm::dvec3 e1 = p1 - p0, e2 = p2 - p0, e3 = p2 - p1;
  const double longest = std::max(glm::dot(e1, e1), std::max(glm::dot(e2, e2), glm::dot(e3, e3)));
  const double area2 = glm::length(glm::cross(e1, e2));
  return area2 <= 1e-12 * longest || longest == 0.0;
}

void validate_scene(Scene& scene) {
  // Geometry before the camera: a mesh's framing camera derives from its bounds, and a mesh out
  // of range should be named as the cause rather than the camera placed beyond it.
  validate_materials(scene);
  const size_t removed = validate_geometry(scene);
  validate_instances(scene);
  if (scene.spheres.empty() && scene.mesh.indices.empty() && scene.instances.empty()) {
    // As for a mesh file of only degenerate triangles (load_scene): an error, like an empty scene.
    if (removed > 0) {
      std::string names;
      size_t n = 0;
      for (const ObjectInfo& o : scene.objects) {
        if (!o.is_triangles() || o.count > 0) continue;
        if (n++ < 3) names += std::string(names.empty() ? "" : ", ") + "\"" + o.name + "\"";
      }
      if (n > 3) names += " and " + std::to_string(n - 3) + " more";
      const std::string what =
          removed == 1 ? std::string("the scene's only triangle has")
                       : "all " + std::to_string(removed) + " triangles of the scene have";
      throw InputError({scene.source, 0},
                       what + " zero area (degenerate" +
                           (n > 0 ? (n == 1 ? ": object " : ": objects ") + names : std::string()) +
                           "), and it has no other geometry");
    }
    throw InputError({scene.source, 0}, "the scene has no geometry");
  }
  validate_camera_and_settings(scene);
  validate_extent(scene);
  bool lit = false;
  for (const SphereDesc& s : scene.spheres)
    lit |= scene.materials[s.material].material.is_emissive();
  for (uint32_t m : scene.mesh.materials) lit |= scene.materials[m].material.is_emissive();
  const EnvironmentDesc& env = scene.environment;
  lit |= env.strength > 0.0f && (!env.file.empty() || max_component(env.color) > 0.0f);
  for (const DistantLightDesc& d : scene.distant_lights) lit |= max_component(d.irradiance) > 0.0f;
  for (const PointLightDesc& d : scene.point_lights) lit |= max_component(d.intensity) > 0.0f;
  if (!lit) {
    warn_once(scene, {scene.source, 0}, "scene has no light; it will render black",
              "rendering anyway");
  }
}

}  // namespace tracer
