// Image textures: bilinear lookup, wrap modes and sRGB decoding against hand-computed values; a
// textured quad under uniform light whose image mean is the texture's mean albedo; and loading
// the textured glTF samples Debian ships.
#include <gtest/gtest.h>
#include <stb_image_write.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>

#include "scene/loader.h"
#include "scene/loader_util.h"
#include "scene_builders.h"
#include "test_util.h"

namespace {
using namespace tracer;
using namespace test;

uint32_t rgba(int r, int g, int b, int a = 255) {
  return uint32_t(r) | uint32_t(g) << 8 | uint32_t(b) << 16 | uint32_t(a) << 24;
}

// A 2x2 linear texture: red, green / blue, white (rows top to bottom).
struct Tiny {
  std::vector<uint32_t> texels = {rgba(255, 0, 0), rgba(0, 255, 0), rgba(0, 0, 255),
                                  rgba(255, 255, 255)};
  TextureDesc desc{0, 2, 2, 0};
  vec4 at(vec2 uv, TextureWrap s = TextureWrap::kRepeat, TextureWrap t = TextureWrap::kRepeat,
          bool srgb = false) {
    desc.flags = uint32_t(s) | uint32_t(t) << 2 | (srgb ? kTextureSrgb : 0u);
    return sample_texture(&desc, texels.data(), 0, uv);
  }
};

void expect_near(vec4 a, vec4 b, const char* what) {
  for (int c = 0; c < 4; ++c) EXPECT_NEAR(a[c], b[c], 1e-5f) << what << " channel " << c;
}

TEST(TextureLookup, TexelCentresAreExactAndMidpointsAverage) {
  Tiny t;
  expect_near(t.at(vec2(0.25f, 0.25f)), vec4(1, 0, 0, 1), "texel (0,0) centre");
  expect_near(t.at(vec2(0.75f, 0.25f)), vec4(0, 1, 0, 1), "texel (1,0) centre");
  expect_near(t.at(vec2(0.25f, 0.75f)), vec4(0, 0, 1, 1), "texel (0,1) centre");
  expect_near(t.at(vec2(0.75f, 0.75f)), vec4(1, 1, 1, 1), "texel (1,1) centre");
  expect_near(t.at(vec2(0.5f, 0.25f)), vec4(0.5f, 0.5f, 0, 1), "midpoint of the top row");
  expect_near(t.at(vec2(0.5f, 0.5f)), vec4(0.5f, 0.5f, 0.5f, 1), "centre of all four");
}

TEST(TextureLookup, WrapModes) {
  Tiny t;
  // u = -0.25 lands on texel column -1, u = 1.25 on column 2 (v on row 0's centre).
  const vec4 red(1, 0, 0, 1), green(0, 1, 0, 1);
  expect_near(t.at(vec2(-0.25f, 0.25f), TextureWrap::kRepeat), green, "repeat -0.25");
  expect_near(t.at(vec2(1.25f, 0.25f), TextureWrap::kRepeat), red, "repeat 1.25");
  expect_near(t.at(vec2(-0.25f, 0.25f), TextureWrap::kClampToEdge), red, "clamp -0.25");
  expect_near(t.at(vec2(1.25f, 0.25f), TextureWrap::kClampToEdge), green, "clamp 1.25");
  expect_near(t.at(vec2(-0.25f, 0.25f), TextureWrap::kMirroredRepeat), red, "mirror -0.25");
  expect_near(t.at(vec2(1.25f, 0.25f), TextureWrap::kMirroredRepeat), green, "mirror 1.25");
  expect_near(t.at(vec2(-0.75f, 0.25f), TextureWrap::kMirroredRepeat), green, "mirror -0.75");
  // wrap_t acts on v independently: row -1 is row 1 (blue) when repeating, row 0 when clamped.
  expect_near(t.at(vec2(0.25f, -0.25f), TextureWrap::kClampToEdge, TextureWrap::kRepeat),
              vec4(0, 0, 1, 1), "t repeat");
  expect_near(t.at(vec2(0.25f, -0.25f), TextureWrap::kRepeat, TextureWrap::kClampToEdge), red,
              "t clamp");
}

TEST(TextureLookup, SrgbDecodesBeforeFiltering) {
  Tiny t;
  t.texels.assign(4, rgba(128, 128, 128, 128));
  const vec4 c = t.at(vec2(0.3f, 0.6f), TextureWrap::kRepeat, TextureWrap::kRepeat, true);
  EXPECT_NEAR(c.x, 0.21586f, 1e-4f);
  EXPECT_NEAR(c.y, 0.21586f, 1e-4f);
  EXPECT_NEAR(c.w, 128.0f / 255.0f, 1e-6f) << "alpha stays linear";
  EXPECT_NEAR(srgb_to_linear(1.0f), 1.0f, 1e-6f);
  EXPECT_NEAR(srgb_to_linear(0.04f), 0.04f / 12.92f, 1e-7f);
  // Filtering decoded values: halfway between black and white is 0.5 in linear light.
  t.texels = {rgba(0, 0, 0), rgba(255, 255, 255), rgba(0, 0, 0), rgba(255, 255, 255)};
  EXPECT_NEAR(t.at(vec2(0.5f, 0.25f), TextureWrap::kRepeat, TextureWrap::kRepeat, true).x, 0.5f,
              1e-6f);
}

// A flat normal map tilts the shading normal along the tangent frame glTF defines: texture +X
// along dp/du, texture +Y up the image (v runs down it), +Z along the surface normal.
TEST(TextureLookup, NormalMapFollowsTheUvTangentFrame) {
  for (int axis = 0; axis < 2; ++axis) {
    Scene s;
    s.source = "<normal map>";
    TextureImage t;
    t.width = t.height = 1;
    t.rgba8 = {uint8_t(axis == 0 ? 204 : 128), uint8_t(axis == 1 ? 204 : 128), 230, 255};
    s.textures.push_back(t);
    Material m;
    m.normal_tex = 0;
    s.materials.push_back({"bumpy", m});
    s.materials.push_back({"light", diffuse(vec3(0.0f), vec3(1.0f))});
    add_quad(s.mesh, vec3(0, 0, 0), vec3(1, 0, 0), vec3(0, 1, 0), 0);
    s.mesh.uvs.clear();
    for (const vec3& p : s.mesh.positions) s.mesh.uvs.push_back(vec2(p.x, 1.0f - p.y));
    s.spheres.push_back({vec3(0, 0, 5), 0.5f, 1});
    const CompiledScene cs(s, 4, 4);
    ASSERT_TRUE(cs.features() & kFeatureTextures);
    const Ray ray{vec3(0.25f, 0.3f, 1.0f), kInfinity, vec3(0, 0, -1), 0.0f};
    const Hit hit = intersect_closest(cs.view(), ray);
    ASSERT_TRUE(hit.valid());
    SurfaceHit sh = make_surface_hit(cs.view(), ray, hit);
    ASSERT_GT(sh.ng.z, 0.0f) << "the quad should face +z";
    Material mt = cs.materials()[sh.material];
    apply_textures<kAllFeatures>(cs.view(), hit.prim, sh, mt);
    const vec3 c(axis == 0 ? 0.6f : 0.0039f, axis == 1 ? 0.6f : 0.0039f, 0.8039f);
    const vec3 expected = glm::normalize(c);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(sh.ns[k], expected[k], 0.01f) << "axis " << axis;
  }
}

// A temp folder removed at the end of the test.
struct TempDir {
  std::string path;
  TempDir() {
    char tmpl[] = "/tmp/texture_test_XXXXXX";
    path = mkdtemp(tmpl);
  }
  ~TempDir() { std::system(("rm -rf '" + path + "'").c_str()); }
};

float srgb8(int v) {
  return srgb_to_linear(float(v) / 255.0f);
}

// The quad z = 0, x and y in [-1, 1], with uv = (x + 1, y + 1) as an OBJ using checker.png
// (a 2x2 checker of sRGB (230, 40, 40) and (40, 40, 230)) through map_Kd.
std::string write_checker_obj(const TempDir& dir, bool with_map) {
  const uint8_t a[4] = {230, 40, 40, 255}, b[4] = {40, 40, 230, 255};
  uint8_t px[16];
  for (int i = 0; i < 4; ++i) std::memcpy(px + 4 * i, (i == 0 || i == 3) ? a : b, 4);
  EXPECT_TRUE(stbi_write_png((dir.path + "/checker.png").c_str(), 2, 2, 4, px, 8));
  std::ofstream(dir.path + "/quad.mtl") << "newmtl checker\nKd 1 1 1\n"
                                        << (with_map ? "map_Kd checker.png\n" : "");
  // OBJ's v runs up the image: vt v = y + 1 becomes glTF v = -y, still one period of the map.
  std::ofstream(dir.path + "/quad.obj") << "mtllib quad.mtl\nusemtl checker\n"
                                           "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
                                           "vt 0 0\nvt 2 0\nvt 2 2\nvt 0 2\n"
                                           "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
  return dir.path + "/quad.obj";
}

// The quad inside an emitting sky (radiance 1, albedo 0), seen face on so that the image covers
// x, y in [-0.5, 0.5]: exactly one period of the repeating map. A diffuse surface under uniform
// radiance 1 reflects its albedo, so the image mean is the mean of the filtered texture, which
// for a full period of a repeating bilinear texture is the mean of its (linear) texels.
vec3 render_checker(const std::string& obj) {
  Scene s;
  s.source = obj;
  append_obj_file(s, obj, mat4(1.0f), kInvalid, {obj, 0});
  s.materials.push_back({"sky", diffuse(vec3(0.0f), vec3(1.0f), true)});
  s.spheres.push_back({vec3(0.0f), 1000.0f, uint32_t(s.materials.size() - 1)});
  s.camera.position = vec3(0.0f, 0.0f, 1.0f);
  s.camera.look_at = vec3(0.0f);
  s.camera.vfov_deg = 2.0f * glm::degrees(std::atan(0.5f));
  validate_scene(s);
  RenderSettings rs;
  rs.width = rs.height = 16;
  rs.max_depth = 2;
  const PixelStats ps = render_pixel_stats(s, rs, 64);
  EXPECT_EQ(ps.nonfinite, 0u);
  return ps.image_mean();
}

bool matches(vec3 got, vec3 expected) {
  for (int c = 0; c < 3; ++c)
    if (std::abs(got[c] - expected[c]) > 0.02f * expected[c] + 1e-3f) return false;
  return true;
}

TEST(TextureRender, CheckerQuadMeanIsTheTextureMeanAlbedo) {
  TempDir dir;
  const std::string obj = write_checker_obj(dir, true);
  Scene probe;
  append_obj_file(probe, obj, mat4(1.0f), kInvalid, {obj, 0});
  ASSERT_EQ(probe.textures.size(), 1u) << "map_Kd was not loaded";
  EXPECT_TRUE(probe.textures[0].srgb);
  EXPECT_EQ(probe.mesh.uvs.size(), probe.mesh.positions.size());
  const vec3 expected =
      0.5f * vec3(srgb8(230) + srgb8(40), srgb8(40) + srgb8(40), srgb8(40) + srgb8(230));
  const vec3 got = render_checker(obj);
  EXPECT_TRUE(matches(got, expected))
      << "mean " << got.x << " " << got.y << " " << got.z << ", expected " << expected.x << " "
      << expected.y << " " << expected.z;
  // Negative control: the same scene without map_Kd renders the factor (Kd = 1), not the map.
  TempDir plain;
  const vec3 untextured = render_checker(write_checker_obj(plain, false));
  EXPECT_FALSE(matches(untextured, expected)) << "the control cannot tell textures apart";
  EXPECT_TRUE(matches(untextured, vec3(1.0f)));
}

TEST(TextureLoad, MissingMapKdWarnsAndRendersUntextured) {
  TempDir dir;
  const std::string obj = write_checker_obj(dir, true);
  std::remove((dir.path + "/checker.png").c_str());
  Scene s;
  append_obj_file(s, obj, mat4(1.0f), kInvalid, {obj, 0});
  EXPECT_TRUE(s.textures.empty());
  bool warned = false;
  for (const std::string& w : s.diagnostics.warnings)
    warned |= w.find("map_Kd") != std::string::npos;
  EXPECT_TRUE(warned);
}

// One triangle with TEXCOORD_0 and a base colour texture from `image` (a file in dir).
std::string write_triangle_gltf(const TempDir& dir, const std::string& image) {
  const float data[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1};
  std::ofstream(dir.path + "/tri.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(data), sizeof(data));
  std::ofstream(dir.path + "/tri.gltf")
      << R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
  "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
  "textures": [{"source": 0}], "images": [{"uri": ")"
      << image << R"("}],
  "buffers": [{"uri": "tri.bin", "byteLength": 60}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                  {"buffer": 0, "byteOffset": 36, "byteLength": 24}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}]})";
  return dir.path + "/tri.gltf";
}

