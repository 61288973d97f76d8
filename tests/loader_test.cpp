// Scene loaders on good and broken input: every asset loads, every bad file fails with its file
// name, line and a useful hint, and no broken glTF from assimp's test set crashes or hangs.
#include "scene/loader.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <cstring>
#include <fstream>
#include <sstream>
#include <nlohmann/json.hpp>

#include "materials/metals.h"
#include "test_util.h"

namespace fs = std::filesystem;
using namespace tracer;

namespace {

std::string bad(const std::string& name) {
  return test::data_dir() + "/bad/" + name;
}

// Loads `path`, expects an InputError, returns its message.
std::string load_error(const std::string& path) {
  try {
    load_scene(path);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << path << " loaded without an error";
  return "";
}

bool has_warning(const Scene& s, const std::string& text) {
  for (const std::string& w : s.diagnostics.warnings)
    if (w.find(text) != std::string::npos) return true;
  return false;
}

size_t emissive_materials(const Scene& s) {
  size_t n = 0;
  for (const NamedMaterial& m : s.materials) n += m.material.is_emissive();
  return n;
}

}  // namespace

TEST(Loader, BuiltinCornellBox) {
  const Scene s = builtin_default_scene();
  EXPECT_EQ(s.source, "<built-in>");
  // Five walls and the light as quads (2 triangles each) plus two boxes (12 each).
  EXPECT_EQ(s.mesh.indices.size(), 6u * 2u + 2u * 12u);
  EXPECT_EQ(s.mesh.materials.size(), s.mesh.indices.size());
  EXPECT_TRUE(s.spheres.empty());
  EXPECT_EQ(s.objects.size(), 8u);
  EXPECT_EQ(emissive_materials(s), 1u);
  EXPECT_EQ(s.camera.position, vec3(278, 273, -800));
  EXPECT_EQ(s.camera.look_at, vec3(278, 273, 0));
  EXPECT_FLOAT_EQ(s.camera.vfov_deg, 39.3f);
  EXPECT_EQ(s.settings.width, 512);
  EXPECT_EQ(s.settings.spp, 64);
  EXPECT_TRUE(s.diagnostics.warnings.empty()) << s.diagnostics.warnings.front();

  // The light faces down: its triangles' geometric normal is -y.
  const uint32_t light = s.find_material("light");
  ASSERT_NE(light, kInvalid);
  EXPECT_EQ(s.materials[light].material.emission, vec3(17, 12, 4));
  for (size_t t = 0; t < s.mesh.indices.size(); ++t) {
    if (s.mesh.materials[t] != light) continue;
    const uvec3 i = s.mesh.indices[t];
    const vec3 n = glm::cross(s.mesh.positions[i.y] - s.mesh.positions[i.x],
                              s.mesh.positions[i.z] - s.mesh.positions[i.x]);
    EXPECT_LT(n.y, 0.0f);
  }
  // The red wall is at x = 555, which appears on the left of this camera.
  const uint32_t red = s.find_material("red");
  for (size_t t = 0; t < s.mesh.indices.size(); ++t)
    if (s.mesh.materials[t] == red) EXPECT_NEAR(s.mesh.positions[s.mesh.indices[t].x].x, 555, 1);
}

TEST(Loader, BoxesHaveOutwardNormals) {
  const Scene s = builtin_default_scene();
  for (const ObjectInfo& o : s.objects) {
    if (o.kind != "box") continue;
    vec3 centre(0.0f);
    for (uint32_t t = o.first; t < o.first + o.count; ++t)
      for (int k = 0; k < 3; ++k) centre += s.mesh.positions[s.mesh.indices[t][k]];
    centre /= float(3 * o.count);
    for (uint32_t t = o.first; t < o.first + o.count; ++t) {
      const uvec3 i = s.mesh.indices[t];
      const vec3 p0 = s.mesh.positions[i.x];
      const vec3 n = glm::cross(s.mesh.positions[i.y] - p0, s.mesh.positions[i.z] - p0);
      EXPECT_GT(glm::dot(n, p0 - centre), 0.0f) << o.name << " triangle " << t;
    }
  }
}

TEST(Loader, EveryAssetLoads) {
  int count = 0;
  for (const char* dir : {"/assets/scenes", "/assets/meshes"}) {
    for (const auto& entry : fs::directory_iterator(test::source_dir() + dir)) {
      const std::string ext = entry.path().extension().string();
      if (ext != ".json" && ext != ".obj" && ext != ".gltf" && ext != ".glb") continue;
      SCOPED_TRACE(entry.path().string());
      // Scenes lit by Debian's blender-data world maps (scripts/setup.sh installs the package).
      if (entry.path().filename().string().rfind("env_", 0) == 0 &&
          !fs::exists(test::kBlenderWorlds)) {
        std::printf("skipped %s: %s is absent (Debian package blender-data)\n",
                    entry.path().filename().c_str(), test::kBlenderWorlds);
        continue;
      }
      if (entry.path().filename() == "terrain_10m.json") {
        std::printf("skipped %s here: 10 million triangles (Loader.TerrainObject loads it at a "
                    "smaller resolution)\n", entry.path().filename().c_str());
        continue;
      }
      Scene s;
      ASSERT_NO_THROW(s = load_scene(entry.path().string()));
      EXPECT_GT(s.mesh.indices.size() + s.spheres.size() + s.instances.size(), 0u);
      if (entry.path().filename() == "instanced_100m.json") {
        // A million-triangle tile placed 100 times; the mirrored tiles meet their neighbours.
        EXPECT_EQ(s.instanced_meshes.size(), 1u);
        EXPECT_EQ(s.instances.size(), 100u);
        EXPECT_GE(s.instanced_triangle_count(), 100000000u);
      }
      const bool sky = !s.environment.file.empty() || !s.distant_lights.empty();
      EXPECT_TRUE(emissive_materials(s) >= 1u || sky);
      for (const std::string& w : s.diagnostics.warnings) {
        // The world maps' DWA compression leaves tiny negative texels: one warning says so.
        if (sky && w.find("negative texel values") != std::string::npos) continue;
        if (ext == ".json" || ext == ".gltf") ADD_FAILURE() << "unexpected warning: " << w;
      }
      ++count;
    }
  }
  EXPECT_GE(count, 7);
}

std::string read_file_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

TEST(Loader, TerrainObject) {
  // The benchmark asset, at 40x40 cells instead of 2237x2237.
  std::string text = read_file_text(test::source_dir() + "/assets/scenes/terrain_10m.json");
  const size_t at = text.find("\"resolution\": 2237");
  ASSERT_NE(at, std::string::npos) << "terrain_10m.json no longer has 2237 cells per side";
  text.replace(at, std::strlen("\"resolution\": 2237"), "\"resolution\": 40");
  const Scene s = load_scene_from_json(text, test::source_dir() + "/assets/scenes/t.json");
  ASSERT_EQ(s.mesh.indices.size(), 2u * 40 * 40);
  ASSERT_EQ(s.mesh.normals.size(), s.mesh.positions.size());
  float lo = 1e30f, hi = -1e30f;
  for (size_t i = 0; i < s.mesh.positions.size(); ++i) {
    const vec3 p = s.mesh.positions[i];
    EXPECT_TRUE(p.x >= 0.0f && p.x <= 100.0f && p.z >= 0.0f && p.z <= 100.0f);
    EXPECT_GT(s.mesh.normals[i].y, 0.0f) << "a heightfield's normals point up";
    lo = std::min(lo, p.y);
    hi = std::max(hi, p.y);
  }
  EXPECT_GT(hi - lo, 1.0f) << "the noise lifts the grid";
  EXPECT_LT(hi - lo, 2.0f * 14.0f);
  for (const uvec3& t : s.mesh.indices) {  // counter-clockwise from above: geometric normal up
    const vec3 a = s.mesh.positions[t.x], b = s.mesh.positions[t.y], c = s.mesh.positions[t.z];
    EXPECT_GT(glm::cross(b - a, c - a).y, 0.0f);
  }
  // The same seed gives the same land, another seed another.
  const Scene again = load_scene_from_json(text, test::source_dir() + "/assets/scenes/t.json");
  EXPECT_EQ(again.mesh.positions[777].y, s.mesh.positions[777].y);
  std::string other = text;
  other.replace(other.find("\"seed\": 7"), std::strlen("\"seed\": 7"), "\"seed\": 8");
  EXPECT_NE(load_scene_from_json(other, "t.json").mesh.positions[777].y, s.mesh.positions[777].y);

  for (const char* bad : {"\"resolution\": 0", "\"resolution\": 8193", "\"resolution\": 2.5"}) {
    std::string t = text;
    t.replace(t.find("\"resolution\": 40"), std::strlen("\"resolution\": 40"), bad);
    try {
      load_scene_from_json(t, "terrain.json");
      ADD_FAILURE() << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("terrain.json:12:"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("1..8192"), std::string::npos) << e.what();
    }
  }
}

TEST(Loader, GltfSceneHasCameraDielectricAndLight) {
  const Scene s = load_scene(test::source_dir() + "/assets/scenes/gltf_scene.gltf");
  EXPECT_NEAR(s.camera.vfov_deg, 40.0f, 1e-3f);
  EXPECT_NEAR(s.camera.position.z, 5.0f, 1e-4f);
  EXPECT_LT(s.camera.look_at.y, s.camera.position.y);  // pitched down
  const uint32_t glass = s.find_material("glass");
  ASSERT_NE(glass, kInvalid);
  EXPECT_EQ(s.materials[glass].material.type, MaterialType::kDielectric);
  EXPECT_FLOAT_EQ(s.materials[glass].material.ior, 1.5f);
  const uint32_t lamp = s.find_material("lamp");
  ASSERT_NE(lamp, kInvalid);
  EXPECT_NEAR(s.materials[lamp].material.emission.x, 10.0f, 1e-4f);  // x emissiveStrength
  EXPECT_EQ(s.mesh.normals.size(), s.mesh.positions.size());
}

TEST(Loader, ObjSceneUsesFileAndOverrideMaterials) {
  const Scene s = load_scene(test::source_dir() + "/assets/scenes/obj_scene.json");
  EXPECT_NE(s.find_material("blue"), kInvalid);  // from lit_sphere.mtl
  const uint32_t lamp = s.find_material("lamp");
  ASSERT_NE(lamp, kInvalid);
  EXPECT_TRUE(s.materials[lamp].material.is_emissive());  // Ke
  const uint32_t clay = s.find_material("clay");
  for (const ObjectInfo& o : s.objects) {
    if (o.name != "torus") continue;
    EXPECT_GT(o.count, 0u);
    for (uint32_t t = o.first; t < o.first + o.count; ++t) EXPECT_EQ(s.mesh.materials[t], clay);
    EXPECT_EQ(o.loc.line, 16);  // the torus line in obj_scene.json
  }
  EXPECT_EQ(s.mesh.normals.size(), s.mesh.positions.size());
}

TEST(Loader, ObjectsAndTransforms) {
  const Scene s = load_scene_from_json(R"({
    "materials": {"m": {"emission": [1, 1, 1]}},
    "objects": [
      {"type": "sphere", "name": "a", "center": [1, 0, 0], "radius": 2, "material": "m",
       "transform": {"scale": 3, "rotate": [0, 90, 0], "translate": [0, 10, 0]}},
      {"type": "quad", "corner": [0, 0, 0], "edge1": [1, 0, 0], "edge2": [0, 0, 1],
       "material": "m", "transform": {"matrix": [1, 0, 0, 5,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]}}
    ]})",
                                       "inline.json");
  ASSERT_EQ(s.spheres.size(), 1u);
  // Scale 3, then rotate +90 about y: (3, 0, 0) -> (0, 0, -3), then translate.
  EXPECT_NEAR(s.spheres[0].center.x, 0.0f, 1e-5f);
  EXPECT_NEAR(s.spheres[0].center.y, 10.0f, 1e-5f);
  EXPECT_NEAR(s.spheres[0].center.z, -3.0f, 1e-5f);
  EXPECT_FLOAT_EQ(s.spheres[0].radius, 6.0f);
  EXPECT_EQ(s.objects[0].name, "a");
  EXPECT_EQ(s.objects[0].loc.line, 4);
  EXPECT_EQ(s.objects[1].name, "quad 1");
  EXPECT_EQ(s.objects[1].loc.line, 6);
  // Row-major matrix: translation in the last column.
  EXPECT_FLOAT_EQ(s.mesh.positions[s.mesh.indices[0].x].x, 5.0f);
  // Quad front faces cross(edge1, edge2) = (0, -1, 0).
  const uvec3 i = s.mesh.indices[0];
  const vec3 n = glm::cross(s.mesh.positions[i.y] - s.mesh.positions[i.x],
                            s.mesh.positions[i.z] - s.mesh.positions[i.x]);
  EXPECT_LT(n.y, 0.0f);
}

