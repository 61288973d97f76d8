// The glTF JSON pass beside tinygltf: version, compression extensions and the types of the
// material members the loader reads.
#include "scene/gltf_json.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>

namespace tracer {

namespace {

using nlohmann::json;

constexpr uint32_t kGlbMagic = 0x46546C67;      // "glTF"
constexpr uint32_t kGlbJsonChunk = 0x4E4F534A;  // "JSON"

uint32_t read_u32(const char* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);  // GLB is little-endian, as is every machine this builds for
  return v;
}

// The JSON text of a .gltf, or of a .glb's JSON chunk (GLB version 1, glTF 1.0's binary format,
// stores it the same way after a 20-byte header). Empty when the file cannot be read: tinygltf
// says why.
std::string json_text(const std::string& path, bool* binary, uint32_t* glb_version) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return {};
  const std::streamoff size = in.tellg();
  in.seekg(0);
  char header[20];
  in.read(header, sizeof header);
  const std::streamsize got = in.gcount();
  *binary = got >= 12 && read_u32(header) == kGlbMagic;
  if (!*binary) {
    in.clear();
    in.seekg(0);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  *glb_version = read_u32(header + 4);
  if (got < 20) return {};
  const uint32_t length = read_u32(header + 12);
  // GLB 2's first chunk must be JSON; GLB 1's content format 0 is JSON.
  const uint32_t type = read_u32(header + 16);
  if ((*glb_version == 2 && type != kGlbJsonChunk) || (*glb_version == 1 && type != 0) ||
      std::streamoff(length) > size - 20)
    return {};
  std::string text(length, '\0');
  in.read(&text[0], std::streamsize(length));
  if (in.gcount() != std::streamsize(length)) return {};
  return text;
}

std::string version_text(const json& asset) {
  if (!asset.is_object() || !asset.contains("version")) return {};
  const json& v = asset["version"];
  return v.is_string() ? v.get<std::string>() : v.is_number() ? v.dump() : std::string();
}

bool is_vec(const json& v, size_t n) {
  if (!v.is_array() || v.size() != n) return false;
  for (const json& e : v)
    if (!e.is_number()) return false;
  return true;
}

// A JSON number that is a whole number in int range (glTF's "integer"; 1.0 is accepted).
bool as_int(const json& v, int* out) {
  if (!v.is_number()) return false;
  const double d = v.get<double>();
  if (!(d == std::floor(d) && std::abs(d) < 2147483647.0)) return false;
  *out = int(d);
  return true;
}

std::string type_of(const json& v) {
  if (v.is_number()) return "a number";
  if (v.is_boolean()) return "a boolean";
  if (v.is_null()) return "null";
  return std::string(v.is_object() || v.is_array() ? "an " : "a ") + v.type_name();
}

enum class Want { kObject, kNumber, kInteger, kString, kVec3, kVec4 };

bool has_type(const json& v, Want w) {
  int i = 0;
  switch (w) {
    case Want::kInteger:
      return as_int(v, &i) && i >= 0;
    case Want::kObject:
      return v.is_object();
    case Want::kNumber:
      return v.is_number();
    case Want::kString:
      return v.is_string();
    case Want::kVec3:
      return is_vec(v, 3);
    case Want::kVec4:
      return is_vec(v, 4);
  }
  return false;
}

const char* want_name(Want w) {
  switch (w) {
    case Want::kObject:
      return "an object";
    case Want::kNumber:
      return "a number";
    case Want::kInteger:
      return "an index";
    case Want::kString:
      return "a string";
    case Want::kVec3:
      return "an array of 3 numbers";
    case Want::kVec4:
      return "an array of 4 numbers";
  }
  return "";
}

// The material members the loader reads, their parent ("" the material) and what the loader
// uses instead of a wrongly typed one (tinygltf's default).
struct MemberRule {
  const char* parent;
  const char* key;
  Want want;
  const char* instead;
};
const MemberRule kMaterialMembers[] = {
    {"", "name", Want::kString, "left the material unnamed"},
    {"", "pbrMetallicRoughness", Want::kObject,
     "used glTF's defaults: base colour white, metallic 1, roughness 1, no base colour or "
     "metallic-roughness texture"},
    {"/pbrMetallicRoughness", "baseColorFactor", Want::kVec4, "used white"},
    {"/pbrMetallicRoughness", "metallicFactor", Want::kNumber, "used 1 (glTF's default)"},
    {"/pbrMetallicRoughness", "roughnessFactor", Want::kNumber, "used 1 (glTF's default)"},
    {"", "emissiveFactor", Want::kVec3, "used black (no emission)"},
    {"/normalTexture", "scale", Want::kNumber, "used 1"},
    {"", "alphaMode", Want::kString, "rendered the material opaque"},
    {"", "extensions", Want::kObject, "ignored the material's extensions"},
    {"/extensions", "KHR_materials_emissive_strength", Want::kObject, "ignored it"},
    {"/extensions/KHR_materials_emissive_strength", "emissiveStrength", Want::kNumber, "used 1"},
    {"/extensions", "KHR_materials_transmission", Want::kObject, "ignored it"},
    {"/extensions/KHR_materials_transmission", "transmissionFactor", Want::kNumber, "used 0"},
    {"/extensions", "KHR_materials_ior", Want::kObject, "ignored it"},
    {"/extensions/KHR_materials_ior", "ior", Want::kNumber, "used 1.5"},
    {"/extensions", "KHR_materials_volume", Want::kObject, "ignored it"},
    {"/extensions/KHR_materials_volume", "attenuationDistance", Want::kNumber,
     "used no attenuation"},
    {"/extensions/KHR_materials_volume", "attenuationColor", Want::kVec3, "used white"},
    {"/extensions", "KHR_materials_diffuse_transmission", Want::kObject, "ignored it"},
    {"/extensions/KHR_materials_diffuse_transmission", "diffuseTransmissionFactor", Want::kNumber,
     "used 0"},
};

// The JSON value at `relative` ("/a/b") below `base`, nullptr where a step is missing or not
// an object.
const json* find(const json& base, const std::string& relative) {
  const json* v = &base;
  size_t at = 1;
  while (at <= relative.size() && !relative.empty()) {
    const size_t next = std::min(relative.find('/', at), relative.size());
    const std::string key = relative.substr(at, next - at);
    if (!v->is_object()) return nullptr;
    const auto it = v->find(key);
    if (it == v->end()) return nullptr;
    v = &*it;
    at = next + 1;
  }
  return v;
}

}  // namespace