bool has_warning(const Scene& s, const std::string& part) {
  for (const std::string& w : s.diagnostics.warnings)
    if (w.find(part) != std::string::npos) return true;
  return false;
}

TEST(TextureLoad, GltfImagesTooLargeUndecodableOrMissing) {
  TempDir dir;
  std::vector<uint8_t> row(16385 * 4, 128);
  ASSERT_TRUE(stbi_write_png((dir.path + "/big.png").c_str(), 16385, 1, 4, row.data(), 0));
  std::ofstream(dir.path + "/junk.png") << "not an image at all";
  try {
    Scene s;
    const std::string path = write_triangle_gltf(dir, "big.png");
    append_gltf_file(s, path, mat4(1.0f), kInvalid, {path, 0}, nullptr, nullptr);
    ADD_FAILURE() << "a 16385-texel-wide image was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("16384"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("tri.gltf"), std::string::npos) << e.what();
  }
  for (const char* image : {"junk.png", "missing.png"}) {
    Scene s;
    const std::string path = write_triangle_gltf(dir, image);
    append_gltf_file(s, path, mat4(1.0f), kInvalid, {path, 0}, nullptr, nullptr);
    EXPECT_TRUE(s.textures.empty()) << image;
    EXPECT_TRUE(has_warning(s, "could not be loaded")) << image;
    EXPECT_EQ(s.mesh.uvs.size(), 3u) << image;
  }
  // The same triangle with a good image is textured; uv (0, 1) of vertex 2 is kept as is.
  const uint8_t px[4] = {255, 0, 0, 255};
  ASSERT_TRUE(stbi_write_png((dir.path + "/red.png").c_str(), 1, 1, 4, px, 4));
  Scene s;
  const std::string path = write_triangle_gltf(dir, "red.png");
  append_gltf_file(s, path, mat4(1.0f), kInvalid, {path, 0}, nullptr, nullptr);
  ASSERT_EQ(s.textures.size(), 1u);
  EXPECT_EQ(s.mesh.uvs[2], vec2(0.0f, 1.0f));
  EXPECT_FALSE(has_warning(s, "textures"));
}

