// The pbrt-v4 reader: a camera and shapes land where pbrt puts them in the image (handedness,
// fov on the shorter axis), transforms, attribute blocks, orientation, materials and area lights,
// instancing and Include; every error names file:line; the shared Bitterli scenes load and render
// with only their expected warnings.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>
#include <random>

#include "cpu/cpu_backend.h"
#include "image/image.h"
#include "scene/compiled_scene.h"
#include "scene/loader.h"
#include "scene/pbrt_loader.h"
#include "scene/pbrt_spectra.h"
#include "test_util.h"

using namespace tracer;

namespace {

std::string temp_dir() {
  std::string tmpl = testing::TempDir() + "pbrt_test_XXXXXX";
  return std::string(mkdtemp(tmpl.data()));
}

std::string write_file(const std::string& path, const std::string& text) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

Scene load(const std::string& text) {
  return load_pbrt_string(text, "/nonexistent/scene.pbrt");
}

std::string error_of(const std::string& text, const std::string& path = "/nonexistent/scene.pbrt") {
  try {
    load_pbrt_string(text, path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

int count_warnings(const Scene& s, const std::string& part) {
  int n = 0;
  for (const std::string& w : s.diagnostics.warnings) n += contains(w, part);
  return n;
}

std::string all_warnings(const Scene& s) {
  std::string out;
  for (const std::string& w : s.diagnostics.warnings) out += w + "\n";
  return out;
}

const Material& material_of_triangle(const Scene& s, size_t t) {
  return s.materials[s.mesh.materials[t]].material;
}

std::string film(int w, int h) {
  return "Film \"rgb\" \"integer xresolution\" [" + std::to_string(w) +
         "] \"integer yresolution\" [" + std::to_string(h) + "]\n";
}

const char* kTriangle =
    "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\n";

ImageRGB render(const Scene& s, int spp, int max_depth) {
  RenderSettings rs = s.settings;
  rs.max_depth = max_depth;
  const CompiledScene cs(s, rs.width, rs.height);
  CpuRenderer r(2);
  r.set_scene(cs, make_integrator_settings(rs));
  r.render(uint32_t(spp));
  return r.image();
}

// The luminance-weighted centre of an image, in raster coordinates (pixel centres at +0.5).
vec2 centroid(const ImageRGB& img) {
  glm::dvec2 sum(0.0);
  double total = 0.0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const double l = double(luminance(img.at(x, y)));
      sum += l * glm::dvec2(x + 0.5, y + 0.5);
      total += l;
    }
  return total > 0.0 ? vec2(sum / total) : vec2(-1.0f);
}

// Where pbrt-v4's perspective camera puts a world point: camera space by camera_from_world,
// then the screen window of pbrt's PerspectiveCamera ([-aspect, aspect] x [-1, 1] for a
// landscape film, [-1, 1] x [-1/aspect, 1/aspect] for a portrait one, fov on the shorter
// axis), raster y down.
vec2 pbrt_raster(const mat4& camera_from_world, float fov_deg, int w, int h, vec3 world) {
  const vec3 c = vec3(camera_from_world * vec4(world, 1.0f));
  const float t = std::tan(glm::radians(0.5f * fov_deg));
  const vec2 screen(c.x / (c.z * t), c.y / (c.z * t));
  const float aspect = float(w) / float(h);
  const vec2 half = aspect > 1.0f ? vec2(aspect, 1.0f) : vec2(1.0f, 1.0f / aspect);
  return vec2((screen.x + half.x) / (2.0f * half.x) * float(w),
              (half.y - screen.y) / (2.0f * half.y) * float(h));
}

}  // namespace

// A small emitting sphere is rendered where pbrt's camera model projects it: not mirrored, with
// the fov on the shorter image axis, and mirrored exactly when the file mirrors the camera.
TEST(Pbrt, ShapesLandWherePbrtPutsThemInTheImage) {
  struct Case {
    int w, h;
    bool mirror_camera;
  };
  const vec3 eye(0.5f, 1.0f, -5.0f), at(0.0f, 0.2f, 0.0f), up(0.0f, 1.0f, 0.0f);
  const vec3 centre(1.0f, 0.6f, 2.0f);
  for (const Case c : {Case{96, 48, false}, Case{48, 96, false}, Case{96, 48, true}}) {
    const std::string text =
        std::string(c.mirror_camera ? "Scale -1 1 1\n" : "") +
        "LookAt 0.5 1 -5  0 0.2 0  0 1 0\nCamera \"perspective\" \"float fov\" [30]\n" +
        film(c.w, c.h) +
        "WorldBegin\nAttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [10 10 10]\n"
        "  Translate 1 0.6 2\n  Shape \"sphere\" \"float radius\" [0.12]\nAttributeEnd\n";
    const Scene s = load(text);
    // pbrt's LookAt is glm's left-handed one: x = up x dir, y = dir x x, z = dir.
    mat4 camera_from_world = glm::lookAtLH(eye, at, up);
    if (c.mirror_camera)
      camera_from_world = glm::scale(mat4(1.0f), vec3(-1, 1, 1)) * camera_from_world;
    const vec2 expected = pbrt_raster(camera_from_world, 30.0f, c.w, c.h, centre);
    const vec2 got = centroid(render(s, 16, 1));
    EXPECT_NEAR(got.x, expected.x, 0.6f) << c.w << "x" << c.h << " mirror " << c.mirror_camera;
    EXPECT_NEAR(got.y, expected.y, 0.6f) << c.w << "x" << c.h << " mirror " << c.mirror_camera;
    // The sphere sits right of the view axis in pbrt's image unless the camera is mirrored.
    EXPECT_EQ(got.x > 0.5f * float(c.w), !c.mirror_camera);
  }
}

TEST(Pbrt, FovSpansTheShorterImageAxis) {
  const std::string cam = "Camera \"perspective\" \"float fov\" [40]\n";
  EXPECT_NEAR(load(film(200, 100) + cam + "WorldBegin\n" + kTriangle).camera.vfov_deg, 40.0f,
              1e-4f);
  const float portrait = load(film(100, 200) + cam + "WorldBegin\n" + kTriangle).camera.vfov_deg;
  EXPECT_NEAR(portrait, glm::degrees(2.0f * std::atan(2.0f * std::tan(glm::radians(20.0f)))),
              1e-3f);
  // Film after Camera counts too (the camera is resolved at WorldBegin).
  EXPECT_NEAR(load(cam + film(100, 200) + "WorldBegin\n" + kTriangle).camera.vfov_deg, portrait,
              1e-4f);
}

TEST(Pbrt, CameraAndRenderSettings) {
  const Scene s = load(
      "Integrator \"path\" \"integer maxdepth\" [ 4 ]\n"
      "Sampler \"halton\" \"integer pixelsamples\" 7\n" +
      film(40, 30) +
      "LookAt 0 0 0  0 0 1  0 1 0\n"
      "Camera \"perspective\" \"float fov\" 50 \"float lensradius\" 0.1 \"float focaldistance\" 3\n"
      "WorldBegin\n" +
      std::string(kTriangle));
  EXPECT_EQ(s.settings.width, 40);
  EXPECT_EQ(s.settings.height, 30);
  EXPECT_EQ(s.settings.spp, 7);
  EXPECT_EQ(s.settings.max_depth, 5);  // pbrt's bounces + the camera segment
  EXPECT_FLOAT_EQ(s.camera.aperture_radius, 0.1f);
  EXPECT_FLOAT_EQ(s.camera.focus_distance, 3.0f);
  EXPECT_EQ(s.diagnostics.warnings.size(), 1u) << all_warnings(s);  // only "no light"
  EXPECT_EQ(count_warnings(s, "scene has no light"), 1);
  // pbrt's defaults without any option: 1280x720, 16 spp, maxdepth 5, fov 90.
  const Scene d = load("WorldBegin\n" + std::string(kTriangle));
  EXPECT_EQ(d.settings.width, 1280);
  EXPECT_EQ(d.settings.spp, 16);
  EXPECT_EQ(d.settings.max_depth, 6);
  EXPECT_FLOAT_EQ(d.camera.vfov_deg, 90.0f);
}

TEST(Pbrt, TransformsAndBlocks) {
  // Identity camera: our world is pbrt's with x negated.
  const Scene s = load(
      "WorldBegin\n"
      "AttributeBegin\n"
      "  Transform [1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1]\n" +
      std::string(kTriangle) +  // column-major
      "AttributeEnd\n"
      "AttributeBegin\n  Translate 1 0 0\n  ConcatTransform [2 0 0 0 0 2 0 0 0 0 2 0 0 0 0 1]\n" +
      kTriangle +
      "AttributeEnd\n"
      "AttributeBegin\n  Rotate 90 0 0 1\n  Scale 3 1 1\n" +
      kTriangle +
      "AttributeEnd\n"
      "TransformBegin\n  Translate 0 0 9\n  Material \"diffuse\" \"rgb reflectance\" [0.1 0.2 "
      "0.3]\nTransformEnd\n" +
      kTriangle + "CoordinateSystem \"here\"\nTranslate 0 0 100\nCoordSysTransform \"here\"\n" +
      kTriangle);
  ASSERT_EQ(s.mesh.indices.size(), 5u);
  auto vertex = [&](size_t t, int k) { return s.mesh.positions[s.mesh.indices[t][k]]; };
  auto has_vertex = [&](size_t t, vec3 p) {
    for (int k = 0; k < 3; ++k)
      if (glm::length(vertex(t, k) - p) < 1e-5f) return true;
    return false;
  };
  EXPECT_TRUE(has_vertex(0, vec3(-5, 6, 7)));
  EXPECT_TRUE(has_vertex(0, vec3(-6, 6, 7)));
  EXPECT_TRUE(has_vertex(1, vec3(-3, 0, 0)));  // translate then scale 2: (1,0,0) -> (3,0,0)
  EXPECT_TRUE(has_vertex(2, vec3(0, 3, 0)));   // scale x by 3, then rotate x onto y
  // TransformEnd restored the transform but kept the material.
  EXPECT_TRUE(has_vertex(3, vec3(0, 0, 0)));
  EXPECT_EQ(material_of_triangle(s, 3).albedo, vec3(0.1f, 0.2f, 0.3f));
  EXPECT_TRUE(has_vertex(4, vec3(0, 0, 0)));                 // CoordSysTransform went back
  EXPECT_EQ(material_of_triangle(s, 0).albedo, vec3(0.5f));  // pbrt's default diffuse
}

// pbrt's area lights emit on the side of the surface normal: counter-clockwise winding, or the
// side of the vertex normals N, flipped by ReverseOrientation; mirroring transforms keep it.
TEST(Pbrt, OrientationOfEmittersMatchesPbrt) {
  const std::string head =
      "LookAt 0.3 0.3 -3  0.3 0.3 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\n" +
      film(16, 16) + "WorldBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n";
  // The triangle's counter-clockwise normal is +z, away from the camera at z = -3.
  struct Case {
    std::string prefix, extra;
    bool faces_camera;
  };
  const Case cases[] = {
      {"", "", false},
      {"ReverseOrientation\n", "", true},
      {"", " \"normal N\" [0 0 -1 0 0 -1 0 0 -1]", true},
      {"ReverseOrientation\n", " \"normal N\" [0 0 -1 0 0 -1 0 0 -1]", false},
      {"Scale -1 1 1\nTranslate -0.6 0 0\n", "", false},  // a mirroring transform keeps the side
  };
  for (const Case& c : cases) {
    const Scene s =
        load(head + c.prefix +
             "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]" +
             c.extra + "\n");
    const ImageRGB img = render(s, 4, 1);
    float total = 0.0f;
    for (float v : img.pixels) total += v;
    EXPECT_EQ(total > 0.0f, c.faces_camera) << c.prefix << c.extra;
  }
}

TEST(Pbrt, AreaLightsApplyToTheirBlock) {
  const Scene s = load(
      "WorldBegin\nAttributeBegin\n"
      "  AreaLightSource \"diffuse\" \"rgb L\" [1 2 3] \"float scale\" 2 \"bool twosided\" true\n" +
      std::string(kTriangle) + "AttributeEnd\n" + kTriangle +
      "AttributeBegin\n  AreaLightSource \"diffuse\" \"blackbody L\" 6500\n" + kTriangle +
      "AttributeEnd\n");
  ASSERT_EQ(s.mesh.indices.size(), 3u);
  EXPECT_EQ(material_of_triangle(s, 0).emission, vec3(2, 4, 6));
  EXPECT_TRUE(material_of_triangle(s, 0).flags & kMaterialTwoSidedEmission);
  EXPECT_FALSE(material_of_triangle(s, 1).is_emissive());
  const vec3 bb = material_of_triangle(s, 2).emission;
  EXPECT_NEAR(luminance(bb), 1.0f, 0.02f);  // pbrt normalises spectra of lights to 1 nit
  EXPECT_NEAR(bb.x, 1.0f, 0.15f);
  EXPECT_NEAR(bb.z, 1.0f, 0.15f);
  EXPECT_FALSE(material_of_triangle(s, 2).flags & kMaterialTwoSidedEmission);
}

TEST(Pbrt, MaterialsMapToTheClosestOfOurs) {
  const Scene s = load(
      "WorldBegin\n"
      "MakeNamedMaterial \"silver\" \"string type\" \"conductor\" \"spectrum eta\" "
      "\"metal-Ag-eta\"\n"
      "  \"spectrum k\" \"metal-Ag-k\" \"float roughness\" 0.04\n"
      "MakeNamedMaterial \"raw\" \"string type\" \"conductor\" \"rgb eta\" [0.2 0.9 1.1]\n"
      "  \"rgb k\" [3.9 2.5 2.1] \"float uroughness\" 0.04 \"float vroughness\" 0.09 \"bool "
      "remaproughness\" false\n"
      "MakeNamedMaterial \"water\" \"string type\" \"dielectric\" \"float eta\" 1.33\n"
      "MakeNamedMaterial \"bk7\" \"string type\" \"dielectric\" \"spectrum eta\" \"glass-BK7\"\n"
      "MakeNamedMaterial \"plastic\" \"string type\" \"coateddiffuse\" \"rgb reflectance\" [0.8 "
      "0.2 0.1]\n"
      "MakeNamedMaterial \"plastic2\" \"string type\" \"coateddiffuse\"\n"
      "MakeNamedMaterial \"leaf\" \"string type\" \"diffusetransmission\" \"rgb reflectance\" [0.1 "
      "0.6 0.1]\n"
      "MakeNamedMaterial \"blend\" \"string type\" \"mix\" \"string materials\" [\"water\" "
      "\"plastic\"] \"float amount\" 0.8\n"
      "MakeNamedMaterial \"boundary\" \"string type\" \"interface\"\n"
      "NamedMaterial \"silver\"\n" +
      std::string(kTriangle) + "NamedMaterial \"raw\"\n" + kTriangle + "NamedMaterial \"water\"\n" +
      kTriangle + "NamedMaterial \"bk7\"\n" + kTriangle + "NamedMaterial \"plastic\"\n" +
      kTriangle + "NamedMaterial \"plastic2\"\n" + kTriangle + "NamedMaterial \"leaf\"\n" +
      kTriangle + "NamedMaterial \"blend\"\n" + kTriangle + "NamedMaterial \"boundary\"\n" +
      kTriangle);
  ASSERT_EQ(s.mesh.indices.size(), 8u);  // the interface's triangle is skipped
  vec3 eta, k;
  ASSERT_TRUE(pbrt_named_metal("metal-Ag-eta", &eta) && pbrt_named_metal("metal-Ag-k", &k));
  const Material& silver = material_of_triangle(s, 0);
  EXPECT_EQ(silver.type, MaterialType::kConductor);
  EXPECT_TRUE(silver.flags & kMaterialConductorIor);  // the exact Fresnel of eta + i k
  EXPECT_EQ(silver.eta, eta);
  EXPECT_EQ(silver.k, k);
  EXPECT_EQ(silver.albedo, vec3(1.0f));
  // remaproughness (default true): alpha = sqrt(0.04) = 0.2, ours = sqrt(alpha).
  EXPECT_NEAR(silver.roughness, std::sqrt(0.2f), 1e-5f);
  EXPECT_FALSE(silver.is_anisotropic());
  const Material& raw = material_of_triangle(s, 1);
  EXPECT_NEAR(raw.roughness, 0.2f, 1e-5f);    // alpha 0.04 along u, as given
  EXPECT_NEAR(raw.roughness_v, 0.3f, 1e-5f);  // alpha 0.09 along v
  EXPECT_EQ(raw.eta, vec3(0.2f, 0.9f, 1.1f));
  EXPECT_EQ(raw.k, vec3(3.9f, 2.5f, 2.1f));
  EXPECT_EQ(material_of_triangle(s, 2).type, MaterialType::kDielectric);
  EXPECT_FLOAT_EQ(material_of_triangle(s, 2).ior, 1.33f);
  EXPECT_NEAR(material_of_triangle(s, 3).ior, 1.5168f, 1e-4f);
  // coateddiffuse: our coated diffuse, pbrt's defaults (eta 1.5, smooth, a 0.01 layer of unit
  // extinction that scatters nothing: absorption 1 x thickness 0.01).
  const Material& plastic = material_of_triangle(s, 4);
  EXPECT_EQ(plastic.type, MaterialType::kCoatedDiffuse);
  EXPECT_EQ(plastic.albedo, vec3(0.8f, 0.2f, 0.1f));
  EXPECT_EQ(plastic.ior, 1.5f);
  EXPECT_EQ(plastic.roughness, 0.0f);
  EXPECT_EQ(plastic.absorption, vec3(1.0f));
  EXPECT_FLOAT_EQ(plastic.thickness, 0.01f);
  EXPECT_EQ(material_of_triangle(s, 5).albedo, vec3(0.5f));
  const Material& leaf = material_of_triangle(s, 6);
  EXPECT_EQ(leaf.type, MaterialType::kDiffuseTransmission);
  EXPECT_EQ(leaf.albedo, vec3(0.1f, 0.6f, 0.1f));
  EXPECT_EQ(leaf.transmittance, vec3(0.25f));                            // pbrt's default
  EXPECT_EQ(material_of_triangle(s, 7).albedo, vec3(0.8f, 0.2f, 0.1f));  // amount 0.8: "plastic"
  // What maps without loss says nothing; one warning per kind and file, at the first
  // occurrence, naming the substitute, for the rest.
  EXPECT_EQ(count_warnings(s, "conductor"), 0) << all_warnings(s);
  EXPECT_EQ(count_warnings(s, "coateddiffuse"), 0) << all_warnings(s);
  EXPECT_EQ(count_warnings(s, "transmission"), 0) << all_warnings(s);
  EXPECT_EQ(count_warnings(s, "dispersion of \"glass-BK7\""), 1);
  EXPECT_EQ(count_warnings(s, "used \"plastic\", the one of larger weight"), 1);
  EXPECT_EQ(count_warnings(s, "\"interface\" bounds participating media"), 1);
}

TEST(Pbrt, TexturesImageCheckerboardAndMissingFiles) {
  const std::string dir = temp_dir();
  std::filesystem::create_directories(dir + "/tex");
  const uint8_t px[16] = {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 255};
  write_png_rgba8(dir + "/tex/check.png", 2, 2, px, false);
  const std::string scene = write_file(
      dir + "/scene.pbrt",
      "WorldBegin\n"
      "Texture \"img\" \"spectrum\" \"imagemap\" \"string filename\" \"tex/check.png\" \"string "
      "filter\" \"bilinear\"\n"
      "Texture \"lin\" \"spectrum\" \"imagemap\" \"string filename\" \"tex/check.png\" \"string "
      "encoding\" \"linear\"\n"
      "Texture \"gone\" \"spectrum\" \"imagemap\" \"string filename\" \"tex/missing.png\"\n"
      "Texture \"checks\" \"spectrum\" \"checkerboard\" \"float uscale\" 2 \"float vscale\" 2\n"
      "  \"rgb tex1\" [1 0 0] \"rgb tex2\" [0 0 1]\n"
      "Material \"diffuse\" \"texture reflectance\" \"img\"\n" +
          std::string(kTriangle) + "Material \"diffuse\" \"texture reflectance\" \"lin\"\n" +
          kTriangle + "Material \"diffuse\" \"texture reflectance\" \"gone\"\n" + kTriangle +
          "Material \"diffuse\" \"texture reflectance\" \"checks\"\n" + kTriangle);
  const Scene s = load_scene(scene);
  ASSERT_EQ(s.textures.size(), 3u);  // two decodings of the image and the checkerboard
  EXPECT_EQ(material_of_triangle(s, 0).base_color_tex, 0u);
  EXPECT_TRUE(s.textures[0].srgb);
  EXPECT_FALSE(s.textures[material_of_triangle(s, 1).base_color_tex].srgb);
  EXPECT_EQ(material_of_triangle(s, 2).base_color_tex, kInvalid);
  EXPECT_EQ(count_warnings(s, "scene.pbrt:4: image texture \"tex/missing.png\" not found"), 1)
      << all_warnings(s);
  // The checkerboard: our uv (0, 0) is pbrt's (0, 1): floor(0) + floor(2 * ~1) is odd: tex2.
  const TextureImage& c = s.textures[material_of_triangle(s, 3).base_color_tex];
  EXPECT_EQ(c.width, 32);
  EXPECT_EQ(c.rgba8[0], 0);
  EXPECT_EQ(c.rgba8[2], 255);
  const size_t right = size_t(c.width - 1) * 4;  // u ~ 1: floor(2) + floor(2): even: tex1
  EXPECT_EQ(c.rgba8[right], 255);
  EXPECT_EQ(c.rgba8[right + 2], 0);
  // A texture coordinate's v is flipped: pbrt's image lookups use 1 - v.
  const Scene uv = load(
      "WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n"
      "  \"point2 uv\" [0 0.25 1 0 0 1]\n");
  EXPECT_EQ(uv.mesh.uvs[uv.mesh.indices[0].x], vec2(0.0f, 0.75f));
}

TEST(Pbrt, InstancesFlattenToTheirPlacements) {
  Scene s = load(
      "WorldBegin\n"
      "ObjectBegin \"tri\"\n  Material \"diffuse\" \"rgb reflectance\" [0.2 0.3 0.4]\n  Translate "
      "0 1 0\n" +
      std::string(kTriangle) +
      "ObjectEnd\n"
      "AttributeBegin\n  Translate 10 0 0\n  ObjectInstance \"tri\"\nAttributeEnd\n"
      "ObjectInstance \"tri\"\n" +
      kTriangle);
  // The object is one instanced mesh placed twice (instances_test.cpp checks the instancing);
  // flattened, its copies follow the scene's own triangle.
  ASSERT_EQ(s.mesh.indices.size(), 1u);
  ASSERT_EQ(s.instances.size(), 2u);
  EXPECT_TRUE(contains(s.objects[0].name, "tri #1"));
  EXPECT_TRUE(contains(s.objects[1].name, "tri #2"));
  flatten_instances(s);
  ASSERT_EQ(s.mesh.indices.size(), 3u);
  EXPECT_EQ(s.mesh.positions[s.mesh.indices[1].x], vec3(-10, 1, 0));
  EXPECT_EQ(s.mesh.positions[s.mesh.indices[2].x], vec3(0, 1, 0));
  EXPECT_EQ(material_of_triangle(s, 1).albedo, vec3(0.2f, 0.3f, 0.4f));
  EXPECT_EQ(material_of_triangle(s, 0).albedo, vec3(0.5f));  // ObjectEnd closed the attributes
}

TEST(Pbrt, IncludeResolvesAgainstTheMainFile) {
  const std::string dir = temp_dir();
  write_file(
      dir + "/meshes/quad.ply",
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
  write_file(dir + "/parts/geometry.pbrt",
             "MakeNamedMaterial \"red\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.7 0 0]\n"
             "NamedMaterial \"red\"\n"
             "Shape \"plymesh\" \"string filename\" \"meshes/quad.ply\"\n");
  write_file(dir + "/parts/broken.pbrt",
             "\n\nShape \"plymesh\" \"string filename\" \"meshes/none.ply\"\n");
  const std::string main = write_file(dir + "/main.pbrt",
                                      "WorldBegin\nInclude \"parts/geometry.pbrt\"\n"
                                      "Import \"parts/geometry.pbrt\"\n" +
                                          std::string(kTriangle));
  // Import defines "red" a second time: an error naming the included file's line.
  const std::string twice = error_of(read_file(main), main);
  EXPECT_TRUE(contains(twice, dir + "/parts/geometry.pbrt:1: material \"red\" is defined twice"))
      << twice;
  write_file(main, "WorldBegin\nInclude \"parts/geometry.pbrt\"\n" + std::string(kTriangle));
  const Scene s = load_scene(main);
  ASSERT_EQ(s.mesh.indices.size(), 3u);  // the quad in two triangles, then the triangle
  EXPECT_EQ(material_of_triangle(s, 0).albedo, vec3(0.7f, 0, 0));
  EXPECT_EQ(material_of_triangle(s, 2).albedo, vec3(0.7f, 0, 0));  // the include set the state
  EXPECT_EQ(s.objects[0].name, "quad.ply");
  write_file(main, "WorldBegin\nInclude \"parts/broken.pbrt\"\n");
  const std::string missing = error_of(read_file(main), main);
  EXPECT_TRUE(
      contains(missing, dir + "/parts/broken.pbrt:3: cannot open \"" + dir + "/meshes/none.ply\""))
      << missing;
  write_file(dir + "/loop.pbrt", "Include \"loop.pbrt\"\n");
  EXPECT_TRUE(contains(error_of(read_file(dir + "/loop.pbrt"), dir + "/loop.pbrt"),
                       "Include nested more than 32 deep"));
}

TEST(Pbrt, QuadricsAndPatchesBecomeTriangles) {
  const Scene s = load(
      "WorldBegin\n"
      "Shape \"disk\" \"float radius\" 2 \"float innerradius\" 1\n"
      "Shape \"cylinder\" \"float phimax\" 180\n"
      "Shape \"sphere\" \"float zmax\" 0\n"
      "Shape \"bilinearmesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 0]\n"
      "AttributeBegin\n Scale 1 2 1\n Shape \"sphere\"\nAttributeEnd\n"
      "Shape \"sphere\" \"float radius\" 3\n"
      "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 0 0 3 0 0]\n"
      "Shape \"loopsubdiv\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\n");
  EXPECT_EQ(s.spheres.size(), 1u);  // only the full sphere under a similarity stays analytic
  EXPECT_FLOAT_EQ(s.spheres[0].radius, 3.0f);
  EXPECT_GT(s.mesh.indices.size(), 500u);
  EXPECT_EQ(count_warnings(s, "scene.pbrt:8: a sphere under a non-uniform scale or shear"), 1);
  EXPECT_EQ(count_warnings(s, "Shape \"curve\" (hair and fur) is not supported; skipped it"), 1);
  EXPECT_EQ(count_warnings(s, "Loop subdivision is not supported"), 1);
}

TEST(Pbrt, UnsupportedLightsAndOptionsWarnOncePerKind) {
  const Scene s = load(
      "PixelFilter \"gaussian\"\nAccelerator \"bvh\"\nIntegrator \"bdpt\" \"integer maxdepth\" 3\n"
      "WorldBegin\n"
      "LightSource \"goniometric\" \"rgb I\" [1 1 1]\n"
      "LightSource \"goniometric\"\n"
      "LightSource \"projection\" \"string filename\" \"slide.exr\"\n"
      "LightSource \"point\" \"rgb I\" [1 1 1]\nLightSource \"spot\"\n"
      "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\"\n"
      "Shape \"sphere\" \"float radus\" 2\n");
  for (const char* kind : {"goniometric", "projection"})
    EXPECT_EQ(count_warnings(
                  s, "LightSource \"" + std::string(kind) + "\" is not supported yet; skipped"),
              1)
        << kind << "\n"
        << all_warnings(s);
  EXPECT_EQ(
      count_warnings(
          s, "scene.pbrt:5: LightSource \"goniometric\" is not supported yet; skipped (and 1 more"),
      1);
  EXPECT_EQ(s.point_lights.size(), 2u) << "point and spot lights are supported";
  EXPECT_EQ(count_warnings(s, "LightSource \"point\""), 0);
  EXPECT_EQ(count_warnings(s, "LightSource \"spot\""), 0);
  EXPECT_EQ(count_warnings(s, "PixelFilter"), 0);  // a supported filter (render.filter)
  EXPECT_EQ(s.settings.filter, tracer::PixelFilter::kGaussian);
  EXPECT_EQ(count_warnings(s, "Integrator \"bdpt\" is not supported; substituted our path tracer"),
            1);
  EXPECT_EQ(count_warnings(s, "participating media are not supported"), 1);
  EXPECT_EQ(count_warnings(s,
                           "scene.pbrt:11: Shape \"sphere\" has no parameter \"float radus\" (did "
                           "you mean \"radius\"?); ignored it"),
            1)
      << all_warnings(s);
  EXPECT_EQ(s.settings.max_depth, 4);
}

// Every error: "path:line: what; nothing was rendered".
TEST(Pbrt, ErrorsNameFileAndLine) {
  struct Case {
    std::string text, expected;
  };
  const Case cases[] = {
      {"WorldBegin\nShap \"sphere\"\n",
       "scene.pbrt:2: unknown directive \"Shap\" (did you mean \"Shape\"?)"},
      {"WorldBegin\n\nShape \"sphere\" \"flaot radius\" 2\n",
       "scene.pbrt:3: Shape \"sphere\": unknown parameter type \"flaot\" in \"flaot radius\" (did "
       "you mean \"float\"?)"},
      {"WorldBegin\nShape \"sphere\" \"float radius\" [ \"one\" ]\n",
       "scene.pbrt:2: Shape \"sphere\": \"float radius\" takes numbers, but its value holds a "
       "string"},
      {"WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n  \"integer indices\" "
       "[0 1 2.5]\n",
       "scene.pbrt:3: Shape \"trianglemesh\": \"integer indices\" takes integers"},
      {"WorldBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0.5 0.5]\n",
       "scene.pbrt:2: Material \"diffuse\": \"rgb reflectance\" takes numbers in groups of 3, but "
       "has 2"},
      {"WorldBegin\nShape \"sphere\" \"integer radius\" 2\n",
       "scene.pbrt:2: Shape \"sphere\": parameter \"integer radius\" has the wrong type; "
       "\"radius\" takes \"float\""},
      {"WorldBegin\nShape \"sphere\" \"string radius\" \"big\"\n", "has the wrong type"},
      {"WorldBegin\nShape \"sphere\" \"bool alpha\" maybe\n",
       "scene.pbrt:2: expected a number in Shape \"sphere\" \"bool alpha\", found maybe"},
      {"WorldBegin\nShape \"plymesh\" \"string filename\" \"nowhere.ply\"\n",
       "scene.pbrt:2: cannot open \"/nonexistent/nowhere.ply\""},
      {"Include \"other.pbrt\"\n", "scene.pbrt:1: cannot open \"/nonexistent/other.pbrt\""},
      {"WorldBegin\nShape \"sphere\" \"string name\" \"unterminated\n",
       "scene.pbrt:2: unterminated string \"unterminated\""},
      {"WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0\nShape \"sphere\"\n",
       "scene.pbrt:2: Shape \"trianglemesh\": unterminated '[' of \"point3 P\" (found Shape at "
       "line 3 before its ']')"},
      {"WorldBegin\nShape \"sphere\" \"float radius\" [ 1\n",
       "scene.pbrt:2: Shape \"sphere\": unterminated '[' of \"float radius\" (found the end of the "
       "file"},
      {"Translate 1 2\nWorldBegin\n",
       "scene.pbrt:2: expected a number in Translate (line 1), found WorldBegin"},
      {"WorldBegin\nMaterial \"difuse\"\n",
       "scene.pbrt:2: unknown material type \"difuse\" (did you mean \"diffuse\"?)"},
      {"WorldBegin\nMakeNamedMaterial \"a\" \"string type\" \"diffuse\"\nNamedMaterial \"b\"\n",
       "scene.pbrt:3: NamedMaterial \"b\" is not defined"},
      {"WorldBegin\nMakeNamedMaterial \"glass\" \"string type\" \"diffuse\"\nNamedMaterial "
       "\"glas\"\n",
       "(did you mean \"glass\"?)"},
      {"WorldBegin\nAttributeEnd\n",
       "scene.pbrt:2: AttributeEnd without a matching AttributeBegin"},
      {"WorldBegin\nAttributeBegin\nTransformEnd\n",
       "scene.pbrt:3: TransformEnd closes the AttributeBegin of line 2"},
      {"Shape \"sphere\"\n", "scene.pbrt:1: Shape is only allowed after WorldBegin"},
      {"WorldBegin\nCamera \"perspective\"\n",
       "scene.pbrt:2: Camera is only allowed before WorldBegin"},
      {"WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 "
       "1 3]\n",
       "scene.pbrt:2: Shape \"trianglemesh\": index 3 (entry 2 of \"indices\") is out of range; "
       "\"P\" has 3 points"},
      {"WorldBegin\nShape \"spere\"\n",
       "scene.pbrt:2: unknown Shape \"spere\" (did you mean \"sphere\"?)"},
      {"WorldBegin\nMaterial \"conductor\" \"spectrum eta\" \"metal-Agg-eta\"\n",
       "unknown named spectrum \"metal-Agg-eta\" (did you mean \"metal-Ag-eta\"?)"},
      {"WorldBegin\nObjectInstance \"tree\"\n", "scene.pbrt:2: ObjectInstance: no object \"tree\""},
      {"WorldBegin\nLightSource \"sun\"\n", "scene.pbrt:2: unknown LightSource \"sun\""},
      {"WorldBegin\nMaterial \"diffuse\" \"texture reflectance\" \"wood\"\n",
       "scene.pbrt:2: Material \"diffuse\": texture \"wood\" is not defined"},
      {"Camera \"perspective\" \"float fov\" 200\nWorldBegin\n", "scene.pbrt:1: Camera fov 200"},
      {"LookAt 0 0 0  0 0 1  0 0 1\n", "scene.pbrt:1: LookAt: the up vector [0, 0, 1] is parallel"},
      {"[ 1 2 ]\n", "scene.pbrt:1: expected a directive, found '['"},
      {"WorldBegin\nShape \"sphere\" \"float radius\" 1e99\n", "scene.pbrt:2: the number 1e99"},
      {"WorldBegin\nShape \"sphere\" \"float radius\" nan\n", "scene.pbrt:2: expected a number"},
      {"WorldBegin\nShape \"sphere\" \"float radius\" \"float radius\" 2\n", "takes numbers"},
      {"WorldBegin\nShape \"sphere\" \"float radius\" 1 \"float radius\" 2\n",
       "parameter \"radius\" is given twice"},
      {"WorldBegin\nShape \"sphere\" \"radius\" 2\n",
       "expected a parameter declaration \"type name\", found \"radius\""},
      {"WorldBegin\nMakeNamedMaterial \"m\" \"rgb reflectance\" [1 1 1]\n",
       "scene.pbrt:2: MakeNamedMaterial \"m\" has no \"string type\""},
      {"WorldBegin\nShape \"sphere\" \"string s\" \"a\\q\"\n",
       "scene.pbrt:2: unknown escape \"\\q\""},
  };
  for (const Case& c : cases) {
    const std::string e = error_of(c.text);
    EXPECT_TRUE(contains(e, c.expected)) << "input:\n" << c.text << "error:\n" << e;
    EXPECT_TRUE(contains(e, "; nothing was rendered")) << e;
    EXPECT_TRUE(contains(e, "/nonexistent/scene.pbrt:")) << e;
  }
}

TEST(Pbrt, LoadScenePicksTheReaderByExtension) {
  const std::string dir = temp_dir();
  const std::string path = write_file(dir + "/x.pbrt", "WorldBegin\n" + std::string(kTriangle));
  EXPECT_EQ(load_scene(path).mesh.indices.size(), 1u);
  try {
    load_scene(dir + "/x.pbrtx");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), ".pbrt")) << e.what();
  }
}

