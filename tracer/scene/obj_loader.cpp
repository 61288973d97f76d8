// Wavefront OBJ + MTL meshes through tinyobjloader, with our own pre-scan so that bad vertices and
// face indices are reported with their line (tinyobjloader would read garbage or crash on them).
#include <tiny_obj_loader.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
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

// 12345678 as "12,345,678", for counts in messages.
std::string grouped(size_t n) {
  std::string digits = std::to_string(n), out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

// A file that ends inside a statement: its last line has no newline and is incomplete (a face
// with fewer than 3 corners, a vertex with fewer than 3 numbers, a keyword cut short). Reading
// stops at that line, or earlier at a face that refers to an element past those the file still
// defines (cut away with the rest of it). tinyobjloader would read such a file without complaint
// (or fail on the cut statement), so the pre-scan says where reading stopped and why. A last line
// that is complete but has no newline is common (and fine) and is not reported.
struct ObjTruncation {
  int line = 0;           // where reading stopped; 0: the file does not end inside a statement
  int last_line = 0;      // the line the file ends inside
  size_t kept_bytes = 0;  // the text before `line`, all that tinyobjloader is given
  std::string statement;  // the line where reading stopped, as read
  std::string why;        // what is wrong with it
  long faces_before = 0, vertices_before = 0;
};

struct ObjPrescan {
  bool mtl_ok = true;    // every referenced mtllib exists
  std::string mtl_path;  // the first material library that exists, for its warnings
  ObjTruncation truncation;
};

// The statements of the OBJ format (and tinyobjloader's "vw" and "t"); any other first word on a
// cut last line is taken for a keyword cut short.
bool known_obj_keyword(const std::string& w) {
  static const char* const kWords[] = {
      "v",          "vt",        "vn",    "vp",     "vw",    "f",        "l",
      "p",          "g",         "o",     "s",      "mg",    "usemtl",   "mtllib",
      "usemap",     "maplib",    "t",     "cstype", "deg",   "bmat",     "step",
      "curv",       "curv2",     "surf",  "parm",   "trim",  "hole",     "scrv",
      "sp",         "end",       "con",   "lod",    "bevel", "c_interp", "d_interp",
      "shadow_obj", "trace_obj", "ctech", "stech",  "call",  "csh"};
  for (const char* k : kWords)
    if (w == k) return true;
  return false;
}

// Finds what tinyobjloader does not report with a line: non-finite numbers, bad face indices and
// where a truncated file stops.
ObjPrescan prescan_obj(const std::string& text, const std::string& path, const std::string& suffix,
                       Diagnostics& diag) {
  ObjCounts total;
  int last_line = 0;
  std::string last_word;
  for_each_obj_line(text, [&](int line, const std::string& w, const std::string&) {
    total.v += w == "v";
    total.vt += w == "vt";
    total.vn += w == "vn";
    last_line = line;
    last_word = w;
  });
  // The last statement, if the file ends inside it (no newline after it); an element cut short
  // is not counted as defined.
  const bool ends_mid_line = !text.empty() && text.back() != '\n' && text.back() != '\r' &&
                             last_line == 1 + int(std::count(text.begin(), text.end(), '\n'));
  if (ends_mid_line) {
    total.v -= last_word == "v";
    total.vt -= last_word == "vt";
    total.vn -= last_word == "vn";
  }
  ObjCounts seen;
  ObjPrescan out;
  long faces = 0;
  // Records where reading stops in a file that ends inside a statement, returning true; false
  // when the file is whole, or `line` is not its last and `anywhere` is false (then the caller
  // reports the problem as for any file).
  auto truncated = [&](int line, const std::string& statement, const std::string& why,
                       bool anywhere = false) {
    if (!ends_mid_line || (line != last_line && !anywhere)) return false;
    size_t kept = 0;
    for (int l = 1; l < line; ++l) kept = text.find('\n', kept) + 1;
    out.truncation = {line, last_line, kept, statement, why, faces, seen.v};
    return true;
  };
  // A positive index past the elements of a truncated file: they were cut away with its end.
  auto cut_away = [&](int line, const std::string& statement, long idx, long total_of,
                      const char* what, const char* plural) {
    if (idx <= total_of) return false;
    return truncated(line, statement,
                     "a face that refers to " + std::string(what) + " " + std::to_string(idx) +
                         ", but the file defines " + grouped(size_t(total_of)) + " " +
                         (total_of == 1 ? what : plural),
                     true);
  };
  for_each_obj_line(text, [&](int line, const std::string& w, const std::string& rest) {
    if (out.truncation.line > 0) return;  // reading stopped
    const SourceLoc loc{path, line};
    if (!known_obj_keyword(w) && w[0] != '#') {
      truncated(line, w + rest, "an unknown statement, likely a keyword cut short");
      return;
    }
    if (w == "v" || w == "vn") {
      const char* p = rest.c_str();
      for (int i = 0; i < 3; ++i) {
        char* end = nullptr;
        const double d = std::strtod(p, &end);
        if (end == p) {
          if (truncated(line, w + rest,
                        std::string(w == "v" ? "a vertex" : "a normal") + " with " +
                            std::to_string(i) + " of its 3 coordinates"))
            return;
          throw InputError(loc, "\"" + w + "\" needs 3 numbers: \"" + w + rest + "\"" + suffix);
        }
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
            if (*end != '\0') {
              if (truncated(line, w + rest, "a face whose corner \"" + corner + "\" is cut short"))
                return;
              throw InputError(loc, "bad face index \"" + corner + "\"" + suffix);
            }
            present[k] = true;
          }
          if (slash == std::string::npos) break;
          start = slash + 1;
        }
        if (!present[0]) {
          if (truncated(line, w + rest, "a face whose corner \"" + corner + "\" is cut short"))
            return;
          throw InputError(loc, "face corner \"" + corner + "\" has no vertex index" + suffix);
        }
        if (cut_away(line, w + rest, idx[0], total.v, "vertex", "vertices") ||
            (present[1] && cut_away(line, w + rest, idx[1], total.vt, "texture coordinate",
                                    "texture coordinates")) ||
            (present[2] && cut_away(line, w + rest, idx[2], total.vn, "normal", "normals")))
          return;
        check_index(idx[0], seen.v, total.v, "vertex", "vertices", loc, suffix);
        if (present[1])
          check_index(idx[1], seen.vt, total.vt, "texture coordinate", "texture coordinates", loc,
                      suffix);
        if (present[2]) check_index(idx[2], seen.vn, total.vn, "normal", "normals", loc, suffix);
      }
      if (corners < 3) {
        if (truncated(
                line, w + rest,
                "a face with " + std::to_string(corners) + (corners == 1 ? " corner" : " corners")))
          return;
        diag.warn(loc, "face with " + std::to_string(corners) + " corners" + suffix,
                  "skipped (a face needs at least 3)");
      } else {
        ++faces;
      }
    } else if (w == "mtllib") {
      std::istringstream ms(rest);
      std::string name;
      while (ms >> name) {
        const std::string full = path_join(path_directory(path), name);
        if (!file_exists(full)) {
          diag.warn(loc, "material library \"" + name + "\" not found" + suffix,
                    "its materials are grey diffuse");
          out.mtl_ok = false;
        } else if (out.mtl_path.empty()) {
          out.mtl_path = full;
        }
      }
    }
  });
  return out;
}

