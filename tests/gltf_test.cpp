// The glTF loader on files the tests write themselves (JSON plus base64 buffers and PNGs):
// KHR_texture_transform against the spec's matrix and through texel lookups, triangle strips and
// fans, glTF 1.0 and compressed files named as such, and wrongly typed members warned with their
// JSON pointer. Debian's assimp-testmodels files are checked too where installed.
#include <gtest/gtest.h>
#include <stb_image_write.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "integrator/textured.h"
#include "scene/gltf_json.h"
#include "scene/loader.h"
#include "scene_builders.h"
#include "test_util.h"

namespace {
using namespace tracer;
using nlohmann::json;
namespace fs = std::filesystem;

const fs::path kAssimp = "/usr/share/assimp/models";

struct TempDir {
  std::string path;
  TempDir() {
    char tmpl[] = "/tmp/gltf_test_XXXXXX";
    path = mkdtemp(tmpl);
  }
  ~TempDir() { fs::remove_all(path); }
};

std::string base64(const std::string& bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t n = uint32_t(uint8_t(bytes[i])) << 16;
    if (i + 1 < bytes.size()) n |= uint32_t(uint8_t(bytes[i + 1])) << 8;
    if (i + 2 < bytes.size()) n |= uint32_t(uint8_t(bytes[i + 2]));
    out += k[(n >> 18) & 63];
    out += k[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? k[(n >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? k[n & 63] : '=';
  }
  return out;
}

std::string png_data_uri(int w, int h, const std::vector<uint8_t>& rgba) {
  std::string png;
  stbi_write_png_to_func(
      [](void* ctx, void* data, int size) {
        static_cast<std::string*>(ctx)->append(static_cast<const char*>(data), size_t(size));
      },
      &png, w, h, 4, rgba.data(), w * 4);
  return "data:image/png;base64," + base64(png);
}

// A glTF 2.0 document with one embedded buffer, built up accessor by accessor.
struct GltfBuilder {
  json j = {{"asset", {{"version", "2.0"}}},
            {"scene", 0},
            {"scenes", {{{"nodes", json::array()}}}},
            {"nodes", json::array()},
            {"meshes", json::array()},
            {"accessors", json::array()},
            {"bufferViews", json::array()}};
  std::string bin;

  int accessor(const void* data, size_t bytes, int component_type, const char* type, size_t count) {
    while (bin.size() % 4) bin.push_back('\0');
    j["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes}});
    bin.append(static_cast<const char*>(data), bytes);
    j["accessors"].push_back({{"bufferView", j["bufferViews"].size() - 1},
                              {"componentType", component_type},
                              {"type", type},
                              {"count", count}});
    return int(j["accessors"].size() - 1);
  }
  int positions(const std::vector<vec3>& p) {
    const int a = accessor(p.data(), p.size() * 12, 5126, "VEC3", p.size());
    vec3 lo(1e30f), hi(-1e30f);
    for (const vec3& v : p) lo = glm::min(lo, v), hi = glm::max(hi, v);
    j["accessors"][size_t(a)]["min"] = {lo.x, lo.y, lo.z};
    j["accessors"][size_t(a)]["max"] = {hi.x, hi.y, hi.z};
    return a;
  }
  int uvs(const std::vector<vec2>& t) {
    return accessor(t.data(), t.size() * 8, 5126, "VEC2", t.size());
  }
  int indices(const std::vector<uint32_t>& i) {
    return accessor(i.data(), i.size() * 4, 5125, "SCALAR", i.size());
  }
  // A mesh of one primitive, instanced by a new root node.
  void primitive(json prim) {
    j["meshes"].push_back({{"primitives", {prim}}});
    j["nodes"].push_back({{"mesh", j["meshes"].size() - 1}});
    j["scenes"][0]["nodes"].push_back(j["nodes"].size() - 1);
  }
  std::string write(const TempDir& dir, const std::string& name = "test.gltf") {
    j["buffers"] = {{{"byteLength", bin.size()},
                     {"uri", "data:application/octet-stream;base64," + base64(bin)}}};
    const std::string path = dir.path + "/" + name;
    std::ofstream(path) << j.dump(2);
    return path;
  }
};

std::string load_error(const std::string& path) {
  try {
    load_scene(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

bool has_warning(const Scene& s, const std::string& text) {
  for (const std::string& w : s.diagnostics.warnings)
    if (w.find(text) != std::string::npos) return true;
  return false;
}

std::string warnings(const Scene& s) {
  std::string all;
  for (const std::string& w : s.diagnostics.warnings) all += w + "\n";
  return all;
}

// The unit quad z = 0, x and y in [0, 1], with uv = (x, y), facing +z.
const std::vector<vec3> kQuad = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
const std::vector<vec2> kQuadUv = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
const std::vector<uint32_t> kQuadIdx = {0, 1, 2, 0, 2, 3};

// A 4x4 sRGB image whose texel (x, y) is (40 + 50x, 40 + 50y, 200).
std::vector<uint8_t> grid_texels() {
  std::vector<uint8_t> px;
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x)
      px.insert(px.end(), {uint8_t(40 + 50 * x), uint8_t(40 + 50 * y), 200, 255});
  return px;
}
vec3 grid_colour(int x, int y) {
  return vec3(srgb_to_linear((40 + 50 * x) / 255.0f), srgb_to_linear((40 + 50 * y) / 255.0f),
              srgb_to_linear(200 / 255.0f));
}

json transform(vec2 offset, float rotation, vec2 scale) {
  return {
      {"KHR_texture_transform",
       {{"offset", {offset.x, offset.y}}, {"rotation", rotation}, {"scale", {scale.x, scale.y}}}}};
}

// Material `m` of a one-quad glTF at the surface point (x, y): textures applied as the renderer
// applies them.
struct Shaded {
  Material m;
  SurfaceHit sh;
};
Shaded shade_at(const Scene& s, float x, float y) {
  const CompiledScene cs(s, 4, 4);
  EXPECT_TRUE(cs.features() & kFeatureTextures);
  const Ray ray{vec3(x, y, 1.0f), kInfinity, vec3(0, 0, -1), 0.0f};
  const Hit hit = intersect_closest(cs.view(), ray);
  EXPECT_TRUE(hit.valid());
  Shaded out;
  out.sh = make_surface_hit(cs.view(), ray, hit);
  out.m = cs.materials()[out.sh.material];
  apply_textures<kAllFeatures>(cs.view(), hit.prim, out.sh, out.m);
  return out;
}

void expect_near(vec3 a, vec3 b, const std::string& what, float tol = 1e-4f) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], tol) << what << " channel " << c;
}

// uv' = T R S uv: the extension's worked example maps the unit square onto the lower left
// quadrant of the image (v runs down it), rotated: (0, 0) -> (0, 1), (1, 0) -> (0, 0.5),
// (1, 1) -> (0.5, 0.5), (0, 1) -> (0.5, 1). The opposite rotation sign leaves [0, 1]^2.
TEST(GltfTextureTransform, MatrixIsTheSpecsWorkedExample) {
  const glm::mat3x2 m = khr_texture_transform(vec2(0, 1), 1.57079632679f, vec2(0.5f));
  const vec2 in[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  const vec2 out[4] = {{0, 1}, {0, 0.5f}, {0.5f, 0.5f}, {0.5f, 1}};
  for (int i = 0; i < 4; ++i) {
    const vec2 got = m * vec3(in[i], 1.0f);
    EXPECT_NEAR(got.x, out[i].x, 1e-6f) << i;
    EXPECT_NEAR(got.y, out[i].y, 1e-6f) << i;
  }
  // Scale first, then rotation, then offset: a non-uniform scale does not shear.
  const glm::mat3x2 s = khr_texture_transform(vec2(0.25f, -0.5f), 0.3f, vec2(2.0f, 3.0f));
  const vec2 u = s * vec3(1, 0, 0), v = s * vec3(0, 1, 0);
  EXPECT_NEAR(glm::length(u), 2.0f, 1e-6f);
  EXPECT_NEAR(glm::length(v), 3.0f, 1e-6f);
  EXPECT_NEAR(glm::dot(u, v), 0.0f, 1e-6f);
  EXPECT_NEAR(s[2].x, 0.25f, 1e-7f);
  EXPECT_NEAR(s[2].y, -0.5f, 1e-7f);
}

// One transform on every slot of a material is baked into the uvs, so the image stays shared
// with a material that draws it untransformed; the lookup lands on the texel T R S uv names.
TEST(GltfTextureTransform, SharedTransformIsBakedIntoTheUvs) {
  TempDir dir;
  GltfBuilder b;
  const int pos = b.positions(kQuad), uv = b.uvs(kQuadUv), idx = b.indices(kQuadIdx);
  b.j["images"] = {{{"uri", png_data_uri(4, 4, grid_texels())}}};
  b.j["textures"] = {{{"source", 0}}};
  // uv' = 0.5 uv + (0.25, 0.5): the surface point (0.25, 0.25) reads (0.375, 0.625), the centre
  // of texel (1, 2).
  const json tt = transform(vec2(0.25f, 0.5f), 0.0f, vec2(0.5f));
  b.j["materials"] = {
      {{"name", "shifted"},
       {"pbrMetallicRoughness",
        {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 0}, {"extensions", tt}}}}},
       {"emissiveFactor", {1, 1, 1}},
       {"emissiveTexture", {{"index", 0}, {"extensions", tt}}}},
      {{"name", "plain"},
       {"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 0}}}}}}};
  b.j["extensionsUsed"] = {"KHR_texture_transform"};
  b.primitive(
      {{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv}}}, {"indices", idx}, {"material", 0}});
  const Scene s = load_scene(b.write(dir));
  EXPECT_TRUE(s.diagnostics.warnings.empty()) << warnings(s);
  ASSERT_EQ(s.textures.size(), 1u) << "one image, sRGB, untransformed: shared by both slots";
  EXPECT_EQ(s.textures[0].uv_transform, glm::mat3x2(1.0f));
  for (size_t i = 0; i < kQuadUv.size(); ++i) {
    const vec2 want = 0.5f * kQuadUv[i] + vec2(0.25f, 0.5f);
    EXPECT_NEAR(s.mesh.uvs[i].x, want.x, 1e-6f);
    EXPECT_NEAR(s.mesh.uvs[i].y, want.y, 1e-6f);
  }
  const Shaded at = shade_at(s, 0.25f, 0.25f);
  expect_near(at.m.albedo, grid_colour(1, 2), "base colour");
  expect_near(at.m.emission, grid_colour(1, 2), "emission");
}

// Slots with different transforms keep the uvs and carry their own transform to the lookup;
// a rotated normal map turns its tangent frame with it.
TEST(GltfTextureTransform, EachSlotLooksUpThroughItsOwnTransform) {
  TempDir dir;
  GltfBuilder b;
  const int pos = b.positions(kQuad), uv = b.uvs(kQuadUv), idx = b.indices(kQuadIdx);
  // A flat normal map tilted towards texture +X: (0.6, 0, 0.8) encoded.
  b.j["images"] = {{{"uri", png_data_uri(4, 4, grid_texels())}},
                   {{"uri", png_data_uri(1, 1, {204, 128, 230, 255})}}};
  b.j["textures"] = {{{"source", 0}}, {{"source", 1}}};
  // Base colour: uv' = uv + (0.25, 0.5). Emissive and normal: a quarter turn with offset (0, 1),
  // uv' = (v, 1 - u). At (0.375, 0.125): base colour reads (0.625, 0.625), texel (2, 2);
  // emission reads (0.125, 0.625), texel (0, 2).
  const json shift = transform(vec2(0.25f, 0.5f), 0.0f, vec2(1.0f));
  const json turn = transform(vec2(0.0f, 1.0f), 1.57079632679f, vec2(1.0f));
  b.j["materials"] = {
      {{"pbrMetallicRoughness",
        {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 0}, {"extensions", shift}}}}},
       {"emissiveFactor", {1, 1, 1}},
       {"emissiveTexture", {{"index", 0}, {"extensions", turn}}},
       {"normalTexture", {{"index", 1}, {"extensions", turn}}}}};
  b.primitive(
      {{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv}}}, {"indices", idx}, {"material", 0}});
  const Scene s = load_scene(b.write(dir));
  for (const std::string& w : s.diagnostics.warnings)
    EXPECT_EQ(w.find("texture"), std::string::npos) << w;
  for (size_t i = 0; i < kQuadUv.size(); ++i) EXPECT_EQ(s.mesh.uvs[i], kQuadUv[i]);
  EXPECT_EQ(s.textures.size(), 3u) << "image 0 twice (two transforms), the normal map once";

  const Shaded at = shade_at(s, 0.375f, 0.125f);
  expect_near(at.m.albedo, grid_colour(2, 2), "base colour");
  expect_near(at.m.emission, grid_colour(0, 2), "emission");
  // u' = v grows along +y, so texture +X is the surface's +y; texture +Y (up the image, against
  // v' = 1 - u) is +x. The texel tilts the normal towards +y.
  const vec3 want = glm::normalize(vec3(0.0039f, 0.6f, 0.8039f));
  expect_near(at.sh.ns, want, "normal", 0.01f);
}