// The shared Bitterli scenes (README.md beside them): each loads and renders small on the CPU,
// with only the warnings its constructs are expected to give.
TEST(Pbrt, BitterliScenesLoadAndRenderWithTheirExpectedWarnings) {
  const std::string root = test::source_dir() + "/../shared/scenes/bitterli";
  if (!std::filesystem::is_directory(root))
    GTEST_SKIP() << "no shared scenes at " << root
                 << " (the Bitterli set lives beside the checkout)";
  struct Case {
    const char* name;
    std::vector<std::string> must;  // warnings that must appear
    bool lit;
  };
  const Case cases[] = {
      {"cornell-box", {}, true},
      {"veach-mis", {}, true},  // rough conductors (eta, k) map without a warning
      {"coffee", {}, true},     // coated diffuse, silver's named spectra: likewise
      {"water-caustic", {"Integrator \"sppm\" is not supported"}, true},
      // A distant light and an infinite light (its sky through the windows).
      {"classroom", {"blackboard.tga\" not found"}, true},
  };
  // Everything a warning of these scenes may say.
  const std::vector<std::string> allowed = {"Integrator \"sppm\"",
                                            "zero-area triangle",
                                            "not supported yet; skipped",
                                            "blackboard.tga\" not found",
                                            "scene has no light"};
  for (const Case& c : cases) {
    const std::string path = root + "/" + c.name + "/scene-v4.pbrt";
    Scene s = load_scene(path);
    for (const std::string& w : s.diagnostics.warnings) {
      bool ok = false;
      for (const std::string& a : allowed) ok |= contains(w, a);
      EXPECT_TRUE(ok) << c.name << ": unexpected warning: " << w;
    }
    for (const std::string& m : c.must) EXPECT_GE(count_warnings(s, m), 1) << c.name << ": " << m;
    s.settings.width = 64;
    s.settings.height = 64;
    const ImageRGB img = render(s, 4, s.settings.max_depth);
    double sum = 0.0;
    for (float v : img.pixels) {
      ASSERT_TRUE(std::isfinite(v)) << c.name;
      sum += v;
    }
    EXPECT_EQ(sum > 0.0, c.lit) << c.name;
  }
}