TEST(Loader, DidYouMean) {
  EXPECT_EQ(did_you_mean("albdo", {"albedo", "emission"}), "albedo");
  EXPECT_EQ(did_you_mean("Emision", {"albedo", "emission"}), "emission");
  EXPECT_EQ(did_you_mean("xyz", {"albedo", "emission"}), "");
}

struct BadCase {
  const char* file;
  int line;  // 0: the message names no line
  std::vector<const char*> words;
};

TEST(Loader, BadFilesFailWithFileLineAndHint) {
  const std::vector<BadCase> cases = {
      {"unknown_key.json", 4, {"unknown key \"albdo\"", "did you mean \"albedo\""}},
      {"unknown_top_key.json", 6, {"\"rendr\"", "did you mean \"render\""}},
      {"wrong_type.json", 5, {"\"radius\"", "must be a number", "string"}},
      {"short_vector.json", 4, {"\"camera.look_at\"", "three numbers", "[0,1]"}},
      {"unknown_material.json", 9, {"unknown material \"whte\"", "did you mean \"white\""}},
      {"bad_object_type.json", 5, {"unknown object type \"spere\"", "did you mean \"sphere\""}},
      {"negative_radius.json", 5, {"\"radius\"", "> 0"}},
      {"infinite_number.json", 5, {"1e999"}},
      {"trailing_comma.json", 5, {"syntax error"}},
      {"truncated.json", 4, {"syntax error", "end of input"}},
      {"missing_mesh.json", 6, {"does_not_exist.obj", "not found"}},
      {"absurd_width.json", 3, {"\"render.width\"", "1000000", "1..16384"}},
      {"bad_ior.json", 4, {"\"ior\""}},
      {"bad_vfov.json", 3, {"\"camera.vfov\"", "[1, 179]"}},
      {"unknown_sampler.json", 3, {"\"render.sampler\"", "\"sobel\"", "did you mean \"sobol\""}},
      {"duplicate_key.json", 4, {"duplicate key \"white\"", "line 3"}},
      {"no_objects.json", 3, {"no objects"}},
      {"sphere_nonuniform.json", 5, {"non-uniformly"}},
      {"bad_index.obj", 7, {"vertex 9", "4 vertices"}},
      {"bad_relative_index.obj", 5, {"vertex -4", "before this line"}},
      {"nan_vertex.obj", 4, {"non-finite", "nan"}},
      {"bad_index.gltf", 0, {"index 7", "out of range"}},
      {"view_past_buffer.gltf", 0, {"past the end"}},
      {"does_not_exist.json", 0, {"cannot open", "No such file"}},
  };
  for (const BadCase& c : cases) {
    SCOPED_TRACE(c.file);
    const std::string msg = load_error(bad(c.file));
    const std::string prefix =
        bad(c.file) + (c.line > 0 ? ":" + std::to_string(c.line) + ": " : std::string(": "));
    EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;
    for (const char* w : c.words) EXPECT_NE(msg.find(w), std::string::npos) << msg;
    EXPECT_NE(msg.find("; nothing was rendered"), std::string::npos) << msg;
  }
}