// KHR_texture_transform's texCoord overrides the textureInfo's: the primitive reads that set.
TEST(GltfTextureTransform, TexCoordOverrideSelectsTheUvSet) {
  TempDir dir;
  GltfBuilder b;
  const std::vector<vec2> zeros(4, vec2(0.0f));
  const int pos = b.positions(kQuad), uv0 = b.uvs(zeros), uv1 = b.uvs(kQuadUv),
            idx = b.indices(kQuadIdx);
  b.j["images"] = {{{"uri", png_data_uri(4, 4, grid_texels())}}};
  b.j["textures"] = {{{"source", 0}}};
  json tt = transform(vec2(0.0f), 0.0f, vec2(1.0f));
  tt["KHR_texture_transform"]["texCoord"] = 1;
  b.j["materials"] = {
      {{"pbrMetallicRoughness",
        {{"metallicFactor", 0},
         {"baseColorTexture", {{"index", 0}, {"texCoord", 0}, {"extensions", tt}}}}}}};
  b.primitive({{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv0}, {"TEXCOORD_1", uv1}}},
               {"indices", idx},
               {"material", 0}});
  const Scene s = load_scene(b.write(dir));
  for (size_t i = 0; i < kQuadUv.size(); ++i) EXPECT_EQ(s.mesh.uvs[i], kQuadUv[i]);
  expect_near(shade_at(s, 0.875f, 0.125f).m.albedo, grid_colour(3, 0), "texel (3, 0)");
}