glm::mat3x2 khr_texture_transform(vec2 offset, float rotation, vec2 scale) {
  const float c = std::cos(rotation), s = std::sin(rotation);
  // Columns: T R S applied to (1, 0, 0), (0, 1, 0) and (0, 0, 1).
  return glm::mat3x2(vec2(c * scale.x, -s * scale.x), vec2(s * scale.y, c * scale.y), offset);
}

std::string GltfJson::compression_what(const std::string& extension) {
  return extension == "KHR_draco_mesh_compression" ? "Draco-compressed geometry"
                                                   : "meshopt-compressed buffers";
}

GltfJson::GltfJson(const std::string& path, const std::string& suffix)
    : path_(path), suffix_(suffix) {
  uint32_t glb_version = 0;
  const std::string text = json_text(path, &binary_, &glb_version);
  // Only the members checked here are kept: the rest (nodes, accessors, embedded buffers) can be
  // large, and tinygltf reads them anyway. The others' JSON types are noted, for glTF 1.0.
  std::string key;
  const auto keep = [&](int depth, json::parse_event_t event, json& parsed) {
    if (depth != 1) return true;
    if (event == json::parse_event_t::key) {
      key = parsed.get<std::string>();
      return key == "asset" || key == "extensionsUsed" || key == "extensionsRequired" ||
             key == "materials" || key == "meshes";
    }
    if (!key.empty()) {
      top_types_[key] = event == json::parse_event_t::object_start  ? "object"
                        : event == json::parse_event_t::array_start ? "array"
                                                                    : "value";
      key.clear();
    }
    return true;
  };
  if (!text.empty()) root_ = json::parse(text, keep, /*allow_exceptions=*/false);
  if (!root_.is_object()) root_ = json::object();

  // glTF 1.0: asset.version "1.0" (some exporters write the number 1), GLB version 1, or, with no
  // asset at all, the top-level collections written as objects keyed by id.
  const std::string version = version_text(root_.value("asset", json()));
  std::string why;
  if (version == "1" || version.rfind("1.", 0) == 0) {
    why = "asset version " + version;
  } else if (glb_version == 1) {
    why = "binary glTF version 1";
  } else if (version.empty()) {
    for (const char* c : {"meshes", "nodes", "accessors", "buffers", "scenes"}) {
      const auto it = top_types_.find(c);
      if (it != top_types_.end() && it->second == "object") {
        why = std::string("no asset version, and \"") + c +
              "\" is an object keyed by id, as in glTF 1.0";
        break;
      }
    }
  }
  if (!why.empty())
    throw InputError({path_, 0}, "glTF 1.0 is not supported (" + why + ")" + suffix_);

  const auto listed = [&](const char* member, const std::string& ext) {
    const json& list = root_.value(member, json::array());
    if (!list.is_array()) return false;
    for (const json& e : list)
      if (e.is_string() && e.get<std::string>() == ext) return true;
    return false;
  };
  for (const char* ext :
       {"KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression"}) {
    if (listed("extensionsRequired", ext))
      throw InputError({path_, 0}, std::string("the file requires ") + ext + " (" +
                                       compression_what(ext) + "), which is not supported" +
                                       suffix_);
    if (compression_.empty() && listed("extensionsUsed", ext)) compression_ = ext;
  }
}

