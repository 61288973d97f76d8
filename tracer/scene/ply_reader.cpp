// PLY reader: header, then the elements in file order, every value read through one cursor that
// knows the encoding. A lying header cannot make it allocate or loop more than the file's size
// allows: element counts are checked against the bytes after the header first, list lengths
// against the bytes left before they are read.
#include "scene/ply_reader.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "core/math.h"

namespace tracer {

namespace {

enum class PlyType : uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kFloat32,
  kFloat64
};
enum class PlyFormat : uint8_t { kAscii, kBinaryLittle, kBinaryBig };

bool parse_type(const std::string& s, PlyType* t) {
  static const struct {
    const char* name;
    PlyType type;
  } kNames[] = {
      {"char", PlyType::kInt8},      {"int8", PlyType::kInt8},       {"uchar", PlyType::kUint8},
      {"uint8", PlyType::kUint8},    {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUint16},  {"uint16", PlyType::kUint16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},    {"uint", PlyType::kUint32},     {"uint32", PlyType::kUint32},
      {"float", PlyType::kFloat32},  {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64}};
  for (const auto& n : kNames) {
    if (s == n.name) {
      *t = n.type;
      return true;
    }
  }
  return false;
}

size_t type_size(PlyType t) {
  switch (t) {
    case PlyType::kInt8:
    case PlyType::kUint8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUint16:
      return 2;
    case PlyType::kInt32:
    case PlyType::kUint32:
    case PlyType::kFloat32:
      return 4;
    case PlyType::kFloat64:
      return 8;
  }
  return 1;
}

bool is_integer(PlyType t) {
  return t != PlyType::kFloat32 && t != PlyType::kFloat64;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;  // the items' type for a list
  bool is_list = false;
  PlyType count_type = PlyType::kUint8;
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  int line = 0;
  std::vector<PlyProperty> props;
};

struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  size_t data_start = 0;  // first byte after the end_header line
  int data_line = 1;      // line number of data_start (ASCII)
};

std::vector<std::string> split_words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