// Slots that read different uv sets cannot be represented (one set per primitive): a warning.
TEST(GltfTextureTransform, DifferentUvSetsWarn) {
  TempDir dir;
  GltfBuilder b;
  const int pos = b.positions(kQuad), uv0 = b.uvs(kQuadUv), uv1 = b.uvs(kQuadUv),
            idx = b.indices(kQuadIdx);
  b.j["images"] = {{{"uri", png_data_uri(4, 4, grid_texels())}}};
  b.j["textures"] = {{{"source", 0}}};
  b.j["materials"] = {{{"name", "two sets"},
                       {"pbrMetallicRoughness",
                        {{"baseColorTexture", {{"index", 0}}},
                         {"metallicRoughnessTexture", {{"index", 0}, {"texCoord", 1}}}}}}};
  b.primitive({{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv0}, {"TEXCOORD_1", uv1}}},
               {"indices", idx},
               {"material", 0}});
  const Scene s = load_scene(b.write(dir));
  EXPECT_TRUE(
      has_warning(s, "material \"two sets\"'s textures read texture coordinate sets 0 and 1"))
      << warnings(s);
  EXPECT_TRUE(has_warning(s, "used set 0 (the base colour texture's)")) << warnings(s);
}

// The sample model: every quad's transform is baked (the images stay one each) and nothing is
// reported unsupported. Its image, rendered, shows the arrows on the green markers.
TEST(GltfTextureTransform, SampleModelLoadsEveryTransform) {
  const fs::path file = kAssimp / "glTF2/textureTransform/TextureTransformTest.gltf";
  if (!fs::exists(file)) GTEST_SKIP() << file << " is missing (apt install assimp-testmodels)";
  const Scene s = load_scene(file.string());
  EXPECT_TRUE(s.diagnostics.warnings.empty()) << warnings(s);  // the added light is a note
  EXPECT_EQ(s.textures.size(), 5u);
  for (const TextureImage& t : s.textures) EXPECT_EQ(t.uv_transform, glm::mat3x2(1.0f));
}