// The line of the n-th (from 0) "usemtl <name>" of `text`, or 0.
int usemtl_line(const std::string& text, const std::string& name, int n) {
  int found = 0;
  for_each_obj_line(text, [&](int line, const std::string& w, const std::string& rest) {
    if (found || w != "usemtl") return;
    std::istringstream rs(rest);
    std::string word;
    if (rs >> word && word == name && n-- == 0) found = line;
  });
  return found;
}

// The line number in a tinyobjloader message ("(line 12.)", "(line 3 in .mtl.)", "line: 7"), or 0.
int line_named_in(const std::string& w) {
  for (const char* key : {"line: ", "line "}) {
    const size_t at = w.rfind(key);
    if (at != std::string::npos) return std::atoi(w.c_str() + at + std::strlen(key));
  }
  return 0;
}

// The message without its line note (given as path:line instead) and trailing newlines.
std::string strip_line_note(std::string w, int line) {
  auto trim = [&w] {
    while (!w.empty() && (w.back() == ' ' || w.back() == '.' || w.back() == '\n')) w.pop_back();
  };
  trim();
  if (line > 0) {
    for (const char* key : {"line: ", "line "}) {
      const size_t at = w.rfind(key);
      if (at == std::string::npos) continue;
      // "(line 3.)" goes whole; "(e.g. ... line 5.)" loses only "line 5.".
      const size_t open = w.rfind('(', at), close = w.find(')', at);
      const bool own = open != std::string::npos && open + 1 == at;
      const bool inside = !own && open != std::string::npos && close != std::string::npos;
      w = w.substr(0, own ? open : at);
      trim();
      if (inside) w += ")";
      break;
    }
  }
  return w;
}