// Random damage to a scene that uses most directives: every variant loads or fails with an
// InputError; nothing crashes, hangs or throws anything else.
TEST(Pbrt, DamagedScenesFailCleanly) {
  const std::string good =
      "Integrator \"path\" \"integer maxdepth\" [ 4 ]\nSampler \"stratified\" \"integer xsamples\" "
      "2\n"
      "Transform [ 1 0 0 0 0 1 0 0 0 0 -1 0 0 -1 6.8 1 ]\n" +
      film(16, 12) +
      "Camera \"perspective\" \"float fov\" [ 19.5 ] \"float lensradius\" 0.01\n"
      "WorldBegin\nTexture \"c\" \"spectrum\" \"checkerboard\" \"float uscale\" 4 \"rgb tex1\" [1 "
      "0 0]\n"
      "MakeNamedMaterial \"m\" \"string type\" \"diffuse\" \"texture reflectance\" \"c\"\n"
      "MakeNamedMaterial \"g\" \"string type\" \"dielectric\" \"float eta\" 1.5 \"float "
      "roughness\" 0.1\n"
      "MakeNamedMaterial \"x\" \"string type\" \"mix\" \"string materials\" [ \"m\" \"g\" ]\n"
      "ObjectBegin \"o\"\nNamedMaterial \"m\"\nShape \"disk\" \"float radius\" 0.3\nObjectEnd\n"
      "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [ 17 12 4 ]\nTranslate 0 1.9 0\n"
      "Rotate 90 1 0 0\nReverseOrientation\nShape \"disk\" \"float radius\" 0.3\nAttributeEnd\n"
      "TransformBegin\nScale 2 1 1\nObjectInstance \"o\"\nTransformEnd\nNamedMaterial \"x\"\n"
      "Shape \"sphere\" \"float radius\" 0.5 \"float zmin\" -0.2\n"
      "Shape \"trianglemesh\" \"point3 P\" [ -1 0 -1 -1 0 1 1 0 1 1 0 -1 ]\n"
      "  \"integer indices\" [ 0 1 2 0 2 3 ] \"normal N\" [ 0 1 0 0 1 0 0 1 0 0 1 0 ]\n"
      "  \"point2 uv\" [ 0 0 1 0 1 1 0 1 ]\n"
      "Shape \"bilinearmesh\" \"point3 P\" [ 0 0 0 1 0 0 0 1 0 1 1 0 ]\n";
  ASSERT_NO_THROW(load(good));
  const char pieces[] = "\"[]# \n0-.e9xAS";
  std::mt19937 rng(21);
  int loaded = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::string s = good;
    const int edits = 1 + int(rng() % 3);
    for (int k = 0; k < edits; ++k) {
      const size_t at = rng() % s.size();
      switch (rng() % 3) {
        case 0:
          s.erase(at, 1 + rng() % 8);
          break;
        case 1:
          s.insert(at, 1, pieces[rng() % (sizeof pieces - 1)]);
          break;
        default:
          s[at] = pieces[rng() % (sizeof pieces - 1)];
          break;
      }
    }
    try {
      load(s);
      ++loaded;
    } catch (const InputError&) {
    }
  }
  EXPECT_GT(loaded, 0);
}

