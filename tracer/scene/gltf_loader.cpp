// glTF 2.0 (.gltf/.glb) meshes through tinygltf. tinygltf checks little of what it reads, so every
// index, accessor range and node link is validated here before use: a broken file gives an
// InputError, never an out-of-bounds read or an endless node walk. The file's JSON is also read
// as written (scene/gltf_json.h): the version, compression extensions, texture references with
// their KHR_texture_transform, and members of the wrong type that tinygltf would drop silently.
#include <stb_image.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <set>
#include <tuple>

#include "core/math.h"
#include "materials/subsurface.h"
#include "scene/gltf_json.h"
#include "scene/loader_util.h"

namespace tracer {

namespace {

constexpr int kMaxTextureSide = 16384;

// Decodes an encoded image (PNG, JPEG, ...) into RGBA8 with stb_image; `what` names the image.
// One larger than kMaxTextureSide a side is an error (returns false, says why in *err); one stb
// cannot decode (KTX2, WebP behind an extension, a corrupt file) stays empty, and the materials
// that use it are rendered without it, with a warning (GltfReader::texture).
bool decode_image(tinygltf::Image* image, const unsigned char* bytes, size_t size,
                  const std::string& what, std::string* err) {
  int w = 0, h = 0, comp = 0;
  if (size > size_t(INT32_MAX) || !stbi_info_from_memory(bytes, int(size), &w, &h, &comp))
    return true;
  if (w > kMaxTextureSide || h > kMaxTextureSide) {
    if (err)
      *err += what + " is " + std::to_string(w) + "x" + std::to_string(h) + ", larger than " +
              std::to_string(kMaxTextureSide) + "x" + std::to_string(kMaxTextureSide) + "\n";
    return false;
  }
  unsigned char* data = stbi_load_from_memory(bytes, int(size), &w, &h, &comp, 4);
  if (!data || w <= 0 || h <= 0) {
    stbi_image_free(data);
    return true;
  }
  image->width = w;
  image->height = h;
  image->component = 4;
  image->bits = 8;
  image->pixel_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  image->image.assign(data, data + size_t(w) * size_t(h) * 4);
  stbi_image_free(data);
  return true;
}

// tinygltf's image callback. Images stored in a buffer view arrive as a pointer tinygltf has not
// checked against the buffer's size; those are left for GltfReader::decode_buffer_images, which
// checks the range first. Data URIs and external files arrive in tinygltf's own copy.
bool load_image(tinygltf::Image* image, const int index, std::string* err, std::string*, int, int,
                const unsigned char* bytes, int size, void*) {
  if (image->bufferView >= 0) return true;
  const std::string what =
      "image " + std::to_string(index) +
      (image->uri.empty() || image->uri.rfind("data:", 0) == 0 ? std::string()
                                                               : " (\"" + image->uri + "\")");
  return decode_image(image, bytes, size_t(size), what, err);
}

class GltfReader {
 public:
  GltfReader(Scene& scene, const std::string& path, const SourceLoc& from)
      : scene_(scene),
        path_(path),
        suffix_(from.path == path ? "" : " (mesh referenced at " + from.str() + ")"),
        json_(path, suffix_) {}

  void load() {
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(&load_image, nullptr);
    std::string err, warn;
    const bool binary = path_extension_lower(path_) == ".glb";
    const bool ok = binary ? loader.LoadBinaryFromFile(&model_, &err, &warn, path_)
                           : loader.LoadASCIIFromFile(&model_, &err, &warn, path_);
    if (!ok) fail_data("cannot read glTF: " + trim(err.empty() ? warn : err));
    if (!warn.empty())
      scene_.diagnostics.warn(file(), "tinygltf: " + trim(warn) + suffix_, "continued");
    decode_buffer_images();
    json_.check_meshes(scene_.diagnostics);
    for (const std::string& ext : model_.extensionsRequired) {
      if (ext != "KHR_materials_emissive_strength" && ext != "KHR_materials_transmission" &&
          ext != "KHR_materials_ior" && ext != "KHR_texture_transform")
        approximated_.insert("required extension " + ext);
    }
  }