// tinyobjloader's warnings as "path:line: ..." messages. Those about faces with fewer than 3
// corners or indices out of range repeat what the pre-scan reported with its line (or rejected);
// a missing material library was reported by the pre-scan too. Its "Degenerated face found\n."
// is where the bare "tinyobjloader: ." warning came from.
void report_tinyobj_warnings(const std::string& warnings, const std::string& text,
                             const std::string& path, const std::string& suffix,
                             const ObjPrescan& pre, Diagnostics& diag) {
  std::istringstream lines(warnings);
  std::unordered_map<std::string, int> missing_seen;  // one warning per "usemtl" of the name
  for (std::string w; std::getline(lines, w);) {
    while (!w.empty() && (w.back() == ' ' || w.back() == '\r')) w.pop_back();
    if (w.empty() || w == "." || w.rfind("Degenerated face found", 0) == 0 ||
        w.rfind("Face with invalid vertex index", 0) == 0 ||
        w.find("indices out of bounds") != std::string::npos)
      continue;
    if (!pre.mtl_ok && w.find("aterial") != std::string::npos) continue;
    const std::string kMissing = "material [ '";
    if (w.rfind(kMissing, 0) == 0) {
      const size_t end = w.find("' ]", kMissing.size());
      const std::string name = w.substr(
          kMissing.size(), end == std::string::npos ? std::string::npos : end - kMissing.size());
      diag.warn({path, usemtl_line(text, name, missing_seen[name]++)},
                "material \"" + name + "\" is not defined" +
                    (pre.mtl_path.empty() ? " (the file names no material library)"
                                          : " in the material library") +
                    suffix,
                "used grey diffuse");
      continue;
    }
    const int line = line_named_in(w);
    const bool in_mtl = w.find("in .mtl") != std::string::npos && !pre.mtl_path.empty();
    diag.warn({in_mtl ? pre.mtl_path : path, line},
              "tinyobjloader: " + strip_line_note(w, line) + suffix, "continued");
  }
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
  TextureImage t;
  if (!decode_texture_file(file, &t, suffix)) {
    scene.diagnostics.warn(loc, what + " cannot be decoded" + suffix, "rendered it untextured");
    return kInvalid;
  }
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
  // A UTF-16 file (a byte-order mark, or NULs between ASCII characters) reads as no statements
  // at all; say so rather than "no faces".
  const bool bom16 = text.size() >= 2 && ((uint8_t(text[0]) == 0xFE && uint8_t(text[1]) == 0xFF) ||
                                          (uint8_t(text[0]) == 0xFF && uint8_t(text[1]) == 0xFE));
  if (bom16 || text.find('\0') < std::min<size_t>(text.size(), 64)) {
    throw InputError({path, 0}, "the file is UTF-16 (or binary), not the ASCII/UTF-8 text OBJ is"
                                " written in; convert it, e.g. iconv -f UTF-16 -t UTF-8" + suffix);
  }
  const ObjPrescan pre = prescan_obj(text, path, suffix, scene.diagnostics);

  // tinyobjloader reads the text already in memory, up to where a truncated file's reading stops
  // (it would read a cut statement as a bogus vertex, or fail on it), and the MTL files beside
  // the OBJ.
  std::istringstream obj_text(pre.truncation.line > 0 ? text.substr(0, pre.truncation.kept_bytes)
                                                      : text);
  const std::string dir = path_directory(path);
  tinyobj::MaterialFileReader mtl_reader(dir.empty() ? "." : dir);
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> mtls;
  std::string warnings, error;
  if (!tinyobj::LoadObj(&attrib, &shapes, &mtls, &warnings, &error, &obj_text, &mtl_reader,
                        /*triangulate=*/true, /*default_vcols_fallback=*/false)) {
    const int line = line_named_in(error);
    throw InputError({path, line}, "cannot read OBJ: " + strip_line_note(error, line) + suffix);
  }
  report_tinyobj_warnings(warnings, text, path, suffix, pre, scene.diagnostics);

  // Normals are used only if every corner has one; de-indexing by (position, normal) pairs turns
  // OBJ's separate index streams into the one-normal-per-position layout.
  bool use_normals = !attrib.normals.empty();
  for (const tinyobj::shape_t& shape : shapes)
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
  for (const tinyobj::shape_t& shape : shapes)
    for (const tinyobj::index_t& ix : shape.mesh.indices) use_uvs &= ix.texcoord_index >= 0;

  MeshPart part;
  std::unordered_map<CornerKey, uint32_t, CornerHash> remap;
  const size_t nv = attrib.vertices.size() / 3, nn = attrib.normals.size() / 3;
  const size_t nt = attrib.texcoords.size() / 2;
  for (const tinyobj::shape_t& shape : shapes) {
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
  const ObjTruncation& cut = pre.truncation;
  if (cut.line > 0) {
    const std::string stopped =
        cut.line == cut.last_line
            ? "it ends inside line " + std::to_string(cut.line) + ", \"" + cut.statement + "\" (" +
                  cut.why + "), with no newline; reading stopped there"
            : "it ends inside line " + std::to_string(cut.last_line) +
                  " with no newline; reading stopped at line " + std::to_string(cut.line) + ", \"" +
                  cut.statement + "\" (" + cut.why + "),";
    scene.diagnostics.warn(
        {path, cut.line},
        "the file appears truncated: " + stopped + " after " + grouped(size_t(cut.faces_before)) +
            (cut.faces_before == 1 ? " face" : " faces") + " and " +
            grouped(size_t(cut.vertices_before)) +
            (cut.vertices_before == 1 ? " vertex" : " vertices") + suffix,
        part.indices.empty() ? "nothing was added"
                             : "used the " + grouped(part.indices.size()) + " triangle" +
                                   (part.indices.size() == 1 ? "" : "s") + " read");
  }
  if (part.indices.empty()) {
    scene.diagnostics.warn({path, 0}, "OBJ file has no faces" + suffix, "nothing was added");
    return;
  }
  append_part(scene, part, xform);
}

}  // namespace tracer