TEST(TextureLoad, DebianBoxTexturedSamples) {
  const std::string root = "/usr/share/assimp/models/glTF2/";
  const char* files[] = {"BoxTextured-glTF/BoxTextured.gltf",
                         "BoxTextured-glTF-Binary/BoxTextured.glb",
                         "BoxTextured-glTF-Embedded/BoxTextured.gltf"};
  int found = 0;
  for (const char* f : files) {
    const std::string path = root + f;
    if (!file_exists(path)) continue;
    ++found;
    const Scene s = load_scene(path);
    EXPECT_FALSE(s.mesh.uvs.empty()) << f;
    EXPECT_EQ(s.mesh.uvs.size(), s.mesh.positions.size()) << f;
    ASSERT_EQ(s.textures.size(), 1u) << f;
    EXPECT_EQ(s.textures[0].width, 211) << f;
    EXPECT_EQ(s.textures[0].height, 211) << f;
    EXPECT_TRUE(s.textures[0].srgb) << f;
    bool textured_material = false;
    for (const NamedMaterial& m : s.materials) textured_material |= m.material.base_color_tex == 0;
    EXPECT_TRUE(textured_material) << f;
    for (const std::string& w : s.diagnostics.warnings)
      EXPECT_EQ(w.find("textures"), std::string::npos) << f << ": " << w;
    const CompiledScene cs(s, 8, 8);
    EXPECT_TRUE(cs.features() & kFeatureTextures) << f;
    EXPECT_EQ(cs.texels().size(), 211u * 211u) << f;
  }
  if (found == 0) GTEST_SKIP() << "the Debian glTF samples are not installed under " << root;
}