// Strips and fans, indexed or not, become triangle lists that all face the way the first
// triangle does; a stitched strip's joins (triangles with a repeated vertex) are dropped.
TEST(GltfPrimitiveModes, StripsAndFansBecomeTriangleLists) {
  TempDir dir;
  GltfBuilder b;
  // Strip over a 1-high band: v_2k = (k, 1), v_2k+1 = (k, 0); its first triangle faces +z.
  auto strip = [](float x0, int quads) {
    std::vector<vec3> v;
    for (int k = 0; k <= quads; ++k) v.insert(v.end(), {vec3(x0 + k, 1, 0), vec3(x0 + k, 0, 0)});
    return v;
  };
  // Fan around a centre, counter-clockwise seen from +z: a diamond of area 2.
  auto fan = [](float x0) {
    return std::vector<vec3>{{x0, 0, 0},     {x0 + 1, 0, 0}, {x0, 1, 0},
                             {x0 - 1, 0, 0}, {x0, -1, 0},    {x0 + 1, 0, 0}};
  };
  b.primitive({{"attributes", {{"POSITION", b.positions(strip(0, 2))}}}, {"mode", 5}});
  b.primitive({{"attributes", {{"POSITION", b.positions(strip(10, 2))}}},
               {"indices", b.indices({0, 1, 2, 3, 4, 5})},
               {"mode", 5}});
  b.primitive({{"attributes", {{"POSITION", b.positions(fan(20))}}}, {"mode", 6}});
  b.primitive({{"attributes", {{"POSITION", b.positions(fan(30))}}},
               {"indices", b.indices({0, 1, 2, 3, 4, 5})},
               {"mode", 6}});
  // Two 2-quad strips stitched with repeated vertices: 10 indices, 8 candidates, 4 triangles.
  std::vector<vec3> two = strip(40, 1);
  for (const vec3& p : strip(42, 1)) two.push_back(p);
  b.primitive({{"attributes", {{"POSITION", b.positions(two)}}},
               {"indices", b.indices({0, 1, 2, 3, 3, 4, 4, 5, 6, 7})},
               {"mode", 5}});
  b.primitive({{"attributes", {{"POSITION", b.positions(strip(50, 1))}}}, {"mode", 1}});
  const Scene s = load_scene(b.write(dir));
  EXPECT_TRUE(has_warning(s, "1 primitive(s) are points or lines (mode 0-3)")) << warnings(s);
  EXPECT_TRUE(has_warning(s, "skipped them")) << warnings(s);
  // 4 + 4 + 4 + 4 + 4 triangles of the file, and the two of the default light.
  size_t up = 0;
  float area = 0.0f;
  for (size_t i = 0; i < s.mesh.indices.size(); ++i) {
    if (s.materials[s.mesh.materials[i]].material.is_emissive()) continue;
    const uvec3 t = s.mesh.indices[i];
    const vec3 a = s.mesh.positions[t.x];
    const vec3 n = glm::cross(s.mesh.positions[t.y] - a, s.mesh.positions[t.z] - a);
    EXPECT_GT(n.z, 0.0f) << "triangle at " << a.x << ", " << a.y << " is wound backwards";
    ++up;
    area += 0.5f * glm::length(n);
  }
  EXPECT_EQ(up, 20u);
  EXPECT_NEAR(area, 2.0f * 5.0f, 1e-5f);
}