  void append(const mat4& xform, uint32_t material_override, CameraDesc* camera, bool* has_camera) {
    material_override_ = material_override;
    check_node_graph();
    // Per spec: the default scene, else scene 0; files without scenes get every root node.
    std::vector<int> roots;
    if (!model_.scenes.empty()) {
      int s = model_.defaultScene;
      if (s < 0 || size_t(s) >= model_.scenes.size()) s = 0;
      roots = model_.scenes[size_t(s)].nodes;
    } else {
      std::vector<bool> is_child(model_.nodes.size(), false);
      for (const tinygltf::Node& n : model_.nodes)
        for (int c : n.children) is_child[size_t(c)] = true;
      for (size_t i = 0; i < model_.nodes.size(); ++i)
        if (!is_child[i]) roots.push_back(int(i));
    }
    // Meshes that several nodes use are instanced (read once, in their own space, with an
    // instance per node), unless a material of theirs emits: emitters are world-space triangles.
    std::map<int, size_t> uses;
    walk(roots, xform, [&](const tinygltf::Node& node, const mat4&) {
      if (node.mesh >= 0) ++uses[node.mesh];
    });
    std::map<int, Instanced> instanced;
    std::vector<int> instanced_order;
    walk(roots, xform, [&](const tinygltf::Node& node, const mat4& world) {
      if (node.mesh >= 0) {
        if (uses[node.mesh] < 2 || !instance_transform_problem(world).empty()) {
          append_mesh(scene_, node.mesh, world);
        } else {
          auto [it, first] = instanced.try_emplace(node.mesh);
          Instanced& in = it->second;
          if (first) {
            Scene local;
            append_mesh(local, node.mesh, mat4(1.0f));
            in.mesh = std::move(local.mesh);
            in.emits = uses_emissive_material(scene_, in.mesh);
            if (!in.emits) instanced_order.push_back(node.mesh);
          }
          if (in.emits)
            append_part(scene_, mesh_part_of(in.mesh), world);
          else if (!in.mesh.indices.empty())
            in.placements.push_back(world);
        }
      }
      if (node.camera >= 0 && camera && !*has_camera)
        *has_camera = read_camera(node, world, camera);
    });
    for (int m : instanced_order) {
      Instanced& in = instanced[m];
      if (in.placements.empty()) continue;
      const tinygltf::Mesh& mesh = model_.meshes[size_t(m)];
      ObjectInfo info;
      info.name = base_name(path_) + " mesh " + std::to_string(m) +
                  (mesh.name.empty() ? "" : " (\"" + mesh.name + "\")");
      info.kind = "instances";
      info.is_instances = true;
      info.first = uint32_t(scene_.instances.size());
      info.count = uint32_t(in.placements.size());
      info.loc = file();
      const uint32_t index = uint32_t(scene_.instanced_meshes.size());
      scene_.instanced_meshes.push_back({info.name, std::move(in.mesh)});
      for (const mat4& w : in.placements) scene_.instances.push_back({index, w});
      scene_.objects.push_back(info);
    }
    if (!approximated_.empty()) {
      std::string list;
      for (const std::string& a : approximated_) list += (list.empty() ? "" : ", ") + a;
      scene_.diagnostics.warn(file(), "unsupported glTF features: " + list + suffix_,
                              "approximated with the closest supported materials");
    }
    if (points_or_lines_ > 0) {
      scene_.diagnostics.warn(file(),
                              std::to_string(points_or_lines_) +
                                  " primitive(s) are points or lines (mode 0-3), which have no "
                                  "surface to render" +
                                  suffix_,
                              "skipped them");
    }
    if (bad_modes_ > 0) {
      scene_.diagnostics.warn(
          file(),
          std::to_string(bad_modes_) + " primitive(s) have a mode that is not 0-6" + suffix_,
          "skipped them");
    }
    if (draco_skipped_ > 0) {
      scene_.diagnostics.warn(file(),
                              std::to_string(draco_skipped_) +
                                  " primitive(s) are compressed with KHR_draco_mesh_compression, "
                                  "which is not supported, and have no uncompressed fallback" +
                                  suffix_,
                              "skipped them");
    }
  }

 private:
  SourceLoc file() const { return {path_, 0}; }

  // A mesh that several nodes use: its triangles in its own space and the nodes' transforms.
  struct Instanced {
    TriangleMesh mesh;
    bool emits = false;
    std::vector<mat4> placements;
  };

  // Calls f(node, global transform) for every node under `roots` (placed by `xform`) in
  // depth-first order, children in their order.
  template <typename F>
  void walk(const std::vector<int>& roots, const mat4& xform, F&& f) const {
    struct Item {
      int node;
      mat4 parent;
    };
    std::vector<Item> stack;
    for (auto it = roots.rbegin(); it != roots.rend(); ++it) {
      if (*it < 0 || size_t(*it) >= model_.nodes.size())
        fail("scene refers to node " + std::to_string(*it) + ", but the file has " +
             std::to_string(model_.nodes.size()) + " nodes");
      stack.push_back({*it, xform});
    }
    // The graph is acyclic (checked before), but a DAG that shares children can still blow up
    // exponentially; cap the number of node instances.
    size_t visits = 0;
    while (!stack.empty()) {
      const Item item = stack.back();
      stack.pop_back();
      if (++visits > 1000000) fail("node hierarchy expands to more than a million node instances");
      const tinygltf::Node& node = model_.nodes[size_t(item.node)];
      const mat4 world = item.parent * local_transform(node, item.node);
      f(node, world);
      for (auto c = node.children.rbegin(); c != node.children.rend(); ++c)
        stack.push_back({*c, world});
    }
  }
  static std::string base_name(const std::string& path) {
    const size_t slash = path.find_last_of('/');
    return slash == std::string::npos ? path : path.substr(slash + 1);
  }
  [[noreturn]] void fail(const std::string& problem) const {
    throw InputError(file(), problem + suffix_);
  }
  // A problem with the geometry or image data. A file that uses a compression extension without
  // requiring it must carry uncompressed data as well; where that cannot be read, the extension
  // is the likely cause and is named first.
  [[noreturn]] void fail_data(const std::string& problem) const {
    const std::string& ext = json_.compression();
    if (ext.empty()) fail(problem);
    fail("the file uses " + ext + " (" + GltfJson::compression_what(ext) +
         "), which is not supported, and its uncompressed fallback cannot be read: " + problem);
  }
  static std::string trim(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    for (char& c : s)
      if (c == '\n') c = ' ';
    return s;
  }

