// Wavefront OBJ + MTL meshes through tinyobjloader, with our own pre-scan so that bad vertices and
// face indices are reported with their line (tinyobjloader would read garbage or crash on them).
#include <stb_image.h>
#include <tiny_obj_loader.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <unordered_map>

#include "core/math.h"
#include "scene/loader_util.h"

namespace tracer {

namespace {

struct ObjCounts {
  long v = 0, vt = 0, vn = 0;
};

// Splits text into lines and calls fn(line_number, first_word, rest_of_line).
template <typename Fn>
void for_each_obj_line(const std::string& text, Fn fn) {
  std::istringstream in(text);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    std::istringstream ls(line);
    std::string word;
    if (!(ls >> word) || word[0] == '#') continue;
    std::string rest;
    std::getline(ls, rest);
    fn(number, word, rest);
  }
}

void check_index(long idx, long seen, long total, const char* what, const char* plural,
                 const SourceLoc& loc, const std::string& suffix) {
  if (idx == 0)
    throw InputError(loc,
                     std::string(what) + " index 0 in a face (OBJ indices start at 1)" + suffix);
  // Negative indices count back from the elements defined so far (OBJ spec); positive ones may
  // refer to any element of the file, as tinyobjloader resolves them after reading it all.
  const long resolved = idx > 0 ? idx : seen + idx + 1;
  const long limit = idx > 0 ? total : seen;
  if (resolved < 1 || resolved > limit) {
    throw InputError(loc, "face refers to " + std::string(what) + " " + std::to_string(idx) +
                              ", but " + std::to_string(limit) + " " +
                              (limit == 1 ? what : plural) + (limit == 1 ? " is" : " are") +
                              " defined" + (idx < 0 ? " before this line" : " in the file") +
                              suffix);
  }
}

// Finds what tinyobjloader does not report with a line: non-finite numbers and bad face indices.
// Returns whether every referenced mtllib exists.
bool prescan_obj(const std::string& text, const std::string& path, const std::string& suffix,
                 Diagnostics& diag) {
  ObjCounts total;
  for_each_obj_line(text, [&](int, const std::string& w, const std::string&) {
    total.v += w == "v";
    total.vt += w == "vt";
    total.vn += w == "vn";
  });
  ObjCounts seen;
  bool mtl_ok = true;
  for_each_obj_line(text, [&](int line, const std::string& w, const std::string& rest) {
    const SourceLoc loc{path, line};
    if (w == "v" || w == "vn") {
      const char* p = rest.c_str();
      for (int i = 0; i < 3; ++i) {
        char* end = nullptr;
        const double d = std::strtod(p, &end);
        if (end == p)
          throw InputError(loc, "\"" + w + "\" needs 3 numbers: \"" + w + rest + "\"" + suffix);
        if (!std::isfinite(d) || std::fabs(d) > 3.0e38)
          throw InputError(loc, (w == "v" ? "vertex" : "normal") +
                                    std::string(" has a non-finite coordinate: \"") + w + rest +
                                    "\"" + suffix);
        p = end;
      }
      (w == "v" ? seen.v : seen.vn)++;
    } else if (w == "vt") {
      ++seen.vt;
    } else if (w == "f") {
      std::istringstream ts(rest);
      std::string corner;
      int corners = 0;
      while (ts >> corner) {
        ++corners;
        long idx[3] = {0, 0, 0};
        bool present[3] = {false, false, false};
        size_t start = 0;
        for (int k = 0; k < 3 && start <= corner.size(); ++k) {
          const size_t slash = corner.find('/', start);
          const std::string part =
              corner.substr(start, slash == std::string::npos ? std::string::npos : slash - start);
          if (!part.empty()) {
            char* end = nullptr;
            idx[k] = std::strtol(part.c_str(), &end, 10);
            if (*end != '\0') throw InputError(loc, "bad face index \"" + corner + "\"" + suffix);
            present[k] = true;
          }
          if (slash == std::string::npos) break;
          start = slash + 1;
        }
        if (!present[0])
          throw InputError(loc, "face corner \"" + corner + "\" has no vertex index" + suffix);
        check_index(idx[0], seen.v, total.v, "vertex", "vertices", loc, suffix);
        if (present[1])
          check_index(idx[1], seen.vt, total.vt, "texture coordinate", "texture coordinates", loc,
                      suffix);
        if (present[2]) check_index(idx[2], seen.vn, total.vn, "normal", "normals", loc, suffix);
      }
      if (corners < 3) {
        diag.warn(loc, "face with " + std::to_string(corners) + " corners" + suffix,
                  "skipped (a face needs at least 3)");
      }
    } else if (w == "mtllib") {
      std::istringstream ms(rest);
      std::string name;
      while (ms >> name) {
        const std::string full = path_join(path_directory(path), name);
        if (!file_exists(full)) {
          diag.warn(loc, "material library \"" + name + "\" not found" + suffix,
                    "its materials are grey diffuse");
          mtl_ok = false;
        }
      }
    }
  });
  return mtl_ok;
}

Material convert_mtl(const tinyobj::material_t& m, const std::string& path, Diagnostics& diag) {
  Material out;
  const SourceLoc loc{path, 0};
  const vec3 kd(m.diffuse[0], m.diffuse[1], m.diffuse[2]);
  const vec3 ks(m.specular[0], m.specular[1], m.specular[2]);
  const vec3 tf(m.transmittance[0], m.transmittance[1], m.transmittance[2]);
  out.emission = glm::max(vec3(m.emission[0], m.emission[1], m.emission[2]), vec3(0.0f));
  if (m.illum == 4 || m.illum == 6 || m.illum == 7 || m.dissolve < 1.0f) {
    // Glass: illum 4/6/7 are the refraction models, and "d" < 1 means see-through.
    out.type = MaterialType::kDielectric;
    out.albedo = max_component(tf) > 0.0f ? tf : vec3(1.0f);
    out.ior = m.ior > 1.0f && m.ior <= 4.0f ? m.ior : 1.5f;
    if (m.ior != 1.0f && out.ior != m.ior) {
      diag.warn(loc,
                "material \"" + m.name + "\" has Ni " + std::to_string(m.ior) + " outside (1, 4]",
                "used 1.5");
    }
  } else if (m.illum == 3 || m.illum == 5) {
    // illum 3 and 5 are the ray-traced reflection models: a mirror tinted by Ks.
    out.type = MaterialType::kMirror;
    out.albedo = max_component(ks) > 0.0f ? ks : vec3(1.0f);
  } else {
    out.albedo = kd;
  }
  const vec3 clamped = glm::clamp(out.albedo, vec3(0.0f), vec3(1.0f));
  if (clamped != out.albedo) {
    diag.warn(
        loc, "material \"" + m.name + "\" has a colour " + vec3_str(out.albedo) + " outside [0, 1]",
        "clamped");
    out.albedo = clamped;
  }
  if (!is_finite(out.albedo) || !is_finite(out.emission)) {
    throw InputError(loc, "material \"" + m.name + "\" has a non-finite colour or emission");
  }
  return out;
}

// map_Kd: an sRGB colour map, relative to the OBJ's folder (where tinyobjloader finds the MTL).
// A missing or undecodable file leaves the material untextured with a warning; one larger than
// 16384 texels a side is an error. Returns the scene texture index or kInvalid.
uint32_t load_map_kd(Scene& scene, const std::string& obj_path, const tinyobj::material_t& m,
                     const std::string& suffix) {
  std::string name = m.diffuse_texname;
  if (name.empty()) return kInvalid;
  std::replace(name.begin(), name.end(), '\\', '/');
  const std::string file = path_join(path_directory(obj_path), name);
  const SourceLoc loc{obj_path, 0};
  const std::string what = "material \"" + m.name + "\" map_Kd \"" + name + "\"";
  if (!file_exists(file)) {
    scene.diagnostics.warn(loc, what + " not found" + suffix, "rendered it untextured");
    return kInvalid;
  }
  int w = 0, h = 0, comp = 0;
  if (!stbi_info(file.c_str(), &w, &h, &comp)) {
    scene.diagnostics.warn(loc, what + " cannot be decoded" + suffix, "rendered it untextured");
    return kInvalid;
  }
  if (w > 16384 || h > 16384)
    throw InputError({file, 0}, "texture is " + std::to_string(w) + "x" + std::to_string(h) +
                                    ", larger than 16384x16384" + suffix);
  unsigned char* data = stbi_load(file.c_str(), &w, &h, &comp, 4);
  if (!data) {
    scene.diagnostics.warn(loc, what + " cannot be decoded" + suffix, "rendered it untextured");
    return kInvalid;
  }
  TextureImage t;
  t.width = w;
  t.height = h;
  t.rgba8.assign(data, data + size_t(w) * size_t(h) * 4);
  stbi_image_free(data);
  t.srgb = true;
  t.source = file;
  scene.textures.push_back(std::move(t));
  return uint32_t(scene.textures.size() - 1);
}

struct CornerKey {
  int v, n, t;
  bool operator==(const CornerKey& o) const { return v == o.v && n == o.n && t == o.t; }
};
struct CornerHash {
  size_t operator()(const CornerKey& k) const {
    return std::hash<uint64_t>()((uint64_t(uint32_t(k.v)) << 32) ^
                                 (uint64_t(uint32_t(k.n)) * 0x9e3779b97f4a7c15ull) ^
                                 uint64_t(uint32_t(k.t)) << 1);
  }
};

}  // namespace