TEST(GltfPrimitiveModes, StripOfTwoVerticesIsAnError) {
  TempDir dir;
  GltfBuilder b;
  b.primitive({{"attributes", {{"POSITION", b.positions({{0, 0, 0}, {1, 0, 0}})}}}, {"mode", 6}});
  const std::string path = b.write(dir);
  const std::string msg = load_error(path);
  EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
  EXPECT_NE(msg.find("triangle fan of 2 vertices"), std::string::npos) << msg;
}

TEST(GltfPrimitiveModes, AssetGeneratorModes) {
  const fs::path dir = kAssimp / "glTF2/glTF-Asset-Generator/Mesh_PrimitiveMode";
  if (!fs::is_directory(dir)) GTEST_SKIP() << dir << " is missing (apt install assimp-testmodels)";
  // 04 and 11 are strips, 05 and 12 fans, 06 and 13-15 triangle lists: the same square.
  for (const char* n : {"04", "05", "06", "11", "12", "13", "14", "15"}) {
    SCOPED_TRACE(n);
    const Scene s = load_scene((dir / (std::string("Mesh_PrimitiveMode_") + n + ".gltf")).string());
    EXPECT_EQ(s.mesh.indices.size(), 2u + 2u);  // the square and the default light
  }
  for (const char* n : {"00", "01", "02", "03", "07", "08", "09", "10"}) {
    SCOPED_TRACE(n);
    EXPECT_NE(load_error((dir / (std::string("Mesh_PrimitiveMode_") + n + ".gltf")).string())
                  .find("points or lines"),
              std::string::npos);
  }
}