  // Iterative three-colour DFS over all nodes: bad child indices and cycles are errors.
  void check_node_graph() const {
    const size_t n = model_.nodes.size();
    std::vector<uint8_t> state(n, 0);  // 0 new, 1 on the current path, 2 done
    for (size_t root = 0; root < n; ++root) {
      if (state[root]) continue;
      std::vector<std::pair<size_t, size_t>> stack = {{root, 0}};  // node, next child
      state[root] = 1;
      while (!stack.empty()) {
        auto& [node, next] = stack.back();
        const std::vector<int>& kids = model_.nodes[node].children;
        if (next == kids.size()) {
          state[node] = 2;
          stack.pop_back();
          continue;
        }
        const int c = kids[next++];
        if (c < 0 || size_t(c) >= n)
          fail("node " + std::to_string(node) + " has child " + std::to_string(c) +
               ", but the file has " + std::to_string(n) + " nodes");
        if (state[size_t(c)] == 1)
          fail("node hierarchy has a cycle (node " + std::to_string(node) + " -> node " +
               std::to_string(c) + ")");
        if (state[size_t(c)] == 0) {
          state[size_t(c)] = 1;
          stack.push_back({size_t(c), 0});
        }
      }
    }
  }

  // Decodes the images stored in buffer views (GLB and most exporters), range-checked first.
  void decode_buffer_images() {
    for (size_t i = 0; i < model_.images.size(); ++i) {
      tinygltf::Image& image = model_.images[i];
      if (image.bufferView < 0 || !image.image.empty()) continue;
      const std::string what = "image " + std::to_string(i);
      if (size_t(image.bufferView) >= model_.bufferViews.size())
        fail_data(what + " refers to buffer view " + std::to_string(image.bufferView) +
                  ", which does not exist");
      const tinygltf::BufferView& view = model_.bufferViews[size_t(image.bufferView)];
      if (view.buffer < 0 || size_t(view.buffer) >= model_.buffers.size())
        fail_data(what + ": buffer view refers to buffer " + std::to_string(view.buffer) +
                  ", which does not exist");
      const std::vector<unsigned char>& data = model_.buffers[size_t(view.buffer)].data;
      if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset)
        fail_data(what + ": buffer view runs past the end of its " + std::to_string(data.size()) +
                  "-byte buffer");
      std::string err;
      if (!decode_image(&image, data.data() + view.byteOffset, view.byteLength, what, &err))
        fail(trim(err));
    }
  }

  // The scene texture for glTF texture `index` decoded as sRGB colour or as linear data and
  // looked up through `transform`; each (texture, encoding, transform) is converted once (a
  // transform a material's textures share is baked into the uvs instead, so that materials
  // that tile one image differently share its texels). kInvalid, with a warning, when its image
  // could not be loaded.
  uint32_t texture(int index, bool srgb, const glm::mat3x2& transform, const std::string& what) {
    if (index < 0) return kInvalid;
    if (size_t(index) >= model_.textures.size())
      fail(what + " refers to texture " + std::to_string(index) + ", which does not exist");
    std::array<float, 6> t6;
    for (int c = 0; c < 3; ++c) {
      t6[size_t(2 * c)] = transform[c].x;
      t6[size_t(2 * c + 1)] = transform[c].y;
    }
    const auto key = std::make_tuple(index, srgb, t6);
    auto found = textures_.find(key);
    if (found != textures_.end()) return found->second;
    const tinygltf::Texture& t = model_.textures[size_t(index)];
    if (t.source >= 0 && size_t(t.source) >= model_.images.size())
      fail("texture " + std::to_string(index) + " refers to image " + std::to_string(t.source) +
           ", which does not exist");
    // No source: the image is only in an extension (KHR_texture_basisu, EXT_texture_webp).
    static const tinygltf::Image kNoImage;
    const tinygltf::Image& image = t.source >= 0 ? model_.images[size_t(t.source)] : kNoImage;
    uint32_t id = kInvalid;
    if (image.image.empty() || image.component != 4 || image.bits != 8) {
      scene_.diagnostics.warn(file(),
                              "image " + std::to_string(t.source) +
                                  (image.uri.empty() ? "" : " (\"" + image.uri + "\")") +
                                  " could not be loaded" + suffix_,
                              "rendered " + what + " without it");
    } else {
      TextureImage ti;
      ti.width = image.width;
      ti.height = image.height;
      ti.rgba8 = image.image;
      ti.srgb = srgb;
      ti.uv_transform = transform;
      ti.source = image.uri.empty() || image.uri.rfind("data:", 0) == 0
                      ? path_
                      : path_join(path_directory(path_), image.uri);
      if (t.sampler >= 0) {
        if (size_t(t.sampler) >= model_.samplers.size())
          fail("texture " + std::to_string(index) + " refers to sampler " +
               std::to_string(t.sampler) + ", which does not exist");
        const tinygltf::Sampler& sm = model_.samplers[size_t(t.sampler)];
        ti.wrap_s = wrap_mode(sm.wrapS);
        ti.wrap_t = wrap_mode(sm.wrapT);
      }
      scene_.textures.push_back(std::move(ti));
      id = uint32_t(scene_.textures.size() - 1);
    }
    textures_[key] = id;
    return id;
  }

  static TextureWrap wrap_mode(int gl) {
    switch (gl) {
      case TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE:
        return TextureWrap::kClampToEdge;
      case TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT:
        return TextureWrap::kMirroredRepeat;
      default:
        return TextureWrap::kRepeat;
    }
  }