TEST(Loader, MeshErrorsNameTheReferencingScene) {
  const std::string dir = test::data_dir() + "/bad/";
  try {
    load_scene_from_json(R"({"materials": {"m": {}},
      "objects": [{"type": "mesh", "file": "nan_vertex.obj", "material": "m"}]})",
                         dir + "inline.json");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("nan_vertex.obj:4:"), std::string::npos) << msg;
    EXPECT_NE(msg.find("inline.json:2"), std::string::npos) << msg;
  }
}

TEST(Loader, RepairsWithWarnings) {
  const Scene clamped = load_scene(bad("albedo_clamped.json"));
  EXPECT_TRUE(has_warning(clamped, "albedo_clamped.json:4: \"albedo\""))
      << clamped.diagnostics.warnings[0];
  EXPECT_EQ(clamped.materials[clamped.find_material("bright")].material.albedo.x, 1.0f);

  const Scene zero = load_scene(bad("zero_area.obj"));
  EXPECT_TRUE(has_warning(zero, "2 zero-area triangle(s)"));
  // The default light is a choice made for the user (a note), not a problem (a warning).
  bool noted = false;
  for (const std::string& n : zero.diagnostics.notes)
    noted |= n.find("no light in the file") != std::string::npos;
  EXPECT_TRUE(noted);
  // One good triangle plus the two of the default light.
  EXPECT_EQ(zero.mesh.indices.size(), 3u);
  EXPECT_EQ(zero.objects[0].count, 1u);
  EXPECT_EQ(zero.objects[1].first, 1u);

  const Scene mtl = load_scene(bad("missing_mtl.obj"));
  EXPECT_TRUE(has_warning(mtl, "missing_mtl.obj:1: material library \"nowhere.mtl\" not found"));
}