std::string write_text(const TempDir& dir, const std::string& name, const std::string& text) {
  const std::string path = dir.path + "/" + name;
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// GLB: 12-byte header, then the JSON chunk (GLB 2) or content (GLB 1) after 8 more bytes.
std::string glb(uint32_t version, const std::string& json_text) {
  std::string out = "glTF";
  auto u32 = [&](uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
  u32(version);
  u32(uint32_t(20 + json_text.size()));
  u32(uint32_t(json_text.size()));
  u32(version == 2 ? 0x4E4F534Au : 0u);
  return out + json_text;
}

TEST(GltfVersion, Gltf1IsNamed) {
  TempDir dir;
  const std::string v1 =
      R"({"asset": {"version": "1.0"}, "meshes": {"box": {"primitives": []}}, "scene": "s"})";
  struct Case {
    std::string path, reason;
  } cases[] = {
      {write_text(dir, "v1.gltf", v1), "(asset version 1.0)"},
      {write_text(dir, "v1num.gltf", R"({"asset": {"version": 1}, "nodes": {}})"),
       "(asset version 1)"},
      {write_text(dir, "noasset.gltf", R"({"meshes": {"box": {}}})"),
       "(no asset version, and \"meshes\" is an object keyed by id, as in glTF 1.0)"},
      {write_text(dir, "v1.glb", glb(1, v1)), "(asset version 1.0)"},
      {write_text(dir, "v1bare.glb", glb(1, "{}")), "(binary glTF version 1)"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.path);
    const std::string msg = load_error(c.path);
    EXPECT_EQ(msg, c.path + ": glTF 1.0 is not supported " + c.reason + "; nothing was rendered");
  }
  const fs::path truck = kAssimp / "glTF/CesiumMilkTruck/CesiumMilkTruck.gltf";
  const fs::path box = kAssimp / "glTF/BoxTextured-glTF-Binary/BoxTextured.glb";
  if (!fs::exists(truck) || !fs::exists(box))
    GTEST_SKIP() << "assimp-testmodels' glTF 1.0 files are missing";
  EXPECT_NE(load_error(truck.string()).find("glTF 1.0 is not supported (asset version 1)"),
            std::string::npos);
  EXPECT_NE(load_error(box.string()).find("glTF 1.0 is not supported (asset version 1.0)"),
            std::string::npos);
}

// A required compression extension is the reason given, before anything tinygltf says; one
// used without being required is named ahead of the error about the uncompressed fallback.
TEST(GltfCompression, ExtensionIsNamed) {
  TempDir dir;
  for (const char* ext : {"KHR_draco_mesh_compression", "EXT_meshopt_compression"}) {
    SCOPED_TRACE(ext);
    GltfBuilder b;
    b.primitive({{"attributes", {{"POSITION", b.positions(kQuad)}}}});
    b.j["accessors"][0]["bufferView"] = 7;  // as compressed files leave it: no such view
    b.j["extensionsUsed"] = {ext};
    b.j["extensionsRequired"] = {ext};
    const std::string required = b.write(dir, "required.gltf");
    std::string msg = load_error(required);
    EXPECT_EQ(msg.rfind(required + ": the file requires " + std::string(ext) + " (", 0), 0u) << msg;
    EXPECT_NE(msg.find("), which is not supported; nothing was rendered"), std::string::npos)
        << msg;
    b.j.erase("extensionsRequired");
    const std::string used = b.write(dir, "used.gltf");
    msg = load_error(used);
    EXPECT_EQ(msg.rfind(used + ": the file uses " + std::string(ext) + " (", 0), 0u) << msg;
    EXPECT_NE(msg.find("), which is not supported, and its uncompressed fallback cannot be read: "
                       "mesh 0 primitive 0 POSITION refers to buffer view 7"),
              std::string::npos)
        << msg;
  }
  const fs::path engine = kAssimp / "glTF2/draco/2CylinderEngine.gltf";
  if (!fs::exists(engine)) GTEST_SKIP() << engine << " is missing";
  EXPECT_NE(load_error(engine.string()).find("requires KHR_draco_mesh_compression"),
            std::string::npos);
}

// A Draco primitive whose accessors have no buffer views (no uncompressed fallback) is skipped
// with a warning naming the extension; one with the fallback is read from it.
TEST(GltfCompression, DracoPrimitivesUseTheFallback) {
  TempDir dir;
  GltfBuilder b;
  const json draco = {
      {"KHR_draco_mesh_compression", {{"bufferView", 0}, {"attributes", {{"POSITION", 0}}}}}};
  b.primitive({{"attributes", {{"POSITION", b.positions(kQuad)}}},
               {"indices", b.indices(kQuadIdx)},
               {"extensions", draco}});
  b.primitive({{"attributes", {{"POSITION", b.positions(kQuad)}}},
               {"indices", b.indices(kQuadIdx)},
               {"extensions", draco}});
  b.j["accessors"][2].erase("bufferView");
  b.j["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  const Scene s = load_scene(b.write(dir));
  EXPECT_TRUE(has_warning(s, "1 primitive(s) are compressed with KHR_draco_mesh_compression"))
      << warnings(s);
  EXPECT_EQ(s.mesh.indices.size(), 2u + 2u);  // the fallback quad and the default light
}

// Members of the wrong type, which tinygltf replaces by defaults without a word, are warned
// with the file, the line and the JSON pointer; a texture index out of range drops only that
// texture.
TEST(GltfWrongTypes, WarnWithThePointer) {
  TempDir dir;
  GltfBuilder b;
  const int pos = b.positions(kQuad), uv = b.uvs(kQuadUv), idx = b.indices(kQuadIdx);
  b.j["images"] = {{{"uri", png_data_uri(4, 4, grid_texels())}}};
  b.j["textures"] = {{{"source", 0}}};
  b.j["materials"] = {
      {{"pbrMetallicRoughness", json::array({"not an object"})}},
      {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", -1}}}}}},
      {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 9}}}, {"metallicFactor", "0"}}}},
      {{"emissiveTexture", 0}, {"emissiveFactor", {1, 1, 1}}},
      {{"normalTexture", {{"index", 0}, {"scale", "big"}}}},
      {{"pbrMetallicRoughness",
        {{"baseColorTexture",
          {{"index", 0}, {"extensions", {{"KHR_texture_transform", {{"offset", "left"}}}}}}}}}},
  };
  for (int m = 0; m < 6; ++m)
    b.primitive({{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv}}},
                 {"indices", idx},
                 {"material", m}});
  b.primitive({{"attributes", {{"POSITION", pos}}}, {"indices", idx}, {"material", "0"}});
  b.j["meshes"].push_back({{"primitives", {{"not an array", 1}}}});
  const std::string path = b.write(dir);
  const Scene s = load_scene(path);
  const struct {
    const char* pointer;
    const char* says;
  } expected[] = {
      {"/materials/0/pbrMetallicRoughness", "is an array, not an object; used glTF's defaults"},
      {"/materials/1/pbrMetallicRoughness/baseColorTexture/index",
       "is -1, but the file has 1 texture(s); rendered material 1 without this texture"},
      {"/materials/2/pbrMetallicRoughness/baseColorTexture/index", "is 9, but the file has 1"},
      {"/materials/2/pbrMetallicRoughness/metallicFactor", "is a string, not a number; used 1"},
      {"/materials/3/emissiveTexture", "is a number, not a textureInfo object"},
      {"/materials/4/normalTexture/scale", "is a string, not a number; used 1"},
      {"/materials/5/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform/offset",
       "is \"left\", not an array of 2 finite numbers; used [0, 0]"},
      {"/meshes/6/primitives/0/material", "is a string, not an index; used grey diffuse"},
      {"/meshes/7/primitives", "is an object, not an array; skipped the mesh"},
  };
  for (const auto& e : expected) {
    bool found = false;
    for (const std::string& w : s.diagnostics.warnings) {
      const size_t at = w.find(std::string(": ") + e.pointer + " ");
      if (at == std::string::npos) continue;
      found = true;
      // "path:line: pointer ...": the line is that of the value in the written file.
      EXPECT_EQ(w.rfind(path + ":", 0), 0u) << w;
      EXPECT_GT(std::atoi(w.c_str() + path.size() + 1), 1) << w;
      EXPECT_NE(w.find(e.says), std::string::npos) << w;
    }
    EXPECT_TRUE(found) << e.pointer << " not warned in\n" << warnings(s);
  }
  // The one texture that is well referenced is still used.
  ASSERT_GE(s.textures.size(), 1u);
  EXPECT_NE(s.materials[s.find_material("material 4")].material.normal_tex, kInvalid);
}