namespace {

// pbrt's PixelFilter maps onto render.filter with its radius; its default is pbrt-v4's Gaussian.
TEST(PbrtFilter, PixelFiltersMapOntoTheRenderFilter) {
  char tmpl[] = "/tmp/pathtracer_pbrtfilter_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  auto load = [&](const std::string& directive) {
    std::ofstream(dir + "/f.pbrt") << directive
                                   << "\nWorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\"\n"
                                      "Shape \"sphere\" \"float radius\" 1\nAttributeEnd\n";
    return tracer::load_scene(dir + "/f.pbrt");
  };
  tracer::Scene s = load("");
  EXPECT_EQ(s.settings.filter, tracer::PixelFilter::kGaussian);
  EXPECT_EQ(s.settings.filter_radius, 1.5f);
  s = load("PixelFilter \"triangle\"");
  EXPECT_EQ(s.settings.filter, tracer::PixelFilter::kTent);
  EXPECT_EQ(s.settings.filter_radius, 2.0f);  // pbrt-v4's triangle default
  s = load("PixelFilter \"box\" \"float xradius\" [ 1 ] \"float yradius\" [ 1 ]");
  EXPECT_EQ(s.settings.filter, tracer::PixelFilter::kBox);
  EXPECT_EQ(s.settings.filter_radius, 1.0f);
  s = load("PixelFilter \"mitchell\"");
  EXPECT_EQ(s.settings.filter, tracer::PixelFilter::kGaussian);
  ASSERT_FALSE(s.diagnostics.warnings.empty());
  EXPECT_NE(s.diagnostics.warnings[0].find("f.pbrt:1: PixelFilter \"mitchell\" is not supported"),
            std::string::npos) << s.diagnostics.warnings[0];
  EXPECT_THROW(load("PixelFilter \"box\" \"float xradius\" [ -1 ]"), tracer::InputError);
}

}  // namespace