TEST(Loader, ValidateScene) {
  Scene s = builtin_default_scene();
  s.settings.width = s.settings.height = 16384;
  s.mesh.positions[0].x = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(validate_scene(s), InputError);

  Scene dark = builtin_default_scene();
  for (NamedMaterial& m : dark.materials) m.material.emission = vec3(0.0f);
  validate_scene(dark);
  EXPECT_TRUE(has_warning(dark, "scene has no light; it will render black"));

  Scene bad_index = builtin_default_scene();
  bad_index.mesh.indices[3].y = 100000;
  EXPECT_THROW(validate_scene(bad_index), InputError);

  Scene bad_material = builtin_default_scene();
  bad_material.mesh.materials[0] = 99;
  EXPECT_THROW(validate_scene(bad_material), InputError);
}

TEST(Loader, ImageTooLargeForMemory) {
  Scene s = builtin_default_scene();
  s.settings.width = s.settings.height = 16384;  // 16 GiB at 64 bytes a pixel
  const double memory = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGESIZE));
  if (memory >= 32.0 * double(1ull << 30)) GTEST_SKIP() << "this machine has 32 GiB or more";
  try {
    validate_scene(s);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("image of 16384x16384 needs 16 GiB"), std::string::npos)
        << e.what();
  }
}

TEST(Loader, ZeroLengthNormalsAreDropped) {
  const std::string path = testing::TempDir() + "zero_normals.obj";
  std::ofstream(path) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n";
  const Scene s = load_scene(path);
  EXPECT_TRUE(has_warning(s, "zero-length vertex normals"));
  for (const uvec3& t : s.mesh.indices)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(glm::length(s.mesh.normals[t[k]]), 1.0f, 1e-5f);
}

// Every file of assimp's glTF 2 test set, most of them broken on purpose, must load or throw
// InputError: never crash, hang or read out of bounds.
TEST(Loader, AssimpGltfSweep) {
  const fs::path root = "/usr/share/assimp/models/glTF2";
  if (!fs::is_directory(root))
    GTEST_SKIP() << root << " is missing (apt install assimp-testmodels)";
  int loaded = 0, rejected = 0;
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    const std::string ext = entry.path().extension().string();
    if (ext != ".gltf" && ext != ".glb") continue;
    SCOPED_TRACE(entry.path().string());
    try {
      const Scene s = load_scene(entry.path().string());
      EXPECT_GT(s.mesh.indices.size() + s.instanced_triangle_count(), 0u);
      ++loaded;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(entry.path().filename().string()), std::string::npos);
      ++rejected;
    }
  }
  EXPECT_GT(loaded, 0);
  EXPECT_GT(rejected, 0);
  // The files that exist to be broken in a specific way.
  EXPECT_NE(load_error((root / "RecursiveNodes/RecursiveNodes.gltf").string()).find("cycle"),
            std::string::npos);
  EXPECT_NE(
      load_error((root / "IndexOutOfRange/IndexOutOfRange.gltf").string()).find("out of range"),
      std::string::npos);
  EXPECT_NE(load_error((root / "BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb").string())
                .find("non-finite"),
            std::string::npos);
}

TEST(Loader, RealMeshes) {
  int found = 0;
  for (const char* path : {"/usr/share/doc/python3-tinyobjloader/examples/cornell_box.obj",
                           "/usr/share/glmark2/models/bunny.obj"}) {
    if (!fs::exists(path)) continue;
    SCOPED_TRACE(path);
    ++found;
    const Scene s = load_scene(path);
    EXPECT_GT(s.mesh.indices.size(), 0u);
    EXPECT_GE(emissive_materials(s), 1u);
  }
  if (found == 0) GTEST_SKIP() << "neither python3-tinyobjloader nor glmark2-data is installed";
}