TEST(GltfWrongTypes, AssimpWrongTypes) {
  const fs::path dir = kAssimp / "glTF2/wrongTypes";
  if (!fs::is_directory(dir)) GTEST_SKIP() << dir << " is missing (apt install assimp-testmodels)";
  const struct {
    const char* file;
    const char* says;
  } cases[] = {
      {"badObject.gltf", "/materials/0/pbrMetallicRoughness is an array, not an object"},
      {"badUint.gltf", "/materials/0/pbrMetallicRoughness/baseColorTexture/index is -1"},
      {"badNumber.gltf", "/materials/0/normalTexture/scale is a string, not a number"},
      {"badExtension.gltf",
       "/materials/0/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform is a "
       "string, not an object"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.file);
    const Scene s = load_scene((dir / c.file).string());
    EXPECT_TRUE(has_warning(s, c.says)) << warnings(s);
  }
  EXPECT_NE(load_error((dir / "badArray.gltf").string()).find("/meshes/0/primitives is an object"),
            std::string::npos);
}

}  // namespace

namespace {

// A mesh that three nodes use is read once and drawn by three instances (node transform times
// the load transform); a mesh one node uses stays in the scene's mesh; an emissive mesh that
// two nodes use is written out twice.
TEST(GltfInstances, ReusedMeshesBecomeInstances) {
  TempDir dir;
  GltfBuilder g;
  const int pos = g.positions({vec3(0, 0, 0), vec3(1, 0, 0), vec3(0, 1, 0)});
  g.primitive({{"attributes", {{"POSITION", pos}}}});  // mesh 0, node 0
  g.j["meshes"][0]["name"] = "leaf";
  g.primitive({{"attributes", {{"POSITION", pos}}}});  // mesh 1, node 1: used once
  g.j["materials"] = {{{"emissiveFactor", {1, 1, 1}}}};
  g.primitive({{"attributes", {{"POSITION", pos}}}, {"material", 0}});  // mesh 2, node 2
  for (int n = 0; n < 2; ++n) {
    g.j["nodes"].push_back({{"mesh", 0}, {"translation", {0, 0, 2 + 2 * n}}});
    g.j["scenes"][0]["nodes"].push_back(g.j["nodes"].size() - 1);
  }
  g.j["nodes"].push_back({{"mesh", 2}, {"scale", {3, 3, 3}}});
  g.j["scenes"][0]["nodes"].push_back(g.j["nodes"].size() - 1);
  const std::string path = g.write(dir);
  Scene s;
  ASSERT_NO_THROW(s = load_scene(path)) << load_error(path);
  ASSERT_EQ(s.instanced_meshes.size(), 1u);
  EXPECT_EQ(s.instanced_meshes[0].mesh.indices.size(), 1u);
  EXPECT_EQ(s.instanced_meshes[0].mesh.positions[1], vec3(1, 0, 0));
  ASSERT_EQ(s.instances.size(), 3u);
  EXPECT_EQ(s.instances[0].world_from_object, mat4(1.0f));
  EXPECT_EQ(s.instances[2].world_from_object[3], vec4(0, 0, 4, 1));
  EXPECT_EQ(s.mesh.indices.size(), 1u + 2u);  // mesh 1 once, the emissive mesh 2 twice
  bool found = false;
  for (const ObjectInfo& o : s.objects)
    if (o.is_instances) {
      found = true;
      EXPECT_EQ(o.name, "test.gltf mesh 0 (\"leaf\")");
      EXPECT_EQ(o.count, 3u);
    }
  EXPECT_TRUE(found);
  // Placed by a JSON mesh object, the instances carry the object's transform.
  const std::string json = dir.path + "/scene.json";
  std::ofstream(json) << R"({"environment": {"color": [1, 1, 1]}, "objects": [
      {"type": "mesh", "file": "test.gltf", "transform": {"translate": [5, 0, 0]}}]})";
  const Scene placed = load_scene(json);
  ASSERT_EQ(placed.instances.size(), 3u);
  EXPECT_EQ(placed.instances[2].world_from_object[3], vec4(5, 0, 4, 1));
  // With "instances" of its own the file's instances are written into the object's mesh.
  std::ofstream(json) << R"({"environment": {"color": [1, 1, 1]}, "objects": [
      {"type": "mesh", "file": "test.gltf", "instances": [{"translate": [5, 0, 0]}]}]})";
  const Scene nested = load_scene(json);
  EXPECT_TRUE(nested.instances.empty()) << "the file's emitters flatten the object";
  EXPECT_EQ(nested.mesh.indices.size(), 6u);
}

}  // namespace