size_t GltfJson::material_count() const {
  const auto it = root_.find("materials");
  return it != root_.end() && it->is_array() ? it->size() : 0;
}

const json* GltfJson::material(size_t m) const {
  const auto it = root_.find("materials");
  if (it == root_.end() || !it->is_array() || m >= it->size()) return nullptr;
  return &(*it)[m];
}

SourceLoc GltfJson::loc(const std::string& pointer) const {
  if (!binary_ && !lines_tried_) {
    lines_tried_ = true;
    std::ifstream in(path_, std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    try {
      lines_ = std::make_unique<JsonDocument>(parse_json_with_lines(text, path_));
    } catch (const InputError&) {
      // A duplicate key, say: tinygltf read the file, so the warning goes out without a line.
    }
  }
  return {path_, lines_ ? lines_->line_of(pointer) : 0};
}

void GltfJson::warn(Diagnostics& diag, const std::string& pointer, const std::string& problem,
                    const std::string& action) const {
  diag.warn(loc(pointer), pointer + " " + problem + suffix_, action);
}

void GltfJson::check_material(size_t m, Diagnostics& diag) const {
  const json* mat = material(m);
  if (!mat || !mat->is_object()) return;  // tinygltf rejects a material that is not an object
  const std::string base = "/materials/" + std::to_string(m);
  for (const MemberRule& r : kMaterialMembers) {
    const json* parent = find(*mat, r.parent);
    if (!parent || !parent->is_object()) continue;  // absent, or warned about itself
    const auto it = parent->find(r.key);
    if (it == parent->end() || has_type(*it, r.want)) continue;
    warn(diag, base + r.parent + "/" + r.key, "is " + type_of(*it) + ", not " + want_name(r.want),
         r.instead);
  }
}

void GltfJson::check_meshes(Diagnostics& diag) const {
  const auto meshes = root_.find("meshes");
  if (meshes == root_.end() || !meshes->is_array()) return;
  // What the loader does with a wrongly typed member, which tinygltf leaves at its default.
  const MemberRule rules[] = {
      {"", "attributes", Want::kObject, "skipped the primitive"},
      {"", "indices", Want::kInteger, "read its vertices in order, as if it had no indices"},
      {"", "material", Want::kInteger, "used grey diffuse"},
      {"", "mode", Want::kInteger, "read it as triangles"},
  };
  for (size_t i = 0; i < meshes->size(); ++i) {
    const json& mesh = (*meshes)[i];
    const std::string mp = "/meshes/" + std::to_string(i);
    if (!mesh.is_object()) continue;  // tinygltf rejects the file
    const auto prims = mesh.find("primitives");
    if (prims == mesh.end()) continue;
    if (!prims->is_array()) {
      warn(diag, mp + "/primitives", "is " + type_of(*prims) + ", not an array",
           "skipped the mesh");
      continue;
    }
    for (size_t j = 0; j < prims->size(); ++j) {
      const json& prim = (*prims)[j];
      const std::string pp = mp + "/primitives/" + std::to_string(j);
      if (!prim.is_object()) {
        warn(diag, pp, "is " + type_of(prim) + ", not an object", "skipped the primitive");
        continue;
      }
      for (const MemberRule& r : rules) {
        const auto it = prim.find(r.key);
        if (it != prim.end() && !has_type(*it, r.want))
          warn(diag, pp + "/" + r.key, "is " + type_of(*it) + ", not " + want_name(r.want),
               r.instead);
      }
    }
  }
}

GltfTextureRef GltfJson::texture(size_t m, GltfSlot slot, size_t textures,
                                 Diagnostics& diag) const {
  GltfTextureRef ref;
  const json* mat = material(m);
  if (!mat || !mat->is_object()) return ref;
  const char* parent = slot == GltfSlot::kBaseColor || slot == GltfSlot::kMetallicRoughness
                           ? "/pbrMetallicRoughness"
                           : "";
  const char* key = slot == GltfSlot::kBaseColor           ? "baseColorTexture"
                    : slot == GltfSlot::kMetallicRoughness ? "metallicRoughnessTexture"
                    : slot == GltfSlot::kEmissive          ? "emissiveTexture"
                                                           : "normalTexture";
  const json* holder = find(*mat, parent);
  if (!holder || !holder->is_object()) return ref;  // check_material warns about it
  const auto found = holder->find(key);
  if (found == holder->end()) return ref;
  const json& info = *found;
  ref.pointer = "/materials/" + std::to_string(m) + parent + "/" + key;
  const json& name = mat->value("name", json());
  const std::string without = "rendered " +
                              (name.is_string() ? "material \"" + name.get<std::string>() + "\""
                                                : "material " + std::to_string(m)) +
                              " without this texture";
  if (!info.is_object()) {
    warn(diag, ref.pointer, "is " + type_of(info) + ", not a textureInfo object", without);
    return ref;
  }
  int index = -1;
  const auto idx = info.find("index");
  if (idx == info.end()) {
    warn(diag, ref.pointer, "has no \"index\"", without);
    return ref;
  }
  if (!as_int(*idx, &index)) {
    warn(diag, ref.pointer + "/index", "is " + idx->dump() + ", not a texture index", without);
    return ref;
  }
  if (index < 0 || size_t(index) >= textures) {
    warn(diag, ref.pointer + "/index",
         "is " + std::to_string(index) + ", but the file has " + std::to_string(textures) +
             " texture(s)",
         without);
    return ref;
  }
  ref.index = index;
  const auto tex_coord = [&](const json& holder, const std::string& pointer) {
    const auto it = holder.find("texCoord");
    if (it == holder.end()) return;
    int n = -1;
    if (as_int(*it, &n) && n >= 0)
      ref.tex_coord = n;
    else
      warn(diag, pointer + "/texCoord", "is " + it->dump() + ", not a texture coordinate set",
           "used set " + std::to_string(ref.tex_coord));
  };
  tex_coord(info, ref.pointer);

  const auto exts = info.find("extensions");
  if (exts == info.end()) return ref;
  if (!exts->is_object()) {
    warn(diag, ref.pointer + "/extensions", "is " + type_of(*exts) + ", not an object",
         "ignored the texture's extensions");
    return ref;
  }
  for (auto e = exts->begin(); e != exts->end(); ++e)
    if (e.key() != "KHR_texture_transform") ref.ignored_extensions.push_back(e.key());
  const auto tt = exts->find("KHR_texture_transform");
  if (tt == exts->end()) return ref;
  const std::string tp = ref.pointer + "/extensions/KHR_texture_transform";
  if (!tt->is_object()) {
    warn(diag, tp, "is " + type_of(*tt) + ", not an object", "did not transform the texture");
    return ref;
  }
  const auto finite_vec2 = [&](const char* member, vec2 fallback) {
    const auto it = tt->find(member);
    if (it == tt->end()) return fallback;
    if (is_vec(*it, 2) && std::isfinite((*it)[0].get<double>()) &&
        std::isfinite((*it)[1].get<double>()))
      return vec2(float((*it)[0].get<double>()), float((*it)[1].get<double>()));
    warn(diag, tp + "/" + member, "is " + it->dump() + ", not an array of 2 finite numbers",
         "used [" + std::to_string(int(fallback.x)) + ", " + std::to_string(int(fallback.y)) + "]");
    return fallback;
  };
  const vec2 offset = finite_vec2("offset", vec2(0.0f));
  const vec2 scale = finite_vec2("scale", vec2(1.0f));
  float rotation = 0.0f;
  const auto rot = tt->find("rotation");
  if (rot != tt->end()) {
    if (rot->is_number() && std::isfinite(rot->get<double>()))
      rotation = float(rot->get<double>());
    else
      warn(diag, tp + "/rotation", "is " + rot->dump() + ", not a finite number", "used 0");
  }
  ref.transform = khr_texture_transform(offset, rotation, scale);
  tex_coord(*tt, tp);
  return ref;
}

}  // namespace tracer