// glTF volumes become subsurface media: KHR_materials_volume (with transmission) and
// KHR_materials_diffuse_transmission; rough metals become GGX conductors.
TEST(LoaderGltfMaterials, VolumesBecomeSubsurfaceAndMetalsConductors) {
  std::ifstream in(test::source_dir() + "/assets/scenes/gltf_scene.gltf");
  ASSERT_TRUE(in.good());
  nlohmann::json j = nlohmann::json::parse(in);
  auto& mats = j["materials"];
  for (auto& m : mats) {
    if (m["name"] == "glass") {
      m["extensions"]["KHR_materials_volume"] = {{"thicknessFactor", 1.0},
                                                 {"attenuationDistance", 0.5},
                                                 {"attenuationColor", {0.9, 0.5, 0.3}}};
    }
    if (m["name"] == "terracotta") {
      m["pbrMetallicRoughness"]["metallicFactor"] = 1.0;
      m["pbrMetallicRoughness"]["roughnessFactor"] = 0.35;
    }
    if (m["name"] == "floor") {
      m["extensions"]["KHR_materials_diffuse_transmission"] = {{"diffuseTransmissionFactor", 1.0}};
    }
  }
  j["extensionsUsed"].push_back("KHR_materials_volume");
  j["extensionsUsed"].push_back("KHR_materials_diffuse_transmission");
  char tmpl[] = "/tmp/pathtracer_gltfmat_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  const std::string path = dir + "/volume.gltf";
  std::ofstream(path) << j.dump();
  const tracer::Scene s = tracer::load_scene(path);
  int subsurface = 0, conductor = 0;
  for (const auto& nm : s.materials) {
    const tracer::Material& m = nm.material;
    if (m.type == tracer::MaterialType::kSubsurface) {
      ++subsurface;
      EXPECT_EQ(m.albedo, tracer::vec3(1.0f)) << nm.name;  // the boundary is untinted
      if (nm.name.find("glass") != std::string::npos) {
        // mean free path 0.5: sigma_t = 2 in every channel; the surface colour sets the split.
        EXPECT_NEAR(m.scattering.x + m.absorption.x, 2.0f, 1e-4f);
        EXPECT_GT(m.scattering.x / 2.0f, m.scattering.z / 2.0f);  // redder light survives
        EXPECT_NEAR(m.ior, 1.5f, 1e-6f);
      }
    }
    if (m.type == tracer::MaterialType::kConductor) {
      ++conductor;
      EXPECT_NEAR(m.roughness, 0.35f, 1e-6f);
    }
  }
  EXPECT_EQ(subsurface, 2);
  EXPECT_EQ(conductor, 1);
}

// ---- Issue 20: magnitudes, degenerate-only meshes, truncated OBJ files ----

namespace {

// Writes `text` to a fresh file `name` in a temporary folder; returns its path.
std::string temp_file(const std::string& name, const std::string& text) {
  char tmpl[] = "/tmp/pathtracer_loader_XXXXXX";
  const std::string path = std::string(mkdtemp(tmpl)) + "/" + name;
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

}  // namespace

// A sphere of radius 2e38 is a finite float, but past what the intersection code can take: the
// error names the object's line and the bound (it crashed `render` and made `info` print a NaN
// SAH cost).
TEST(LoaderMagnitudes, HugeSphereIsRejectedWithItsLineAndTheBound) {
  const std::string msg = load_error(bad("huge_sphere.json"));
  EXPECT_EQ(msg.rfind(bad("huge_sphere.json") + ":9: ", 0), 0u) << msg;
  for (const char* w : {"\"big\"", "reaches 2e+38", "supported 1e+12", "nothing was rendered"})
    EXPECT_NE(msg.find(w), std::string::npos) << w << " in " << msg;
}

// A whole scene smaller than the ray offset is rejected, not rendered black; a mesh far past
// the bound as well, blamed on the mesh rather than on the camera framed around it.
TEST(LoaderMagnitudes, TinySceneAndHugeMeshAreRejected) {
  try {
    load_scene_from_json(R"({"camera": {"position": [0, 0, -1e-20], "look_at": [0, 0, 0]},
      "materials": {"m": {"emission": [1, 1, 1]}},
      "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1e-21, "material": "m"}]})",
                         "tiny.json");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("tiny.json: the scene (geometry and camera) spans 1.1e-20"),
              std::string::npos)
        << msg;
    EXPECT_NE(msg.find("64 ray offsets"), std::string::npos) << msg;
  }
  const std::string path = temp_file("huge.obj", "v -1e13 0 0\nv 1e13 0 0\nv 0 1e13 0\nf 1 2 3\n");
  const std::string msg = load_error(path);
  EXPECT_EQ(msg.rfind(path + ": object \"huge.obj\" reaches 1e+13", 0), 0u) << msg;
}

namespace {

std::vector<std::string> warnings_with(const Scene& s, const std::string& text) {
  std::vector<std::string> out;
  for (const std::string& w : s.diagnostics.warnings)
    if (w.find(text) != std::string::npos) out.push_back(w);
  return out;
}

}  // namespace

// An OBJ whose every triangle is degenerate is an error, as an empty one is; it rendered its
// default light alone with exit 0.
TEST(LoaderDegenerate, ObjOfOnlyDegenerateTrianglesIsAnError) {
  const std::string path = temp_file("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n");
  const std::string msg = load_error(path);
  EXPECT_EQ(msg.rfind(path + ": all 2 triangles of the file have zero area", 0), 0u) << msg;
  const std::string empty = temp_file("empty.obj", "");
  EXPECT_NE(load_error(empty).find("contains no triangles"), std::string::npos);
}