TEST(TextureLoad, ProjectTexturedSceneLoads) {
  const std::string path = source_dir() + "/assets/scenes/textured.gltf";
  if (!file_exists(path)) GTEST_SKIP() << path << " is missing";
  const Scene s = load_scene(path);
  EXPECT_FALSE(s.textures.empty());
  for (const std::string& w : s.diagnostics.warnings)
    EXPECT_EQ(w.find("textures"), std::string::npos) << w;
  const CompiledScene cs(s, 8, 8);
  EXPECT_TRUE(cs.features() & kFeatureTextures);
}

// Light sampling must return the textured emission a path that hits the light sees, or NEE + MIS
// and pure BSDF sampling converge to different images. The project scene has every map: a
// textured emitter, base colour, metallic-roughness and normal maps.
TEST(TextureRender, TexturedEmitterAgreesWithAndWithoutLightSampling) {
  const std::string path = source_dir() + "/assets/scenes/textured.gltf";
  if (!file_exists(path)) GTEST_SKIP() << path << " is missing";
  Scene s = load_scene(path);
  RenderSettings rs;
  rs.width = rs.height = 16;
  rs.max_depth = 4;
  auto mean_and_se = [&](bool nee, uint32_t spp, double& se) {
    rs.nee = rs.mis = nee;
    const PixelStats ps = render_pixel_stats(s, rs, spp);
    EXPECT_EQ(ps.nonfinite, 0u);
    double var = 0.0, mean = 0.0;
    for (size_t i = 0; i < ps.mean.size(); ++i) {
      mean += luminance(ps.mean[i]);
      var += luminance(ps.var[i]);  // a bound-ish proxy: channels are strongly correlated
    }
    const double n = double(ps.mean.size());
    se = std::sqrt(var / double(spp)) / n;
    return mean / n;
  };
  double se_nee = 0.0, se_naive = 0.0;
  const double nee = mean_and_se(true, 256, se_nee);
  const double naive = mean_and_se(false, 2048, se_naive);
  const double tol = 5.0 * std::sqrt(se_nee * se_nee + se_naive * se_naive);
  EXPECT_NEAR(nee, naive, tol) << "NEE+MIS " << nee << " vs BSDF sampling only " << naive;
  EXPECT_GT(nee, 0.0);
}

}  // namespace