void append_obj_file(Scene& scene, const std::string& path, const mat4& xform,
                     uint32_t material_override, const SourceLoc& from) {
  const std::string suffix = from.path == path ? "" : " (mesh referenced at " + from.str() + ")";
  const std::string text = read_file_text(path, from);
  const bool mtl_ok = prescan_obj(text, path, suffix, scene.diagnostics);

  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path, config)) {
    throw InputError({path, 0}, "cannot read OBJ: " + reader.Error() + suffix);
  }
  std::istringstream warnings(reader.Warning());
  for (std::string w; std::getline(warnings, w);) {
    if (w.empty() || (!mtl_ok && w.find("aterial") != std::string::npos)) continue;
    scene.diagnostics.warn({path, 0}, "tinyobjloader: " + w + suffix, "continued");
  }

  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  const std::vector<tinyobj::material_t>& mtls = reader.GetMaterials();

  // Normals are used only if every corner has one; de-indexing by (position, normal) pairs turns
  // OBJ's separate index streams into the one-normal-per-position layout.
  bool use_normals = !attrib.normals.empty();
  for (const tinyobj::shape_t& shape : reader.GetShapes())
    for (const tinyobj::index_t& ix : shape.mesh.indices) use_normals &= ix.normal_index >= 0;
  if (!use_normals && !attrib.normals.empty()) {
    scene.diagnostics.warn({path, 0}, "some faces have vertex normals and some do not" + suffix,
                           "used flat shading for the whole mesh");
  }

  std::vector<uint32_t> material_ids(mtls.size(), kInvalid);
  uint32_t default_material = kInvalid;
  auto material_for = [&](int id) {
    if (material_override != kInvalid) return material_override;
    if (id < 0 || size_t(id) >= mtls.size()) {
      if (default_material == kInvalid) {
        default_material = scene.add_material("default grey", Material());
      }
      return default_material;
    }
    if (material_ids[size_t(id)] == kInvalid) {
      const tinyobj::material_t& mtl = mtls[size_t(id)];
      Material mat = convert_mtl(mtl, path, scene.diagnostics);
      if (mat.type == MaterialType::kDiffuse)
        mat.base_color_tex = load_map_kd(scene, path, mtl, suffix);
      material_ids[size_t(id)] = scene.add_material(mtl.name, mat);
    }
    return material_ids[size_t(id)];
  };

  // Texture coordinates likewise, only if every corner has one ("vt"); OBJ's v runs up the
  // image, glTF's (and ours) down, hence 1 - v.
  bool use_uvs = !attrib.texcoords.empty();
  for (const tinyobj::shape_t& shape : reader.GetShapes())
    for (const tinyobj::index_t& ix : shape.mesh.indices) use_uvs &= ix.texcoord_index >= 0;

  MeshPart part;
  std::unordered_map<CornerKey, uint32_t, CornerHash> remap;
  const size_t nv = attrib.vertices.size() / 3, nn = attrib.normals.size() / 3;
  const size_t nt = attrib.texcoords.size() / 2;
  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    const tinyobj::mesh_t& m = shape.mesh;
    size_t offset = 0;
    for (size_t f = 0; f < m.num_face_vertices.size(); ++f) {
      const size_t n = m.num_face_vertices[f];
      if (n != 3 || offset + 3 > m.indices.size()) {
        offset += n;
        continue;
      }
      uvec3 tri;
      bool ok = true;
      for (int k = 0; k < 3; ++k) {
        const tinyobj::index_t ix = m.indices[offset + size_t(k)];
        // The pre-scan already rejected bad indices; this guards against anything it missed.
        if (ix.vertex_index < 0 || size_t(ix.vertex_index) >= nv ||
            (use_normals && size_t(ix.normal_index) >= nn) ||
            (use_uvs && size_t(ix.texcoord_index) >= nt)) {
          ok = false;
          break;
        }
        const CornerKey key{ix.vertex_index, use_normals ? ix.normal_index : 0,
                            use_uvs ? ix.texcoord_index : 0};
        auto [it, inserted] = remap.emplace(key, uint32_t(part.positions.size()));
        if (inserted) {
          const float* p = &attrib.vertices[3 * size_t(ix.vertex_index)];
          part.positions.push_back(vec3(p[0], p[1], p[2]));
          if (use_normals) {
            const float* q = &attrib.normals[3 * size_t(ix.normal_index)];
            part.normals.push_back(vec3(q[0], q[1], q[2]));
          }
          if (use_uvs) {
            const float* t = &attrib.texcoords[2 * size_t(ix.texcoord_index)];
            part.uvs.push_back(vec2(t[0], 1.0f - t[1]));
          }
        }
        tri[k] = it->second;
      }
      offset += 3;
      if (!ok) throw InputError({path, 0}, "face index out of range" + suffix);
      part.indices.push_back(tri);
      part.materials.push_back(material_for(f < m.material_ids.size() ? m.material_ids[f] : -1));
    }
  }
  if (part.indices.empty()) {
    scene.diagnostics.warn({path, 0}, "OBJ file has no faces" + suffix, "nothing was added");
    return;
  }
  append_part(scene, part, xform);
}

}  // namespace tracer