// Likewise a JSON scene whose objects all lose every triangle; one object losing all of them
// among others is a warning that names it.
TEST(LoaderDegenerate, JsonSceneOfOnlyDegenerateTrianglesIsAnError) {
  const std::string obj = temp_file("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n");
  const std::string json = obj.substr(0, obj.rfind('/')) + "/scene.json";
  try {
    load_scene_from_json(R"({"materials": {"m": {"emission": [1, 1, 1]}}, "objects": [
      {"type": "mesh", "name": "a", "file": "flat.obj", "material": "m"},
      {"type": "mesh", "name": "b", "file": "flat.obj", "material": "m"}]})",
                         json);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(json + ": all 4 triangles of the scene have zero area", 0), 0u) << msg;
    EXPECT_NE(msg.find("objects \"a\", \"b\""), std::string::npos) << msg;
  }
  const Scene s = load_scene_from_json(R"({"materials": {"m": {"emission": [1, 1, 1]}},
    "objects": [{"type": "mesh", "name": "a", "file": "flat.obj", "material": "m"},
      {"type": "sphere", "name": "ball", "center": [0, 0, 0], "radius": 1, "material": "m"}]})",
                                       json);
  EXPECT_EQ(warnings_with(s, "all 2 triangles of object \"a\" have zero area").size(), 1u);
}

namespace {

// An OBJ grid of n x n quads as 2 n^2 triangles: (n + 1)^2 vertex lines, then the faces.
std::string obj_grid(int n) {
  std::string s;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) s += "v " + std::to_string(x) + " " + std::to_string(y) + " 0\n";
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const int a = 1 + y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
      s += "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(d) + "\n";
      s += "f " + std::to_string(a) + " " + std::to_string(d) + " " + std::to_string(c) + "\n";
    }
  }
  return s;
}

}  // namespace

// A truncated OBJ reads up to the cut line: one warning with the file, that line, what is cut
// and how many faces were read, and none of tinyobjloader's raw "." warnings.
TEST(LoaderObjTruncated, CutFaceSaysWhereReadingStopped) {
  const std::string grid = obj_grid(10);  // 121 vertex lines, 200 faces
  const std::string path =
      temp_file("cut.obj", grid.substr(0, grid.find("f ")) + "f 1 2 13\nf 1 13 12\nf 2 ");
  const Scene s = load_scene(path);
  const auto w = warnings_with(s, "truncated");
  ASSERT_EQ(w.size(), 1u) << (s.diagnostics.warnings.empty() ? "" : s.diagnostics.warnings[0]);
  EXPECT_EQ(w[0].rfind(path + ":124: the file appears truncated", 0), 0u) << w[0];
  for (const char* word : {"\"f 2 \"", "a face with 1 corner", "after 2 faces and 121 vertices",
                           "used the 2 triangles read"})
    EXPECT_NE(w[0].find(word), std::string::npos) << word << " in " << w[0];
  EXPECT_TRUE(warnings_with(s, "tinyobjloader").empty());
  EXPECT_EQ(s.objects[0].count, 2u);

  // A corner cut after its slash: tinyobjloader failed on it ("zero value for face index").
  const std::string slash =
      temp_file("slash.obj", grid.substr(0, grid.find("f ")) + "f 1 2 13\nf 1/");
  EXPECT_EQ(warnings_with(load_scene(slash), "truncated").size(), 1u);
  // A keyword cut short.
  const std::string keyword = temp_file("keyword.obj", grid + "usem");
  const Scene k = load_scene(keyword);
  ASSERT_EQ(warnings_with(k, "truncated").size(), 1u);
  EXPECT_NE(warnings_with(k, "truncated")[0].find("after 200 faces"), std::string::npos);
  // A face that refers to vertices cut away with the end of the file: reading stops there.
  const std::string ahead = temp_file(
      "ahead.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7000\nf 1 3 2\nv 1 1 1\nv 2");
  const Scene a = load_scene(ahead);
  ASSERT_EQ(warnings_with(a, "truncated").size(), 1u);
  EXPECT_EQ(warnings_with(a, "truncated")[0].rfind(
                ahead + ":5: the file appears truncated: it ends inside line 8 with no newline; "
                        "reading stopped at line 5, \"f 1 2 7000\" (a face that refers to vertex "
                        "7000, but the file defines 4 vertices), after 1 face and 3 vertices",
                0),
            0u)
      << warnings_with(a, "truncated")[0];
  EXPECT_EQ(a.objects[0].count, 1u);
  // A complete last line without a newline is common and fine.
  const std::string whole = temp_file("whole.obj", grid.substr(0, grid.size() - 1));
  EXPECT_TRUE(warnings_with(load_scene(whole), "truncated").empty());
}

// Cut among the vertices: no face was read, so the file is an error that says it is truncated.
TEST(LoaderObjTruncated, CutVertexBeforeAnyFaceIsAnError) {
  const std::string path = temp_file("cut.obj", "v 0 0 0\nv 1 0 0\nv 0.5");
  const std::string msg = load_error(path);
  EXPECT_EQ(msg.rfind(path + ": the file contains no triangles", 0), 0u) << msg;
  EXPECT_NE(msg.find("cut.obj:3: the file appears truncated"), std::string::npos) << msg;
  EXPECT_NE(msg.find("a vertex with 1 of its 3 coordinates"), std::string::npos) << msg;
  // The same vertex line cut short but followed by more lines is a plain error at its line.
  const std::string mid = temp_file("mid.obj", "v 0 0 0\nv 1 0 0\nv 0.5\nv 0 1 0\nf 1 2 4\n");
  EXPECT_EQ(load_error(mid).rfind(mid + ":3: \"v\" needs 3 numbers", 0), 0u);
}