  // TEXCOORD_n: floats, or normalized unsigned bytes/shorts (glTF 2.0 sec. 3.7.2.1).
  std::vector<vec2> read_uvs(int index, const std::string& what) const {
    const tinygltf::Accessor& a = accessor(index, what);
    size_t size = 0;
    if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT)
      size = 4;
    else if (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && a.normalized)
      size = 1;
    else if (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT && a.normalized)
      size = 2;
    if (a.type != TINYGLTF_TYPE_VEC2 || size == 0)
      fail_data(what + " must be a VEC2 of floats or normalized unsigned bytes or shorts");
    std::vector<vec2> out(a.count, vec2(0.0f));
    if (a.count == 0) return out;
    size_t stride = 0;
    const unsigned char* p = accessor_data(a, size * 2, &stride, what);
    if (!p) return out;
    for (size_t i = 0; i < a.count; ++i) {
      const unsigned char* e = p + i * stride;
      for (int c = 0; c < 2; ++c) {
        if (size == 4) {
          std::memcpy(&out[i][c], e + 4 * c, 4);
        } else if (size == 2) {
          uint16_t v;
          std::memcpy(&v, e + 2 * c, 2);
          out[i][c] = float(v) / 65535.0f;
        } else {
          out[i][c] = float(e[c]) / 255.0f;
        }
      }
    }
    return out;
  }

  mat4 local_transform(const tinygltf::Node& n, int index) const {
    const std::string where = "node " + std::to_string(index);
    auto finite = [&](const std::vector<double>& v, size_t size, const char* what) {
      if (!v.empty() && v.size() != size)
        fail(where + " has a " + what + " of " + std::to_string(v.size()) + " numbers, not " +
             std::to_string(size));
      for (double d : v)
        if (!std::isfinite(d)) fail(where + " has a non-finite " + what);
      return !v.empty();
    };
    if (finite(n.matrix, 16, "matrix")) {
      mat4 m;
      for (int i = 0; i < 16; ++i)
        glm::value_ptr(m)[i] = float(n.matrix[size_t(i)]);  // column-major
      return m;
    }
    mat4 m(1.0f);
    if (finite(n.translation, 3, "translation"))
      m[3] = vec4(float(n.translation[0]), float(n.translation[1]), float(n.translation[2]), 1.0f);
    if (finite(n.rotation, 4, "rotation")) {
      // glTF stores quaternions as x, y, z, w; glm's constructor takes w first.
      glm::quat q(float(n.rotation[3]), float(n.rotation[0]), float(n.rotation[1]),
                  float(n.rotation[2]));
      if (glm::length(q) == 0.0f) fail(where + " has a zero rotation quaternion");
      m = m * glm::mat4_cast(glm::normalize(q));
    }
    if (finite(n.scale, 3, "scale")) {
      m[0] *= float(n.scale[0]);
      m[1] *= float(n.scale[1]);
      m[2] *= float(n.scale[2]);
    }
    return m;
  }

  // Byte range of an accessor, checked against its buffer view and buffer. Returns nullptr for an
  // accessor without a buffer view (all zeros per spec) and sets *stride.
  const unsigned char* accessor_data(const tinygltf::Accessor& a, size_t elem_size, size_t* stride,
                                     const std::string& what) const {
    if (a.sparse.isSparse) fail_data(what + " uses a sparse accessor, which is not supported");
    if (a.bufferView < 0) return nullptr;
    if (size_t(a.bufferView) >= model_.bufferViews.size())
      fail_data(what + " refers to buffer view " + std::to_string(a.bufferView) +
                ", which does not exist");
    const tinygltf::BufferView& view = model_.bufferViews[size_t(a.bufferView)];
    if (view.buffer < 0 || size_t(view.buffer) >= model_.buffers.size())
      fail_data(what + ": buffer view refers to buffer " + std::to_string(view.buffer) +
                ", which does not exist");
    const std::vector<unsigned char>& data = model_.buffers[size_t(view.buffer)].data;
    *stride = view.byteStride ? view.byteStride : elem_size;
    if (*stride < elem_size)
      fail_data(what + ": byte stride " + std::to_string(*stride) + " is smaller than an element");
    // All in 64 bits with explicit overflow guards: count and offsets come from the file.
    const uint64_t limit = uint64_t(1) << 40;
    if (a.count > limit || view.byteOffset > limit || view.byteLength > limit ||
        a.byteOffset > limit)
      fail_data(what + " has absurd sizes");
    if (view.byteOffset + view.byteLength > data.size())
      fail_data(what + ": buffer view (bytes " + std::to_string(view.byteOffset) + ".." +
                std::to_string(view.byteOffset + view.byteLength) + ") runs past the end of its " +
                std::to_string(data.size()) + "-byte buffer");
    const uint64_t end = uint64_t(a.byteOffset) + uint64_t(*stride) * (a.count - 1) + elem_size;
    if (end > view.byteLength)
      fail_data(what + ": accessor needs " + std::to_string(end) +
                " bytes but its buffer view has " + std::to_string(view.byteLength));
    return data.data() + view.byteOffset + a.byteOffset;
  }

  const tinygltf::Accessor& accessor(int index, const std::string& what) const {
    if (index < 0 || size_t(index) >= model_.accessors.size())
      fail_data(what + " refers to accessor " + std::to_string(index) + ", which does not exist");
    return model_.accessors[size_t(index)];
  }