// ---- LightSource -------------------------------------------------------------------------------

namespace {

// Our world from pbrt's, for a scene without a camera (pbrt's camera space is left-handed:
// the reader mirrors x).
vec3 ours(vec3 p) {
  return vec3(pbrt_world_to_ours(mat4(1.0f)) * vec4(p, 1.0f));
}

// A square PFM whose texels are `value`, but for one texel (hx, hy) of `hot` (rows top to
// bottom, as pbrt-v4 and our reader lay them out).
std::string write_octahedral_pfm(const std::string& path, int n, float value, int hx = -1,
                                 int hy = -1, float hot = 0.0f) {
  std::ofstream f(path, std::ios::binary);
  f << "PF\n" << n << " " << n << "\n-1\n";
  for (int y = n - 1; y >= 0; --y)
    for (int x = 0; x < n; ++x)
      for (int c = 0; c < 3; ++c) {
        const float v = x == hx && y == hy ? hot : value;
        f.write(reinterpret_cast<const char*>(&v), 4);
      }
  return path;
}

}  // namespace

TEST(PbrtLights, PointAndSpot) {
  const Scene s = load(
      "WorldBegin\n"
      "AttributeBegin\nTranslate 1 2 3\n"
      "LightSource \"point\" \"rgb I\" [1 2 3] \"float scale\" 2 \"point3 from\" [0 0 1]\n"
      "AttributeEnd\n"
      "LightSource \"point\" \"float power\" 100\n"
      "LightSource \"point\" \"blackbody I\" 3000\n"
      "LightSource \"spot\" \"point3 from\" [0 5 0] \"point3 to\" [1 0 0] \"float coneangle\" 40 "
      "\"float conedeltaangle\" 10 \"rgb I\" [5 5 5]\n"
      "LightSource \"spot\" \"float power\" 50\n" +
      std::string(kTriangle));
  ASSERT_EQ(s.point_lights.size(), 5u) << all_warnings(s);
  EXPECT_TRUE(s.diagnostics.warnings.empty()) << all_warnings(s);
  const PointLightDesc& a = s.point_lights[0];
  EXPECT_FALSE(a.spot);
  EXPECT_EQ(a.position, ours(vec3(1, 2, 4)));  // "from" under the CTM
  EXPECT_EQ(a.intensity, vec3(2, 4, 6));       // I x scale
  EXPECT_EQ(a.name, "point (scene.pbrt:4)");
  Scene edited = s;  // the name works in lights.NAME.FIELD, dots and all
  EXPECT_EQ(set_setting_assignment(edited, "lights.point (scene.pbrt:4).intensity=1,1,1"), "");
  EXPECT_EQ(edited.point_lights[0].intensity, vec3(1.0f));
  // power: I (pbrt's default illuminant, white) x power / 4 pi.
  EXPECT_NEAR(s.point_lights[1].intensity.x, 100.0 / (4.0 * M_PI), 1e-4);
  EXPECT_NEAR(luminance(s.point_lights[2].intensity), 1.0f, 1e-3f) << "one nit before scale";
  EXPECT_GT(s.point_lights[2].intensity.x, s.point_lights[2].intensity.z) << "3000 K is red";
  const PointLightDesc& sp = s.point_lights[3];
  EXPECT_TRUE(sp.spot);
  EXPECT_EQ(sp.position, ours(vec3(0, 5, 0)));
  const vec3 axis = glm::normalize(ours(vec3(1, -5, 0)) - ours(vec3(0)));
  EXPECT_NEAR(glm::length(sp.direction - axis), 0.0f, 1e-6f);
  EXPECT_FLOAT_EQ(sp.cone_angle_deg, 40.0f);
  EXPECT_FLOAT_EQ(sp.cone_delta_angle_deg, 10.0f);
  EXPECT_EQ(sp.intensity, vec3(5.0f));
  // pbrt's defaults: from (0,0,0) to (0,0,1), coneangle 30, conedeltaangle 5; power over
  // k_e = 2 pi ((1 - cos 25) + (cos 25 - cos 30) / 2).
  const PointLightDesc& d = s.point_lights[4];
  EXPECT_NEAR(glm::length(d.direction - glm::normalize(ours(vec3(0, 0, 1)) - ours(vec3(0)))), 0.0f,
              1e-6f);
  const double c25 = std::cos(glm::radians(25.0)), c30 = std::cos(glm::radians(30.0));
  EXPECT_NEAR(d.intensity.x, 50.0 / (2.0 * M_PI * ((1.0 - c25) + (c25 - c30) / 2.0)), 1e-3);
}