PlyHeader parse_header(const std::string& bytes, const std::string& path,
                       const std::string& suffix) {
  PlyHeader h;
  size_t pos = 0;
  int line = 0;
  bool have_format = false;
  auto fail = [&](const std::string& what) { throw InputError({path, line}, what + suffix); };
  while (true) {
    if (pos >= bytes.size()) {
      const bool empty = line == 0;
      line = 0;
      fail(empty ? "the file is empty" : "the PLY header has no end_header line");
    }
    const size_t nl = bytes.find('\n', pos);
    std::string text = bytes.substr(pos, nl == std::string::npos ? std::string::npos : nl - pos);
    if (!text.empty() && text.back() == '\r') text.pop_back();
    ++line;
    pos = nl == std::string::npos ? bytes.size() : nl + 1;
    const std::vector<std::string> w = split_words(text);
    if (line == 1) {
      if (w.size() != 1 || w[0] != "ply") fail("not a PLY file (the first line is not \"ply\")");
      continue;
    }
    if (w.empty() || w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") break;
    if (w[0] == "format") {
      if (w.size() != 3) fail("\"format\" needs a format and a version: \"" + text + "\"");
      if (w[1] == "ascii")
        h.format = PlyFormat::kAscii;
      else if (w[1] == "binary_little_endian")
        h.format = PlyFormat::kBinaryLittle;
      else if (w[1] == "binary_big_endian")
        h.format = PlyFormat::kBinaryBig;
      else
        fail("unknown PLY format \"" + w[1] +
             "\" (expected ascii, binary_little_endian or binary_big_endian)");
      have_format = true;
    } else if (w[0] == "element") {
      if (w.size() != 3) fail("\"element\" needs a name and a count: \"" + text + "\"");
      PlyElement e;
      e.name = w[1];
      e.line = line;
      char* end = nullptr;
      errno = 0;
      const unsigned long long n = std::strtoull(w[2].c_str(), &end, 10);
      if (*end != '\0' || w[2][0] == '-' || errno == ERANGE)
        fail("element \"" + e.name + "\" has a bad count \"" + w[2] + "\"");
      e.count = n;
      h.elements.push_back(e);
    } else if (w[0] == "property") {
      if (h.elements.empty()) fail("\"property\" before any \"element\"");
      PlyProperty p;
      if (w.size() >= 2 && w[1] == "list") {
        if (w.size() != 5) fail("\"property list\" needs a count type, an item type and a name");
        p.is_list = true;
        if (!parse_type(w[2], &p.count_type) || !is_integer(p.count_type))
          fail("bad list count type \"" + w[2] + "\" (expected an integer type such as uchar)");
        if (!parse_type(w[3], &p.type)) fail("unknown property type \"" + w[3] + "\"");
        p.name = w[4];
      } else {
        if (w.size() != 3) fail("\"property\" needs a type and a name: \"" + text + "\"");
        if (!parse_type(w[1], &p.type)) fail("unknown property type \"" + w[1] + "\"");
        p.name = w[2];
      }
      h.elements.back().props.push_back(p);
    } else {
      fail("unknown PLY header line \"" + text + "\"");
    }
  }
  if (!have_format) fail("the PLY header has no \"format\" line");
  h.data_start = pos;
  h.data_line = line + 1;
  return h;
}

// Reads values in the file's encoding. Throws InputError at the current element instance when
// the data ends early or (ASCII) a token is not a number of the declared type.
class Cursor {
 public:
  Cursor(const std::string& bytes, const PlyHeader& h, const std::string& path,
         const std::string& suffix)
      : bytes_(bytes),
        pos_(h.data_start),
        line_(h.data_line),
        format_(h.format),
        path_(path),
        suffix_(suffix) {
    const uint16_t one = 1;
    uint8_t first = 0;
    std::memcpy(&first, &one, 1);
    swap_ = (format_ == PlyFormat::kBinaryBig) == (first == 1);
  }

  // Where the values being read belong, for messages.
  void at(const PlyElement* e, uint64_t index) {
    element_ = e;
    index_ = index;
  }

  size_t remaining() const { return bytes_.size() - pos_; }
  bool ascii() const { return format_ == PlyFormat::kAscii; }

  double value(PlyType t) { return ascii() ? ascii_value(t) : binary_value(t); }

  // A list's length: a non-negative integer whose items fit in what is left of the file.
  uint64_t list_length(const PlyProperty& p) {
    const double n = value(p.count_type);
    if (n < 0.0) fail("property \"" + p.name + "\" has a negative list length");
    const uint64_t count = uint64_t(n);
    // ASCII items take at least two bytes (a digit and a separator, but for the file's last
    // one), binary ones their size.
    const uint64_t room = ascii() ? (remaining() + 1) / 2 : remaining() / type_size(p.type);
    if (count > room)
      fail("property \"" + p.name + "\" has a list of " + std::to_string(count) +
           " items, more than the rest of the file holds");
    return count;
  }

  void skip(PlyType t, uint64_t n) {
    if (!ascii()) {
      // list_length() bounds n by the file's size, so the product cannot overflow.
      const size_t bytes = size_t(n) * type_size(t);
      if (bytes > remaining()) fail("the file ends early (truncated?)");
      pos_ += bytes;
      return;
    }
    for (uint64_t i = 0; i < n; ++i) ascii_value(t);
  }

  [[noreturn]] void fail(const std::string& what) const {
    std::string where;
    if (element_)
      where = "element \"" + element_->name + "\" " + std::to_string(index_) + " of " +
              std::to_string(element_->count) + ": ";
    throw InputError({path_, ascii() ? line_ : 0}, where + what + suffix_);
  }

 private:
  double binary_value(PlyType t) {
    const size_t n = type_size(t);
    if (remaining() < n) fail("the file ends early (truncated?)");
    uint8_t b[8];
    std::memcpy(b, bytes_.data() + pos_, n);
    pos_ += n;
    if (swap_)
      for (size_t i = 0; i < n / 2; ++i) std::swap(b[i], b[n - 1 - i]);
    switch (t) {
      case PlyType::kInt8:
        return double(int8_t(b[0]));
      case PlyType::kUint8:
        return double(b[0]);
      case PlyType::kInt16:
        return double(load<int16_t>(b));
      case PlyType::kUint16:
        return double(load<uint16_t>(b));
      case PlyType::kInt32:
        return double(load<int32_t>(b));
      case PlyType::kUint32:
        return double(load<uint32_t>(b));
      case PlyType::kFloat32:
        return double(load<float>(b));
      case PlyType::kFloat64:
        return load<double>(b);
    }
    return 0.0;
  }

  template <typename T>
  static T load(const uint8_t* b) {
    T v;
    std::memcpy(&v, b, sizeof v);
    return v;
  }

  double ascii_value(PlyType t) {
    const char* s = bytes_.data();
    while (pos_ < bytes_.size() && std::isspace(static_cast<unsigned char>(s[pos_]))) {
      if (s[pos_] == '\n') ++line_;
      ++pos_;
    }
    if (pos_ >= bytes_.size()) fail("the file ends early (truncated?)");
    const size_t start = pos_;
    while (pos_ < bytes_.size() && !std::isspace(static_cast<unsigned char>(s[pos_]))) ++pos_;
    const std::string token = bytes_.substr(start, pos_ - start);
    char* end = nullptr;
    const double v = std::strtod(token.c_str(), &end);
    if (end == token.c_str() || *end != '\0') fail("\"" + token + "\" is not a number");
    if (is_integer(t) && (v != std::floor(v) || !std::isfinite(v)))
      fail("\"" + token + "\" is not an integer");
    return v;
  }

  const std::string& bytes_;
  size_t pos_;
  int line_;
  PlyFormat format_;
  bool swap_ = false;
  const std::string& path_;
  const std::string& suffix_;
  const PlyElement* element_ = nullptr;
  uint64_t index_ = 0;
};

// Checks the header's counts against the bytes after it, before anything is allocated.
void check_counts(const PlyHeader& h, size_t data_bytes, const std::string& path,
                  const std::string& suffix) {
  const bool ascii = h.format == PlyFormat::kAscii;
  uint64_t needed = 0;
  for (const PlyElement& e : h.elements) {
    uint64_t min_size = 0;  // the smallest an instance can be
    for (const PlyProperty& p : e.props)
      min_size += ascii ? 2 : type_size(p.is_list ? p.count_type : p.type);
    if (min_size == 0 || e.count == 0) continue;
    const uint64_t left = data_bytes + 1 > needed ? data_bytes + 1 - needed : 0;
    if (e.count > left / min_size) {
      throw InputError({path, e.line}, "element \"" + e.name + "\" declares " +
                                           std::to_string(e.count) + " instances, but the " +
                                           std::to_string(data_bytes) +
                                           " bytes after the header hold at most " +
                                           std::to_string(left / min_size) + suffix);
    }
    needed += e.count * min_size;
  }
}

int find_prop(const PlyElement& e, const char* name) {
  for (size_t i = 0; i < e.props.size(); ++i)
    if (e.props[i].name == name) return int(i);
  return -1;
}

void read_vertices(Cursor& in, const PlyElement& e, PlyMesh& out) {
  // Slot of each property: 0-2 position, 3-5 normal, 6-7 uv, -1 skipped.
  std::vector<int> slot(e.props.size(), -1);
  // parse_ply() checked that x, y and z exist.
  const int xyz[3] = {find_prop(e, "x"), find_prop(e, "y"), find_prop(e, "z")};
  for (int k = 0; k < 3; ++k) slot[size_t(xyz[k])] = k;
  const int nx = find_prop(e, "nx"), ny = find_prop(e, "ny"), nz = find_prop(e, "nz");
  const bool normals = nx >= 0 && ny >= 0 && nz >= 0;
  if (normals) {
    slot[size_t(nx)] = 3;
    slot[size_t(ny)] = 4;
    slot[size_t(nz)] = 5;
  }
  // The names in use for texture coordinates; the first complete pair wins.
  static const char* kUv[][2] = {
      {"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}};
  bool uvs = false;
  for (const auto& pair : kUv) {
    const int u = find_prop(e, pair[0]), v = find_prop(e, pair[1]);
    if (u >= 0 && v >= 0) {
      slot[size_t(u)] = 6;
      slot[size_t(v)] = 7;
      uvs = true;
      break;
    }
  }
  for (size_t i = 0; i < e.props.size(); ++i) {
    if (slot[i] >= 0 && e.props[i].is_list) {
      in.at(&e, 0);
      in.fail("property \"" + e.props[i].name + "\" is a list, expected a number");
    }
  }
  MeshPart& part = out.part;
  part.positions.resize(size_t(e.count));
  if (normals) part.normals.resize(size_t(e.count));
  if (uvs) part.uvs.resize(size_t(e.count));
  for (uint64_t v = 0; v < e.count; ++v) {
    in.at(&e, v);
    double val[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (size_t i = 0; i < e.props.size(); ++i) {
      const PlyProperty& p = e.props[i];
      if (p.is_list) {
        in.skip(p.type, in.list_length(p));
      } else if (slot[i] < 0) {
        in.skip(p.type, 1);
      } else {
        val[slot[i]] = in.value(p.type);
        if (!std::isfinite(float(val[slot[i]])))
          in.fail("property \"" + p.name + "\" is not a finite number");
      }
    }
    part.positions[size_t(v)] = vec3(float(val[0]), float(val[1]), float(val[2]));
    if (normals) part.normals[size_t(v)] = vec3(float(val[3]), float(val[4]), float(val[5]));
    // PLY's v runs up the image as OBJ's does; ours runs down.
    if (uvs) part.uvs[size_t(v)] = vec2(float(val[6]), 1.0f - float(val[7]));
  }
}

void read_faces(Cursor& in, const PlyElement& e, uint64_t vertex_count, PlyMesh& out) {
  int list = find_prop(e, "vertex_indices");
  if (list < 0) list = find_prop(e, "vertex_index");
  in.at(&e, 0);
  if (list < 0) in.fail("the face element has no \"vertex_indices\" list");
  const PlyProperty& lp = e.props[size_t(list)];
  if (!lp.is_list) in.fail("\"" + lp.name + "\" is not a list");
  if (!is_integer(lp.type))
    in.fail("\"" + lp.name + "\" holds floating-point numbers, not indices");
  std::vector<uint32_t> corners;
  for (uint64_t f = 0; f < e.count; ++f) {
    in.at(&e, f);
    for (size_t i = 0; i < e.props.size(); ++i) {
      const PlyProperty& p = e.props[i];
      if (int(i) != list) {
        in.skip(p.type, p.is_list ? in.list_length(p) : 1);
        continue;
      }
      const uint64_t n = in.list_length(p);
      corners.clear();
      for (uint64_t k = 0; k < n; ++k) {
        const double idx = in.value(p.type);
        if (idx < 0.0 || idx >= double(vertex_count))
          in.fail("refers to vertex " + std::to_string(int64_t(idx)) + ", but the file has " +
                  std::to_string(vertex_count) + " vertices");
        corners.push_back(uint32_t(idx));
      }
      if (n < 3) {
        ++out.skipped_faces;
        continue;
      }
      for (size_t k = 1; k + 1 < corners.size(); ++k)
        out.part.indices.push_back(uvec3(corners[0], corners[k], corners[k + 1]));
    }
  }
}

}  // namespace

PlyMesh parse_ply(const std::string& bytes, const std::string& path, const std::string& suffix) {
  const PlyHeader h = parse_header(bytes, path, suffix);
  check_counts(h, bytes.size() - h.data_start, path, suffix);
  const PlyElement* vertex = nullptr;
  for (const PlyElement& e : h.elements)
    if (e.name == "vertex" && !vertex) vertex = &e;
  if (!vertex) throw InputError({path, 0}, "the PLY file has no \"vertex\" element" + suffix);
  if (find_prop(*vertex, "x") < 0 || find_prop(*vertex, "y") < 0 || find_prop(*vertex, "z") < 0)
    throw InputError({path, vertex->line},
                     "the vertex element lacks one of the properties x, y, z" + suffix);
  if (vertex->count > uint64_t(UINT32_MAX))
    throw InputError({path, vertex->line}, "more than 2^32 - 1 vertices" + suffix);

  PlyMesh out;
  Cursor in(bytes, h, path, suffix);
  bool seen_face = false;
  for (const PlyElement& e : h.elements) {
    if (&e == vertex) {
      read_vertices(in, e, out);
    } else if (e.name == "face" && !seen_face) {
      read_faces(in, e, vertex->count, out);
      seen_face = true;
    } else if (!e.props.empty()) {
      for (uint64_t i = 0; i < e.count; ++i) {
        in.at(&e, i);
        for (const PlyProperty& p : e.props) in.skip(p.type, p.is_list ? in.list_length(p) : 1);
      }
    }
  }
  return out;
}

PlyMesh read_ply(const std::string& path, const SourceLoc& from, const std::string& suffix) {
  return parse_ply(read_file_text(path, from), path, suffix);
}

void append_ply_file(Scene& scene, const std::string& path, const mat4& xform,
                     uint32_t material_override, const SourceLoc& from) {
  const std::string suffix = from.path == path ? "" : " (mesh referenced at " + from.str() + ")";
  PlyMesh mesh = read_ply(path, from, suffix);
  if (mesh.skipped_faces > 0) {
    scene.diagnostics.warn(
        {path, 0}, std::to_string(mesh.skipped_faces) + " faces with fewer than 3 corners" + suffix,
        "skipped them");
  }
  if (mesh.part.indices.empty()) {
    scene.diagnostics.warn({path, 0}, "PLY file has no faces" + suffix, "nothing was added");
    return;
  }
  const uint32_t material = material_override != kInvalid
                                ? material_override
                                : scene.add_material("default grey", Material());
  mesh.part.materials.assign(mesh.part.indices.size(), material);
  append_part(scene, mesh.part, xform);
}

}  // namespace tracer