  std::vector<vec3> read_vec3(int index, const std::string& what) const {
    const tinygltf::Accessor& a = accessor(index, what);
    if (a.type != TINYGLTF_TYPE_VEC3 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
      fail_data(what + " must be a VEC3 of floats");
    std::vector<vec3> out(a.count, vec3(0.0f));
    if (a.count == 0) return out;
    size_t stride = 0;
    const unsigned char* p = accessor_data(a, sizeof(float) * 3, &stride, what);
    if (!p) return out;
    for (size_t i = 0; i < a.count; ++i) std::memcpy(&out[i], p + i * stride, sizeof(float) * 3);
    return out;
  }

  std::vector<uint32_t> read_indices(int index, const std::string& what) const {
    const tinygltf::Accessor& a = accessor(index, what);
    size_t size = 0;
    switch (a.componentType) {
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
        size = 1;
        break;
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
        size = 2;
        break;
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
        size = 4;
        break;
      default:
        fail_data(what + " must be unsigned 8, 16 or 32-bit integers");
    }
    if (a.type != TINYGLTF_TYPE_SCALAR) fail_data(what + " must be SCALAR");
    std::vector<uint32_t> out(a.count, 0);
    if (a.count == 0) return out;
    size_t stride = 0;
    const unsigned char* p = accessor_data(a, size, &stride, what);
    if (!p) return out;
    for (size_t i = 0; i < a.count; ++i) {
      const unsigned char* e = p + i * stride;
      if (size == 1) {
        out[i] = *e;
      } else if (size == 2) {
        uint16_t v;
        std::memcpy(&v, e, 2);
        out[i] = v;
      } else {
        std::memcpy(&out[i], e, 4);
      }
    }
    return out;
  }

  static double ext_number(const tinygltf::ExtensionMap& exts, const char* ext, const char* key,
                           double def) {
    auto it = exts.find(ext);
    if (it == exts.end() || !it->second.Has(key) || !it->second.Get(key).IsNumber()) return def;
    return it->second.Get(key).GetNumberAsDouble();
  }

  // A scene material, and the texture coordinates a primitive that uses it must carry.
  struct MaterialUse {
    uint32_t id = kInvalid;
    int uv_set = 0;                           // the TEXCOORD_n its textures read
    glm::mat3x2 uv_bake = glm::mat3x2(1.0f);  // applied to the primitive's uvs
  };

  // Material `index`'s textureInfo in `slot`, as the file writes it.
  GltfTextureRef texture_ref(int index, GltfSlot slot) {
    if (json_.material_count() == model_.materials.size())
      return json_.texture(size_t(index), slot, model_.textures.size(), scene_.diagnostics);
    // The JSON pass could not read what tinygltf did: tinygltf's fields, untransformed.
    if (std::count(model_.extensionsUsed.begin(), model_.extensionsUsed.end(),
                   "KHR_texture_transform"))
      approximated_.insert("KHR_texture_transform (the JSON could not be read a second time)");
    const tinygltf::Material& g = model_.materials[size_t(index)];
    const tinygltf::PbrMetallicRoughness& pbr = g.pbrMetallicRoughness;
    GltfTextureRef ref;
    switch (slot) {
      case GltfSlot::kBaseColor:
        std::tie(ref.index, ref.tex_coord) =
            std::tie(pbr.baseColorTexture.index, pbr.baseColorTexture.texCoord);
        break;
      case GltfSlot::kMetallicRoughness:
        std::tie(ref.index, ref.tex_coord) =
            std::tie(pbr.metallicRoughnessTexture.index, pbr.metallicRoughnessTexture.texCoord);
        break;
      case GltfSlot::kEmissive:
        std::tie(ref.index, ref.tex_coord) =
            std::tie(g.emissiveTexture.index, g.emissiveTexture.texCoord);
        break;
      case GltfSlot::kNormal:
        std::tie(ref.index, ref.tex_coord) =
            std::tie(g.normalTexture.index, g.normalTexture.texCoord);
        break;
    }
    return ref;
  }

  const MaterialUse& material(int index) {
    if (material_override_ != kInvalid) {
      override_use_.id = material_override_;
      return override_use_;
    }
    if (index < 0 || size_t(index) >= model_.materials.size()) {
      if (index >= 0) {
        scene_.diagnostics.warn(file(),
                                "a primitive refers to material " + std::to_string(index) +
                                    ", which does not exist" + suffix_,
                                "used grey diffuse");
      }
      if (default_use_.id == kInvalid)
        default_use_.id = scene_.add_material("default grey", Material());
      return default_use_;
    }
    auto found = materials_.find(index);
    if (found != materials_.end()) return found->second;
    json_.check_material(size_t(index), scene_.diagnostics);
    const tinygltf::Material& g = model_.materials[size_t(index)];
    const tinygltf::PbrMetallicRoughness& pbr = g.pbrMetallicRoughness;
    Material m;
    vec3 base(1.0f);
    if (pbr.baseColorFactor.size() >= 3)
      base = vec3(float(pbr.baseColorFactor[0]), float(pbr.baseColorFactor[1]),
                  float(pbr.baseColorFactor[2]));
    base = glm::clamp(is_finite(base) ? base : vec3(0.8f), vec3(0.0f), vec3(1.0f));
    if (g.emissiveFactor.size() >= 3) {
      const float strength = float(
          ext_number(g.extensions, "KHR_materials_emissive_strength", "emissiveStrength", 1.0));
      m.emission = strength * vec3(float(g.emissiveFactor[0]), float(g.emissiveFactor[1]),
                                   float(g.emissiveFactor[2]));
      if (!is_finite(m.emission)) fail("material \"" + g.name + "\" has a non-finite emission");
      m.emission = glm::max(m.emission, vec3(0.0f));
    }
    const double transmission =
        ext_number(g.extensions, "KHR_materials_transmission", "transmissionFactor", 0.0);
    const float roughness = float(std::clamp(pbr.roughnessFactor, 0.0, 1.0));
    const double diffuse_transmission = ext_number(
        g.extensions, "KHR_materials_diffuse_transmission", "diffuseTransmissionFactor", 0.0);
    const float ior = float(ext_number(g.extensions, "KHR_materials_ior", "ior", 1.5));
    const bool volume = g.extensions.count("KHR_materials_volume") > 0;
    // KHR_materials_volume: light fades to attenuationColor over attenuationDistance.
    const double att_distance =
        ext_number(g.extensions, "KHR_materials_volume", "attenuationDistance", 0.0);
    vec3 att_colour(1.0f);
    if (volume) {
      const auto it = g.extensions.find("KHR_materials_volume");
      if (it->second.Has("attenuationColor") && it->second.Get("attenuationColor").IsArray() &&
          it->second.Get("attenuationColor").ArrayLen() == 3) {
        for (int c = 0; c < 3; ++c)
          att_colour[c] = float(it->second.Get("attenuationColor").Get(c).GetNumberAsDouble());
      }
    }
    if ((transmission > 0.0 && volume && att_distance > 0.0) || diffuse_transmission > 0.0) {
      // A scattering volume: subsurface random walk. The base colour is the surface colour and
      // the attenuation distance the mean free path (the artist's pair of JSON scenes).
      m.type = MaterialType::kSubsurface;
      m.ior = ior >= 1.0f && ior <= 4.0f ? ior : 1.5f;
      const vec3 colour = volume ? glm::clamp(att_colour, vec3(0.0f), vec3(1.0f)) : base;
      const float mfp = att_distance > 0.0 ? float(att_distance) : 1.0f;
      vec3 single;
      for (int c = 0; c < 3; ++c) single[c] = albedo_from_surface_colour(colour[c]);
      m.scattering = single / mfp;
      m.absorption = vec3(1.0f / mfp) - m.scattering;
      m.albedo = vec3(1.0f);
      if (att_distance <= 0.0) approximated_.insert("diffuse transmission without a distance");
    } else if (transmission > 0.0) {
      m.type = MaterialType::kDielectric;
      m.albedo = base;
      m.roughness = roughness;
      m.ior = ior > 1.0f && ior <= 4.0f ? ior : 1.5f;
      if (ior != m.ior) approximated_.insert("ior outside (1, 4]");
      if (transmission < 1.0) approximated_.insert("partial transmission");
      if (volume && att_distance > 0.0) {  // absorbing glass: Beer-Lambert
        m.absorption = -glm::log(glm::max(att_colour, vec3(1e-6f))) / float(att_distance);
      }
    } else if (pbr.metallicFactor >= 0.5) {
      // glTF's metallic-roughness model: a GGX conductor with F0 = base colour.
      m.type = MaterialType::kConductor;
      m.albedo = base;
      m.roughness = roughness;
      if (pbr.metallicFactor < 1.0) approximated_.insert("metallic between 0.5 and 1");
    } else {
      m.albedo = base;
      if (pbr.metallicFactor > 0.0) approximated_.insert("metallic below 0.5");
      // A shiny non-metal's specular layer is missing; a rough one looks diffuse anyway.
      if (pbr.roughnessFactor < 0.5) approximated_.insert("glossy dielectric layer");
    }
    const std::string mname =
        g.name.empty() ? "material " + std::to_string(index) : "material \"" + g.name + "\"";
    MaterialUse use;
    if (read_textures(index, mname, m, &use)) {
      m.metallic = float(std::clamp(pbr.metallicFactor, 0.0, 1.0));
      m.roughness = roughness;  // scaled by the texture's G channel per texel
    }
    m.normal_scale = std::isfinite(g.normalTexture.scale) ? float(g.normalTexture.scale) : 1.0f;
    if (g.occlusionTexture.index >= 0) approximated_.insert("occlusion texture (ignored)");
    if (!g.alphaMode.empty() && g.alphaMode != "OPAQUE") approximated_.insert("alphaMode");
    for (const auto& e : g.extensions) {
      if (e.first != "KHR_materials_emissive_strength" && e.first != "KHR_materials_transmission" &&
          e.first != "KHR_materials_ior" && e.first != "KHR_materials_volume" &&
          e.first != "KHR_materials_diffuse_transmission")
        approximated_.insert(e.first);
    }
    const std::string name = g.name.empty() ? "material " + std::to_string(index) : g.name;
    use.id = scene_.add_material(name, m);
    return materials_[index] = use;
  }

  // Fills m's texture slots. A primitive carries one uv set, so the slots share the first used
  // slot's set (a warning where they differ). A transform every used slot shares is baked into
  // the primitive's uvs (use->uv_bake), so the images stay shared with materials that transform
  // them differently; otherwise each texture use carries its own transform. Returns whether the
  // material names a metallic-roughness texture (loaded or not).
  bool read_textures(int index, const std::string& mname, Material& m, MaterialUse* use) {
    struct Slot {
      GltfSlot slot;
      bool srgb;
      uint32_t* target;
      const char* what;
      GltfTextureRef ref;
    };
    Slot slots[] = {
        {GltfSlot::kBaseColor, true, &m.base_color_tex, "base colour", {}},
        {GltfSlot::kMetallicRoughness, false, &m.metal_rough_tex, "metallic-roughness", {}},
        {GltfSlot::kEmissive, true, &m.emissive_tex, "emissive", {}},
        {GltfSlot::kNormal, false, &m.normal_tex, "normal", {}}};
    std::vector<Slot*> used;
    for (Slot& s : slots) {
      s.ref = texture_ref(index, s.slot);
      if (s.ref.index < 0) continue;
      if (s.slot == GltfSlot::kBaseColor && m.type == MaterialType::kSubsurface) {
        approximated_.insert("base colour texture on a scattering volume (ignored)");
        continue;
      }
      for (const std::string& e : s.ref.ignored_extensions)
        approximated_.insert("texture extension " + e + " (ignored)");
      used.push_back(&s);
    }
    const bool metal_rough = slots[1].ref.index >= 0;
    if (used.empty()) return metal_rough;
    use->uv_set = used[0]->ref.tex_coord;
    bool shared = true;
    std::set<int> sets;
    for (const Slot* s : used) {
      sets.insert(s->ref.tex_coord);
      shared &= s->ref.transform == used[0]->ref.transform;
    }
    if (sets.size() > 1) {
      std::string list;
      size_t n = 0;
      for (int set : sets)
        list += (n++ == 0 ? "" : n == sets.size() ? " and " : ", ") + std::to_string(set);
      scene_.diagnostics.warn(file(),
                              mname + "'s textures read texture coordinate sets " + list +
                                  ", but a primitive carries one set" + suffix_,
                              "used set " + std::to_string(use->uv_set) + " (the " + used[0]->what +
                                  " texture's) for all of them");
    }
    if (shared) use->uv_bake = used[0]->ref.transform;
    for (const Slot* s : used) {
      *s->target = texture(s->ref.index, s->srgb, shared ? glm::mat3x2(1.0f) : s->ref.transform,
                           mname + " " + s->what);
    }
    return metal_rough;
  }

  // Appends the mesh's primitives to `target`'s mesh (the scene's, or a mesh of its own for
  // instancing); materials, textures and warnings go to the scene.
  void append_mesh(Scene& target, int mesh_index, const mat4& world) {
    if (size_t(mesh_index) >= model_.meshes.size())
      fail("a node refers to mesh " + std::to_string(mesh_index) + ", which does not exist");
    const tinygltf::Mesh& mesh = model_.meshes[size_t(mesh_index)];
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = mesh.primitives[pi];
      const std::string what = "mesh " + std::to_string(mesh_index) +
                               (mesh.name.empty() ? "" : " (\"" + mesh.name + "\")") +
                               " primitive " + std::to_string(pi);
      const int mode = prim.mode == -1 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode >= TINYGLTF_MODE_POINTS && mode < TINYGLTF_MODE_TRIANGLES) {
        ++points_or_lines_;
        continue;
      }
      if (mode < TINYGLTF_MODE_POINTS || mode > TINYGLTF_MODE_TRIANGLE_FAN) {
        ++bad_modes_;
        continue;
      }
      auto pos = prim.attributes.find("POSITION");
      if (pos == prim.attributes.end()) {
        scene_.diagnostics.warn(file(), what + " has no POSITION" + suffix_, "skipped it");
        continue;
      }
      // A Draco primitive's accessors are the uncompressed fallback where they have buffer views
      // (the extension not required); without, they would read as zeros.
      if (prim.extensions.count("KHR_draco_mesh_compression") &&
          accessor(pos->second, what + " POSITION").bufferView < 0) {
        ++draco_skipped_;
        continue;
      }
      MeshPart part;
      part.positions = read_vec3(pos->second, what + " POSITION");
      for (const vec3& p : part.positions)
        if (!is_finite(p)) fail_data(what + " has a non-finite vertex position " + vec3_str(p));
      auto nrm = prim.attributes.find("NORMAL");
      if (nrm != prim.attributes.end()) {
        part.normals = read_vec3(nrm->second, what + " NORMAL");
        bool good = part.normals.size() == part.positions.size();
        for (const vec3& n : part.normals) good &= is_finite(n) && glm::length(n) > 0.0f;
        if (!good) {
          scene_.diagnostics.warn(file(),
                                  what + " has missing, non-finite or zero normals" + suffix_,
                                  "used flat shading");
          part.normals.clear();
        }
      }
      std::vector<uint32_t> idx;
      if (prim.indices >= 0) {
        idx = read_indices(prim.indices, what + " indices");
        for (size_t i = 0; i < idx.size(); ++i)
          if (idx[i] >= part.positions.size())
            fail_data(what + ": index " + std::to_string(idx[i]) + " (at position " +
                      std::to_string(i) + ") is out of range; the primitive has " +
                      std::to_string(part.positions.size()) + " vertices");
      } else {
        idx.resize(part.positions.size());
        for (size_t i = 0; i < idx.size(); ++i) idx[i] = uint32_t(i);
      }
      if (idx.empty()) continue;
      part.indices = triangles(mode, idx, what);
      if (part.indices.empty()) continue;
      const MaterialUse& mat = material(prim.material);
      part.materials.assign(part.indices.size(), mat.id);
      read_primitive_uvs(prim, mat, what, &part);
      append_part(target, part, world);
    }
  }

  // The triangle list of a primitive's vertex sequence (glTF 2.0 sec. 3.7.2.1, "Topology
  // types"): triangles as they are; strips as {v_i, v_i+(1+i%2), v_i+(2-i%2)}, which swaps the
  // last two of every odd triangle so that all keep the first one's winding; fans as
  // {v_i+1, v_i+2, v_0}. A strip's or fan's triangles with a repeated vertex are the joins of
  // stitched strips, not surfaces: dropped.
  std::vector<uvec3> triangles(int mode, const std::vector<uint32_t>& idx,
                               const std::string& what) const {
    std::vector<uvec3> out;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      if (idx.size() % 3 != 0)
        fail_data(what + " has " + std::to_string(idx.size()) + " indices, not a multiple of 3");
      for (size_t i = 0; i < idx.size(); i += 3)
        out.push_back(uvec3(idx[i], idx[i + 1], idx[i + 2]));
      return out;
    }
    const bool strip = mode == TINYGLTF_MODE_TRIANGLE_STRIP;
    if (idx.size() < 3)
      fail_data(what + " is a triangle " + (strip ? "strip" : "fan") + " of " +
                std::to_string(idx.size()) + " vertices, fewer than 3");
    out.reserve(idx.size() - 2);
    for (size_t i = 0; i + 2 < idx.size(); ++i) {
      uvec3 t;
      if (strip)
        t = i % 2 == 0 ? uvec3(idx[i], idx[i + 1], idx[i + 2])
                       : uvec3(idx[i], idx[i + 2], idx[i + 1]);
      else
        t = uvec3(idx[i + 1], idx[i + 2], idx[0]);
      if (t.x != t.y && t.y != t.z && t.z != t.x) out.push_back(t);
    }
    return out;
  }

  // The uvs of the set the primitive's material reads, through the transform its textures share.
  void read_primitive_uvs(const tinygltf::Primitive& prim, const MaterialUse& mat,
                          const std::string& what, MeshPart* part) {
    std::string set = "TEXCOORD_" + std::to_string(mat.uv_set);
    auto uv = prim.attributes.find(set);
    if (uv == prim.attributes.end() && mat.uv_set != 0) {
      const auto first = prim.attributes.find("TEXCOORD_0");
      scene_.diagnostics.warn(
          file(), what + " has no " + set + ", which its material's textures read" + suffix_,
          first == prim.attributes.end() ? "rendered it untextured" : "used TEXCOORD_0");
      uv = first;
      set = "TEXCOORD_0";
    }
    if (uv == prim.attributes.end()) return;
    part->uvs = read_uvs(uv->second, what + " " + set);
    bool good = part->uvs.size() == part->positions.size();
    for (const vec2& t : part->uvs) good &= std::isfinite(t.x) && std::isfinite(t.y);
    if (!good) {
      scene_.diagnostics.warn(file(), what + " has a wrong count of or non-finite " + set + suffix_,
                              "rendered it untextured");
      part->uvs.clear();
    }
    if (mat.uv_bake != glm::mat3x2(1.0f))
      for (vec2& t : part->uvs) t = mat.uv_bake * vec3(t, 1.0f);
  }

  bool read_camera(const tinygltf::Node& node, const mat4& world, CameraDesc* cam) {
    if (size_t(node.camera) >= model_.cameras.size()) {
      scene_.diagnostics.warn(file(),
                              "a node refers to camera " + std::to_string(node.camera) +
                                  ", which does not exist" + suffix_,
                              "ignored it");
      return false;
    }
    const tinygltf::Camera& c = model_.cameras[size_t(node.camera)];
    const double yfov = c.perspective.yfov;
    if (c.type != "perspective" || !(yfov > 0.0 && yfov < kPi)) {
      scene_.diagnostics.warn(
          file(),
          "camera " + std::to_string(node.camera) + " is not a usable perspective camera" + suffix_,
          "framed the model with a default camera");
      return false;
    }
    // glTF cameras look down their local -Z with +Y up.
    const vec3 pos = vec3(world * vec4(0, 0, 0, 1));
    const vec3 fwd = mat3(world) * vec3(0, 0, -1);
    const vec3 up = mat3(world) * vec3(0, 1, 0);
    if (!is_finite(pos) || glm::length(fwd) == 0.0f || glm::length(glm::cross(fwd, up)) == 0.0f) {
      scene_.diagnostics.warn(file(), "camera node transform is degenerate" + suffix_,
                              "framed the model with a default camera");
      return false;
    }
    *cam = CameraDesc();
    cam->position = pos;
    cam->look_at = pos + glm::normalize(fwd);
    cam->up = glm::normalize(up);
    cam->vfov_deg = float(glm::degrees(yfov));
    return true;
  }

  Scene& scene_;
  const std::string& path_;
  std::string suffix_;
  GltfJson json_;
  tinygltf::Model model_;
  uint32_t material_override_ = kInvalid;
  MaterialUse default_use_, override_use_;
  std::map<int, MaterialUse> materials_;
  // (glTF texture, sRGB, uv transform) -> scene texture
  std::map<std::tuple<int, bool, std::array<float, 6>>, uint32_t> textures_;
  std::set<std::string> approximated_;
  int points_or_lines_ = 0, bad_modes_ = 0, draco_skipped_ = 0;
};

}  // namespace

void append_gltf_file(Scene& scene, const std::string& path, const mat4& xform,
                      uint32_t material_override, const SourceLoc& from, CameraDesc* camera,
                      bool* has_camera) {
  bool found = false;
  GltfReader reader(scene, path, from);
  reader.load();
  reader.append(xform, material_override, camera, has_camera ? has_camera : &found);
}

}  // namespace tracer