TEST(PbrtLights, Distant) {
  const Scene s = load(
      "WorldBegin\nRotate 90 0 0 1\n"
      "LightSource \"distant\" \"point3 from\" [1 0 0] \"point3 to\" [0 0 0] \"rgb L\" [1 2 3] "
      "\"float scale\" 2\n"
      "LightSource \"distant\" \"float illuminance\" 5\n"
      "LightSource \"distant\" \"rgb L\" [0 0 0]\n" +
      std::string(kTriangle));
  ASSERT_EQ(s.distant_lights.size(), 2u) << all_warnings(s);
  // Towards the light: from - to under the CTM (x turned to y).
  const vec3 up = glm::normalize(ours(vec3(0, 1, 0)) - ours(vec3(0)));
  EXPECT_NEAR(glm::length(glm::normalize(s.distant_lights[0].direction) - up), 0.0f, 1e-6f);
  EXPECT_EQ(s.distant_lights[0].irradiance, vec3(2, 4, 6));  // L x scale on a facing surface
  EXPECT_FLOAT_EQ(s.distant_lights[0].angular_diameter_deg, 0.0f);
  EXPECT_EQ(s.distant_lights[1].irradiance, vec3(5.0f));  // "illuminance" in lux, L at one nit
  EXPECT_EQ(count_warnings(s, "scene.pbrt:5: LightSource \"distant\" has zero radiance"), 1)
      << all_warnings(s);
}