// The bunny of glmark2-data cut inside face line 42,557, as the issue found it (7,721 of its
// 69,666 faces read, with the warning "tinyobjloader: .; continued").
TEST(LoaderObjTruncated, TruncatedBunny) {
  const std::string bunny = "/usr/share/glmark2/models/bunny.obj";
  std::ifstream in(bunny, std::ios::binary);
  if (!in) GTEST_SKIP() << bunny << " is missing (apt install glmark2-data)";
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string path = temp_file("trunc.obj", text.substr(0, 1198593));
  const Scene s = load_scene(path);
  const auto w = warnings_with(s, "truncated");
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].rfind(path + ":42557: ", 0), 0u) << w[0];
  EXPECT_NE(w[0].find("after 7,721 faces and 34,835 vertices"), std::string::npos) << w[0];
  EXPECT_TRUE(warnings_with(s, "tinyobjloader").empty());
}

// tinyobjloader's own warnings become path:line messages (of the OBJ or of its MTL file).
TEST(LoaderObjTruncated, TinyobjWarningsCarryFileAndLine) {
  const std::string obj = temp_file("m.obj",
                                    "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                    "usemtl nope\ng \nf 1 2 3\n");
  const std::string dir = obj.substr(0, obj.rfind('/'));
  std::ofstream(dir + "/m.mtl") << "newmtl a\nKd 1 0 0\nd 0.5\nTr 0.5\n";
  const Scene s = load_scene(obj);
  EXPECT_EQ(warnings_with(s, obj + ":5: material \"nope\" is not defined").size(), 1u);
  EXPECT_EQ(warnings_with(s, obj + ":6: tinyobjloader: Empty group name").size(), 1u);
  EXPECT_EQ(warnings_with(s, dir + "/m.mtl:4: tinyobjloader: Both `d` and `Tr`").size(), 1u);
  for (const std::string& w : s.diagnostics.warnings)
    EXPECT_EQ(w.find("(line"), std::string::npos) << w;
}

// ---------------------------------------------------------------------------------------------
// The materials of issue 21 in the scene format: complex-IOR conductors (named metals or eta
// and k), anisotropic roughness, the coated diffuse ("plastic") and the diffuse transmitter.

namespace {

Scene load_materials(const std::string& materials, const std::string& name = "inline.json") {
  return load_scene_from_json(
      "{\"materials\": {\n" + materials +
          "\n},\n\"objects\": [{\"type\": \"sphere\", \"radius\": 1, \"material\": \"m\"}]}",
      test::data_dir() + "/" + name);
}

std::string materials_error(const std::string& materials) {
  try {
    load_materials(materials);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << materials << " loaded without an error";
  return "";
}

const Material& material(const Scene& s, const char* name = "m") {
  return s.materials[s.find_material(name)].material;
}

}  // namespace

TEST(LoaderMaterials, NamedMetalsAndComplexIndices) {
  const Scene s = load_materials(
      R"("m": {"type": "conductor", "metal": "Au", "roughness": 0.2},
         "ek": {"type": "conductor", "eta": [0.2, 0.9, 1.1], "k": 3.9, "albedo": [1, 0.9, 0.8]},
         "schlick": {"type": "conductor", "albedo": [0.9, 0.6, 0.3]},
         "brushed": {"type": "conductor", "metal": "Ti", "roughness": [0.1, 0.5]})");
  const Material& au = material(s);
  EXPECT_EQ(au.type, MaterialType::kConductor);
  EXPECT_TRUE(au.flags & kMaterialConductorIor);
  EXPECT_EQ(au.eta, find_metal("Au")->eta);
  EXPECT_EQ(au.k, find_metal("Au")->k);
  EXPECT_EQ(au.albedo, vec3(1.0f));  // a tint, white unless given
  EXPECT_EQ(au.roughness, 0.2f);
  EXPECT_FALSE(au.is_anisotropic());
  const Material& ek = material(s, "ek");
  EXPECT_EQ(ek.eta, vec3(0.2f, 0.9f, 1.1f));
  EXPECT_EQ(ek.k, vec3(3.9f));
  EXPECT_EQ(ek.albedo, vec3(1.0f, 0.9f, 0.8f));
  EXPECT_FALSE(material(s, "schlick").flags & kMaterialConductorIor);  // as before: F0 = albedo
  const Material& ti = material(s, "brushed");
  EXPECT_TRUE(ti.is_anisotropic());
  EXPECT_EQ(ti.roughness, 0.1f);
  EXPECT_EQ(ti.roughness_v, 0.5f);
  for (const char* name : {"Ag", "Al", "Au", "Cu", "Cr", "Ni", "Ti"})
    EXPECT_NE(find_metal(name), nullptr) << name;
}

TEST(LoaderMaterials, MistakesNameTheLineAndGuess) {
  const std::string dir = test::data_dir() + "/inline.json:";
  struct Case {
    std::string materials;
    std::vector<std::string> words;
  };
  const std::vector<Case> cases = {
      {"\"m\": {\"type\": \"conductor\",\n \"metal\": \"Cuu\"}",
       {dir + "3:", "unknown metal \"Cuu\"", "did you mean \"Cu\""}},
      {"\"m\": {\"type\": \"conductor\",\n \"metal\": \"unobtainium\"}",
       {dir + "3:", "known: Ag, Al, Au, Cr, Cu, Ni, Ti"}},
      {"\"m\": {\"type\": \"conductor\",\n \"eta\": [1, 1, 1]}", {dir + "3:", "without \"k\""}},
      {"\"m\": {\"type\": \"conductor\", \"metal\": \"Au\",\n \"k\": 3}", {"not both"}},
      {"\"m\": {\"type\": \"conductor\",\n \"eta\": [0, 1, 1], \"k\": 1}", {dir + "3:", "> 0"}},
      {"\"m\": {\"type\": \"dielectric\",\n \"roughness\": [0.1, 0.2]}",
       {dir + "3:", "anisotropic roughness is for conductors"}},
      {"\"m\": {\"type\": \"conductor\",\n \"roughness\": [0.1, 1.2]}", {dir + "3:", "[0, 1]"}},
      {"\"m\": {\"type\": \"plastik\"}", {"did you mean \"plastic\""}},
      {"\"m\": {\"type\": \"coated_diffuse\",\n \"thickness\": -1}", {dir + "3:", ">= 0"}},
      {"\"m\": {\"type\": \"diffuse_transmission\",\n \"transmittance\": [0.1, -0.1, 0]}",
       {dir + "3:", ">= 0"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.materials);
    const std::string msg = materials_error(c.materials);
    for (const std::string& w : c.words) EXPECT_NE(msg.find(w), std::string::npos) << msg;
  }
}

TEST(LoaderMaterials, CoatedDiffuseAndDiffuseTransmission) {
  const Scene s = load_materials(
      R"("m": {"type": "plastic", "albedo": [0.8, 0.1, 0.1], "ior": 1.6, "roughness": 0.3,
               "absorption": [0.1, 0.2, 0.3], "thickness": 0.05, "fresnel": "schlick"},
         "coat": {"type": "coated_diffuse"},
         "sheet": {"type": "diffuse_transmission", "albedo": [0.2, 0.2, 0.2],
                   "transmittance": [0.7, 0.5, 0.3]},
         "bright": {"type": "diffuse_transmission", "albedo": [0.6, 0.6, 0.6],
                    "transmittance": [0.8, 0.4, 0.2]},
         "plain": {"type": "diffuse", "thickness": 2, "transmittance": [1, 1, 1]})");
  const Material& p = material(s);
  EXPECT_EQ(p.type, MaterialType::kCoatedDiffuse);
  EXPECT_EQ(p.ior, 1.6f);
  EXPECT_EQ(p.roughness, 0.3f);
  EXPECT_EQ(p.absorption, vec3(0.1f, 0.2f, 0.3f));
  EXPECT_EQ(p.thickness, 0.05f);
  EXPECT_TRUE(p.flags & kMaterialSchlickFresnel);
  const Material& c = material(s, "coat");  // defaults: ior 1.5, smooth, clear, albedo 0.8
  EXPECT_EQ(c.ior, 1.5f);
  EXPECT_EQ(c.roughness, 0.0f);
  EXPECT_EQ(c.albedo, vec3(0.8f));
  EXPECT_EQ(material(s, "sheet").transmittance, vec3(0.7f, 0.5f, 0.3f));
  // More out than in: both scaled so that no channel exceeds 1, with a warning.
  const Material& b = material(s, "bright");
  EXPECT_NEAR(max_component(b.albedo + b.transmittance), 1.0f, 1e-6f);
  EXPECT_NEAR(b.transmittance.x / b.albedo.x, 0.8f / 0.6f, 1e-5f);
  EXPECT_TRUE(has_warning(s, "\"albedo\" + \"transmittance\""));
  EXPECT_TRUE(has_warning(s, "\"thickness\" has no effect on a diffuse material"));
  EXPECT_TRUE(has_warning(s, "\"transmittance\" has no effect on a diffuse material"));
}

TEST(LoaderMaterials, MeshOverridesTurnFileMaterialsIntoNewTypes) {
  // A mesh object's "materials" edits the file's materials (the `base` of parse_material): a
  // diffuse becomes gold with a white tint (not the file's diffuse colour), a Schlick metal keeps
  // its roughness when given a metal, and a file's colour stays the plastic's base colour.
  const Scene s = load_scene_from_json(
      R"({"materials": {},
          "objects": [{"type": "mesh", "file": "../meshes/lit_sphere.obj",
            "materials": {"blue": {"type": "conductor", "metal": "Au", "roughness": [0.2, 0.4]},
                          "marble": {"type": "plastic", "roughness": 0.1},
                          "lamp": {"type": "diffuse_transmission"}}}]})",
      test::source_dir() + "/assets/scenes/inline.json");
  const Material& blue = material(s, "blue");
  EXPECT_EQ(blue.type, MaterialType::kConductor);
  EXPECT_TRUE(blue.flags & kMaterialConductorIor);
  EXPECT_EQ(blue.albedo, vec3(1.0f));
  EXPECT_TRUE(blue.is_anisotropic());
  const Material& marble = material(s, "marble");
  EXPECT_EQ(marble.type, MaterialType::kCoatedDiffuse);
  EXPECT_EQ(marble.roughness, 0.1f);
  EXPECT_EQ(marble.albedo, vec3(0.8f, 0.8f, 0.78f));
  const Material& lamp = material(s, "lamp");  // keeps its emission; a black sheet by default
  EXPECT_EQ(lamp.type, MaterialType::kDiffuseTransmission);
  EXPECT_TRUE(lamp.is_emissive());
  EXPECT_EQ(lamp.transmittance, vec3(0.5f));
}