TEST(PbrtLights, InfiniteMapFollowsTheLightTransform) {
  // One hot texel of an equal-area map: pbrt-v4 sees it in light-space direction
  // EqualAreaSquareToSphere(uv); under the classroom's transform (light +z to world +y) and our
  // mirror, that is where our environment must show it.
  const std::string dir = temp_dir();
  const int n = 16, hx = 3, hy = 5;
  write_octahedral_pfm(dir + "/sky.pfm", n, 0.1f, hx, hy, 50.0f);
  const std::string xform =
      "ConcatTransform [ -1 0 8.74228e-8 0 -8.74228e-8 0 -1 0 0 1 0 0 0 0 0 1 ]\n";
  const Scene s = load_pbrt_string(
      "WorldBegin\nAttributeBegin\nRotate 30 0 1 0\n" + xform +
          "LightSource \"infinite\" \"string filename\" \"sky.pfm\" \"float scale\" 3\n"
          "AttributeEnd\n" +
          std::string(kTriangle),
      dir + "/scene.pbrt");
  EXPECT_TRUE(s.diagnostics.warnings.empty()) << all_warnings(s);
  EXPECT_EQ(s.environment.file, dir + "/sky.pfm");
  EXPECT_EQ(s.environment.mapping, EnvMapping::kOctahedral);
  EXPECT_FLOAT_EQ(s.environment.strength, 3.0f);
  ASSERT_TRUE(s.environment_image);
  InfiniteLightsData data;
  build_infinite_lights(s.environment, s.environment_image, {}, &data);
  const vec2 uv((hx + 0.5f) / n, (hy + 0.5f) / n);
  const vec3 w_light = equal_area_square_to_sphere(uv);
  // pbrt's Transform lists the matrix column by column; Rotate 30 about y comes first.
  const mat4 m = glm::rotate(mat4(1.0f), glm::radians(30.0f), vec3(0, 1, 0)) *
                 mat4(-1, 0, 8.74228e-8f, 0, -8.74228e-8f, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1);
  const vec3 w = glm::normalize(mat3(pbrt_world_to_ours(mat4(1.0f))) * (mat3(m) * w_light));
  const vec2 got = env_map_uv(kEnvOctahedral, env_world_to_map(data.view, w));
  EXPECT_NEAR(got.x, uv.x, 1e-5f);
  EXPECT_NEAR(got.y, uv.y, 1e-5f);
  EXPECT_NEAR(env_radiance(data.view, w).x, 3.0f * 50.0f, 1e-2f) << "the hot texel, x scale";
  // pbrt-v4's "illuminance": the map scaled so that its estimate of the upper hemisphere's
  // illuminance (sum of luminance x cos over the texels above, times 2 pi / texels) is E.
  write_octahedral_pfm(dir + "/grey.pfm", 32, 1.0f);
  const Scene e = load_pbrt_string(
      "WorldBegin\nLightSource \"infinite\" \"string filename\" \"grey.pfm\" "
      "\"float illuminance\" 3.14159265\n" +
          std::string(kTriangle),
      dir + "/scene.pbrt");
  EXPECT_NEAR(e.environment.strength, 2.0f, 0.02f) << "pi / (pi / 2), as pbrt-v4 estimates it";
}

TEST(PbrtLights, InfiniteConstantsAddAndASecondMapIsSkipped) {
  const std::string dir = temp_dir();
  write_octahedral_pfm(dir + "/sky.pfm", 8, 1.0f);
  const Scene s = load_pbrt_string(
      "WorldBegin\n"
      "LightSource \"infinite\" \"rgb L\" [0.5 0.6 0.7] \"float scale\" 2\n"
      "LightSource \"infinite\" \"blackbody L\" 6500 \"float illuminance\" 3.14159265\n"
      "LightSource \"infinite\" \"string filename\" \"sky.pfm\"\n"
      "LightSource \"infinite\" \"string filename\" \"sky.pfm\" \"point3 portal\" "
      "[0 0 0 1 0 0 1 1 0 0 1 0]\n" +
          std::string(kTriangle),
      dir + "/scene.pbrt");
  EXPECT_TRUE(s.environment.file.empty());
  const vec3 second = blackbody_rgb(6500.0f);  // luminance 1 x (E / pi = 1)
  EXPECT_NEAR(
      glm::length(s.environment.color * s.environment.strength - (vec3(1.0f, 1.2f, 1.4f) + second)),
      0.0f, 1e-5f);
  EXPECT_EQ(count_warnings(s,
                           "scene.pbrt:4: LightSource \"infinite\": a second environment (the "
                           "scene has one, from line 2); skipped this one (and 1 more"),
            1)
      << all_warnings(s);
  // The default infinite light is pbrt's illuminant: white radiance 1.
  EXPECT_EQ(
      load("WorldBegin\nLightSource \"infinite\"\n" + std::string(kTriangle)).environment.color,
      vec3(1.0f));
  const Scene p = load_pbrt_string(
      "WorldBegin\nLightSource \"infinite\" \"string filename\" \"sky.pfm\" \"point3 portal\" "
      "[0 0 0 1 0 0 1 1 0 0 1 0]\n" +
          std::string(kTriangle),
      dir + "/scene.pbrt");
  EXPECT_EQ(count_warnings(p, "portals are not supported"), 1) << all_warnings(p);
  EXPECT_FALSE(p.environment.file.empty());
}

TEST(PbrtLights, ErrorsNameFileAndLine) {
  const std::string dir = temp_dir();
  write_file(dir + "/wide.pfm", "PF\n2 1\n-1\n" + std::string(24, '\0'));
  struct Case {
    std::string text, expected;
  };
  const Case cases[] = {
      {"WorldBegin\nLightSource \"infinite\" \"string filename\" \"sky.pfm\" \"rgb L\" [1 1 1]\n",
       "scene.pbrt:2: LightSource \"infinite\": \"L\" and \"filename\" cannot both be given"},
      {"WorldBegin\n\nLightSource \"infinite\" \"string filename\" \"missing.pfm\"\n",
       "scene.pbrt:3: LightSource \"infinite\": " + dir + "/missing.pfm: no such file"},
      {"WorldBegin\nLightSource \"infinite\" \"string filename\" \"wide.pfm\"\n",
       "scene.pbrt:2: LightSource \"infinite\": " + dir +
           "/wide.pfm: an octahedral map must be square, not 2x1"},
      {"WorldBegin\nLightSource \"spot\" \"float coneangle\" 0\n",
       "scene.pbrt:2: LightSource \"spot\": \"coneangle\" 0"},
      {"WorldBegin\nLightSource \"spot\" \"point3 from\" [1 1 1] \"point3 to\" [1 1 1]\n",
       "scene.pbrt:2: LightSource \"spot\": \"from\" and \"to\" are the same point"},
      {"WorldBegin\nLightSource \"distant\" \"point3 from\" [0 0 1]\n",
       "scene.pbrt:2: LightSource \"distant\": \"from\" and \"to\" are the same point"},
      {"WorldBegin\nScale 0 1 1\nLightSource \"point\"\n",
       "scene.pbrt:3: LightSource \"point\": the current transform is singular"},
      {"WorldBegin\nLightSource \"point\" \"rgb I\" [1 1]\n", "scene.pbrt:2:"},
      {"WorldBegin\nLightSource \"pointt\"\n",
       "scene.pbrt:2: unknown LightSource \"pointt\" (did you mean \"point\"?)"},
  };
  for (const Case& c : cases) {
    const std::string e = error_of(c.text, dir + "/scene.pbrt");
    EXPECT_TRUE(contains(e, c.expected)) << "input:\n" << c.text << "error:\n" << e;
    EXPECT_TRUE(contains(e, "; nothing was rendered")) << e;
  }
  // A falloff wider than the cone is clamped, with a warning (pbrt-v4 takes it as given).
  const Scene s = load(
      "WorldBegin\nLightSource \"spot\" \"float coneangle\" 10 "
      "\"float conedeltaangle\" 20\n" +
      std::string(kTriangle));
  ASSERT_EQ(s.point_lights.size(), 1u);
  EXPECT_FLOAT_EQ(s.point_lights[0].cone_delta_angle_deg, 10.0f);
  EXPECT_EQ(count_warnings(s, "\"conedeltaangle\" 20"), 1) << all_warnings(s);
}

// The classroom's sky as pbrt-v4 places it (its light transform takes the map's +z to the
// scene's up): the pixels that see the sky straight through the windows match Tungsten's
// reference there, left and right windows apart (they face different parts of the sky), far
// better than the map turned half a turn.
TEST(PbrtLights, ClassroomSkyThroughTheWindowsMatchesTheReference) {
  const std::string dir = test::source_dir() + "/../shared/scenes/bitterli/classroom";
  if (!std::filesystem::exists(dir + "/scene-v4.pbrt"))
    GTEST_SKIP() << "no shared scene at " << dir;
  const ImageRGB full = read_image(dir + "/TungstenRender.exr");  // 1280 x 720
  constexpr int kDown = 4;
  ImageRGB ref = make_image(full.width / kDown, full.height / kDown);
  for (int y = 0; y < ref.height; ++y)
    for (int x = 0; x < ref.width; ++x) {
      vec3 sum(0.0f);
      for (int j = 0; j < kDown; ++j)
        for (int i = 0; i < kDown; ++i) sum += full.at(kDown * x + i, kDown * y + j);
      ref.set(x, y, sum / float(kDown * kDown));
    }
  Scene s = load_scene(dir + "/scene-v4.pbrt");
  s.settings.width = ref.width;
  s.settings.height = ref.height;
  s.settings.filter = PixelFilter::kBox;
  struct Match {
    vec3 ratio[2];  // mean of ours over the reference's, left and right windows
    double correlation;
  };
  auto match = [&](float rotation) {
    s.environment.rotation_deg = rotation;
    const ImageRGB img = render(s, 8, 1);  // camera rays only: what they see of the sky
    glm::dvec3 ours[2] = {}, theirs[2] = {};
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    int n = 0;
    for (int y = 2; y < img.height - 2; ++y)
      for (int x = 2; x < img.width - 2; ++x) {
        // The whole 5 x 5 neighbourhood sky (no window frame, black at this depth, in the
        // pixel: it is lit in the reference).
        const float centre = img.at(x, y).y;
        bool sky = centre > 0.02f;
        for (int j = -2; j <= 2; ++j)
          for (int i = -2; i <= 2; ++i) sky &= img.at(x + i, y + j).y > 0.7f * centre;
        if (!sky) continue;
        const int side = x < img.width / 2 ? 0 : 1;
        ours[side] += glm::dvec3(img.at(x, y));
        theirs[side] += glm::dvec3(ref.at(x, y));
        const double a = img.at(x, y).y, b = ref.at(x, y).y;
        sx += a, sy += b, sxx += a * a, syy += b * b, sxy += a * b, ++n;
      }
    EXPECT_GT(n, 40);
    Match m;
    for (int side = 0; side < 2; ++side) m.ratio[side] = vec3(ours[side] / theirs[side]);
    const double cov = sxy / n - sx / n * sy / n;
    m.correlation = cov / std::sqrt((sxx / n - sx / n * sx / n) * (syy / n - sy / n * sy / n));
    return m;
  };
  const Match placed = match(0.0f), turned = match(180.0f);
  for (int side = 0; side < 2; ++side) {
    std::printf("%s windows: ours / Tungsten's %s (turned half a turn: %s)\n",
                side ? "right" : "left", vec3_str(placed.ratio[side], 3).c_str(),
                vec3_str(turned.ratio[side], 3).c_str());
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(placed.ratio[side][c], 1.0f, 0.1f) << side;
  }
  std::printf("correlation of the sky pixels: %.3f (turned: %.3f)\n", placed.correlation,
              turned.correlation);
  EXPECT_GT(placed.correlation, 0.95);
  EXPECT_GT(placed.correlation, turned.correlation);
  EXPECT_GT(std::abs(turned.ratio[0].y - 1.0f), std::abs(placed.ratio[0].y - 1.0f));
}
