// Instanced meshes from the loaders: JSON "instances" (transforms and grids), pbrt-v4's
// ObjectInstance; flattening them gives the triangles the copies written out would; emissive
// meshes are flattened with a note; bad input and bad instance data are errors naming file:line.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>

#include "scene/loader.h"
#include "scene/pbrt_loader.h"
#include "test_util.h"

namespace {
using namespace tracer;

std::string temp_dir() {
  std::string tmpl = testing::TempDir() + "instances_test_XXXXXX";
  return std::string(mkdtemp(tmpl.data()));
}

std::string write_file(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// A JSON scene lit by the sky, with a material "rock", a light-emitting "lamp" and `objects`.
std::string json_scene(const std::string& objects) {
  return R"({
  "environment": {"color": [0.2, 0.3, 0.4]},
  "materials": {"rock": {"albedo": [0.5, 0.4, 0.3]}, "lamp": {"emission": [4, 4, 4]}},
  "objects": [
)" + objects +
         R"(
  ]
})";
}

Scene load_json(const std::string& text, const std::string& path = "/nonexistent/scene.json") {
  return load_scene_from_json(text, path);
}

std::string json_error(const std::string& text) {
  try {
    load_json(text);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

void expect_near(const mat4& a, const mat4& b, float tol = 1e-5f) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      EXPECT_NEAR(a[c][r], b[c][r], tol) << "column " << c << " row " << r;
}

// Every triangle's corners (in winding order), its material's albedo and, where both have them,
// its vertex normals.
void expect_same_triangles(const Scene& sa, const Scene& sb, float tol) {
  const TriangleMesh &a = sa.mesh, &b = sb.mesh;
  ASSERT_EQ(a.indices.size(), b.indices.size());
  const bool normals = !a.normals.empty() && !b.normals.empty();
  for (size_t t = 0; t < a.indices.size(); ++t) {
    EXPECT_EQ(sa.materials[a.materials[t]].material.albedo,
              sb.materials[b.materials[t]].material.albedo)
        << "triangle " << t;
    for (int k = 0; k < 3; ++k) {
      const vec3 pa = a.positions[a.indices[t][k]], pb = b.positions[b.indices[t][k]];
      ASSERT_LE(glm::length(pa - pb), tol * std::max(1.0f, glm::length(pa)))
          << "triangle " << t << " corner " << k << ": " << vec3_str(pa) << " vs " << vec3_str(pb);
      if (!normals) continue;
      const vec3 na = a.normals[a.indices[t][k]], nb = b.normals[b.indices[t][k]];
      ASSERT_LE(glm::length(na - nb), 1e-4f) << "triangle " << t << " corner " << k;
    }
  }
}

// ---- JSON ----

TEST(JsonInstances, TransformsPlaceOneMesh) {
  const Scene s = load_json(json_scene(R"(
    {"type": "terrain", "name": "land", "size": [4, 0, 4], "resolution": 4, "material": "rock",
     "transform": {"translate": [0, 1, 0]},
     "instances": [{"translate": [10, 0, 0]}, {"rotate": [0, 90, 0]}, {"scale": 2}]})"));
  EXPECT_TRUE(s.mesh.indices.empty());
  ASSERT_EQ(s.instanced_meshes.size(), 1u);
  EXPECT_EQ(s.instanced_meshes[0].mesh.indices.size(), 32u);
  EXPECT_EQ(s.instanced_meshes[0].mesh.normals.size(), s.instanced_meshes[0].mesh.positions.size());
  ASSERT_EQ(s.instances.size(), 3u);
  EXPECT_EQ(s.instanced_triangle_count(), 96u);
  const mat4 object = glm::translate(mat4(1.0f), vec3(0, 1, 0));
  expect_near(s.instances[0].world_from_object,
              glm::translate(mat4(1.0f), vec3(10, 0, 0)) * object);
  expect_near(s.instances[1].world_from_object,
              glm::rotate(mat4(1.0f), glm::radians(90.0f), vec3(0, 1, 0)) * object);
  expect_near(s.instances[2].world_from_object, glm::scale(mat4(1.0f), vec3(2.0f)) * object);
  ASSERT_EQ(s.objects.size(), 1u);
  const ObjectInfo& o = s.objects[0];
  EXPECT_EQ(o.name, "land");
  EXPECT_EQ(o.kind, "instances");
  EXPECT_TRUE(o.is_instances);
  EXPECT_FALSE(o.is_triangles());
  EXPECT_EQ(o.first, 0u);
  EXPECT_EQ(o.count, 3u);
  EXPECT_EQ(o.loc.line, 6);
  for (uint32_t m : s.instanced_meshes[0].mesh.materials) EXPECT_EQ(s.materials[m].name, "rock");
}

TEST(JsonInstances, GridPlacesCopiesXFastest) {
  const Scene s = load_json(json_scene(R"(
    {"type": "box", "material": "rock", "min": [-20, -1, -20], "max": [-19, 0, -19]},
    {"type": "terrain", "size": [1, 0, 1], "resolution": 2, "material": "rock",
     "instances": {"grid": [3, 2, 4], "spacing": [1.5, 2, 3]}},
    {"type": "terrain", "size": [1, 0, 1], "resolution": 2, "material": "rock",
     "instances": [{"grid": [2, 1, 1], "spacing": [5, 0, 0]}, {"translate": [0, 7, 0]}]})"));
  EXPECT_EQ(s.mesh.indices.size(), 12u);  // the box
  ASSERT_EQ(s.instanced_meshes.size(), 2u);
  ASSERT_EQ(s.instances.size(), 24u + 3u);
  for (int k = 0, n = 0; k < 4; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 3; ++i, ++n) {
        EXPECT_EQ(s.instances[size_t(n)].mesh, 0u);
        expect_near(
            s.instances[size_t(n)].world_from_object,
            glm::translate(mat4(1.0f), vec3(1.5f * float(i), 2.0f * float(j), 3.0f * float(k))));
      }
  EXPECT_EQ(s.instances[24].mesh, 1u);
  expect_near(s.instances[25].world_from_object, glm::translate(mat4(1.0f), vec3(5, 0, 0)));
  expect_near(s.instances[26].world_from_object, glm::translate(mat4(1.0f), vec3(0, 7, 0)));
  ASSERT_EQ(s.objects.size(), 3u);
  EXPECT_EQ(s.objects[1].first, 0u);
  EXPECT_EQ(s.objects[1].count, 24u);
  EXPECT_EQ(s.objects[2].first, 24u);
  EXPECT_EQ(s.objects[2].count, 3u);
}

// A mesh file (the smooth torus) under a scale, placed by a mirror, a rotation and a move:
// flattening gives the triangles, winding and normals of the copies written out one by one.
TEST(JsonInstances, FlatteningEqualsSeparateObjects) {
  const std::string torus = test::source_dir() + "/assets/meshes/torus.obj";
  const std::string path = test::source_dir() + "/assets/scenes/instances.json";
  Scene inst = load_json(json_scene(R"(
    {"type": "mesh", "file": ")" + torus +
                                    R"(", "material": "rock", "transform": {"scale": 2},
     "instances": [{"translate": [5, 0, 0]}, {"scale": [-1, 1, 1], "translate": [0, 0, 3]},
                   {"rotate": [30, 40, 50]}]})"),
                         path);
  ASSERT_EQ(inst.instances.size(), 3u);
  EXPECT_EQ(inst.instanced_meshes[0].mesh.indices.size(), 1600u);
  flatten_instances(inst);
  EXPECT_TRUE(inst.instances.empty());
  EXPECT_TRUE(inst.instanced_meshes.empty());
  ASSERT_EQ(inst.objects.size(), 1u);
  EXPECT_EQ(inst.objects[0].kind, "mesh");
  EXPECT_EQ(inst.objects[0].count, 4800u);
  const std::string copy = R"({"type": "mesh", "file": ")" + torus + R"(", "material": "rock", )";
  const Scene copies = load_json(
      json_scene(copy + R"("transform": {"scale": 2, "translate": [5, 0, 0]}},)" + copy +
                 R"("transform": {"scale": [-2, 2, 2], "translate": [0, 0, 3]}},)" + copy +
                 R"("transform": {"matrix": [)" +
                 [] {
                   const mat4 m = glm::rotate(mat4(1.0f), glm::radians(50.0f), vec3(0, 0, 1)) *
                                  glm::rotate(mat4(1.0f), glm::radians(40.0f), vec3(0, 1, 0)) *
                                  glm::rotate(mat4(1.0f), glm::radians(30.0f), vec3(1, 0, 0)) *
                                  glm::scale(mat4(1.0f), vec3(2.0f));
                   std::string out;
                   for (int r = 0; r < 4; ++r)
                     for (int c = 0; c < 4; ++c) {
                       char buf[32];
                       std::snprintf(buf, sizeof buf, "%.9g", double(m[c][r]));
                       out += std::string(out.empty() ? "" : ", ") + buf;
                     }
                   return out;
                 }() +
                 "]}}"),
      path);
  expect_same_triangles(inst, copies, 1e-5f);
}

TEST(JsonInstances, FileMaterialsAndOverridesStayValid) {
  const std::string dir = temp_dir();
  write_file(dir + "/two.mtl", "newmtl a\nKd 0.1 0.2 0.3\nnewmtl b\nKd 0.4 0.5 0.6\n");
  write_file(dir + "/two.obj",
             "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
             "usemtl a\nf 1 2 3\nusemtl b\nf 2 4 3\n");
  const Scene s = load_json(json_scene(R"(
    {"type": "box", "material": "rock"},
    {"type": "mesh", "file": "two.obj", "materials": {"a": "rock"},
     "instances": [{"translate": [3, 0, 0]}, {"translate": [6, 0, 0]}]})"),
                            dir + "/scene.json");
  ASSERT_EQ(s.instanced_meshes.size(), 1u);
  const TriangleMesh& m = s.instanced_meshes[0].mesh;
  ASSERT_EQ(m.indices.size(), 2u);
  EXPECT_EQ(m.positions[m.indices[0].y], vec3(1, 0, 0)) << "stored in the file's own space";
  ASSERT_LT(m.materials[0], s.materials.size());
  ASSERT_LT(m.materials[1], s.materials.size());
  EXPECT_EQ(s.materials[m.materials[0]].name, "rock");
  EXPECT_EQ(s.materials[m.materials[1]].name, "b");
  EXPECT_EQ(s.materials[m.materials[1]].material.albedo, vec3(0.4f, 0.5f, 0.6f));
  EXPECT_EQ(s.mesh.indices.size(), 12u) << "the box alone";
}

TEST(JsonInstances, EmissiveObjectsAreFlattenedWithANote) {
  const Scene s = load_json(json_scene(R"(
    {"type": "terrain", "name": "glow", "size": [1, 0, 1], "resolution": 2, "material": "lamp",
     "instances": [{"translate": [0, 0, 0]}, {"translate": [3, 0, 0]}]})"));
  EXPECT_TRUE(s.instances.empty());
  EXPECT_TRUE(s.instanced_meshes.empty());
  ASSERT_EQ(s.mesh.indices.size(), 16u);
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_EQ(s.objects[0].kind, "terrain");
  EXPECT_EQ(s.objects[0].count, 16u);
  EXPECT_NEAR(s.mesh.positions[s.mesh.indices[8].x].x, 3.0f, 1e-6f);
  bool noted = false;
  for (const std::string& n : s.diagnostics.notes)
    noted |= contains(n, "scene.json:6") && contains(n, "\"glow\" emits light") &&
             contains(n, "flattened");
  EXPECT_TRUE(noted);
  EXPECT_TRUE(s.diagnostics.warnings.empty());
  // A file whose own material emits (lit_sphere.obj's Ke lamp) is flattened too.
  const std::string lit = test::source_dir() + "/assets/meshes/lit_sphere.obj";
  const Scene f =
      load_json(json_scene(R"({"type": "mesh", "file": ")" + lit +
                           R"(", "instances": {"grid": [2, 1, 1], "spacing": [9, 0, 0]}})"),
                test::source_dir() + "/assets/scenes/x.json");
  EXPECT_TRUE(f.instances.empty());
  EXPECT_GT(f.mesh.indices.size(), 0u);
}

TEST(JsonInstances, BadInputNamesFileAndLine) {
  const auto object = [](const std::string& instances) {
    return json_scene(R"(
    {"type": "terrain", "size": [1, 0, 1], "resolution": 2, "material": "rock",
     "instances": )" + instances +
                      "}");
  };
  const struct {
    std::string instances, expected;
  } cases[] = {
      {"5", "scene.json:7: \"instances\" of object \"terrain 0\" must be an array"},
      {"[]", "scene.json:7: \"instances\" of object \"terrain 0\" is empty"},
      {"[{\"move\": [1, 0, 0]}]", "scene.json:7: unknown key \"move\""},
      {"{\"grid\": [0, 1, 1], \"spacing\": [1, 1, 1]}", "must be whole numbers >= 1"},
      {"{\"grid\": [2.5, 1, 1], \"spacing\": [1, 1, 1]}", "must be whole numbers >= 1"},
      {"{\"grid\": [1, 1], \"spacing\": [1, 1, 1]}", "must be an array of 3 counts"},
      {"{\"grid\": [10000, 10000, 1], \"spacing\": [1, 1, 1]}",
       "places 100000000 instances, more than 10000000"},
      {"{\"grid\": [2, 2, 2]}", "has no \"spacing\""},
      {"[{\"matrix\": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1]}]", "is singular"},
      {"[{\"scale\": 1e-20}]", "is singular"},
      {"[{\"translate\": [1e39, 0, 0]}]", "too large for a 32-bit float"},
  };
  for (const auto& c : cases) {
    const std::string e = json_error(object(c.instances));
    EXPECT_TRUE(contains(e, c.expected)) << c.instances << "\n  gave: " << e;
    EXPECT_TRUE(contains(e, "scene.json:7:")) << e;
  }
  // "instances" is for meshes and terrains.
  EXPECT_TRUE(
      contains(json_error(json_scene(R"({"type": "box", "material": "rock", "instances": []})")),
               "unknown key \"instances\""));
}

// ---- pbrt-v4 ----

Scene load_pbrt(const std::string& text) {
  return load_pbrt_string(text, "/nonexistent/scene.pbrt");
}

const char* kQuad =
    "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1 1 0 0 1 0] \"integer indices\" "
    "[0 1 2 0 2 3] \"normal N\" [0 0.6 0.8 0 0 1 0 0 1 0.6 0 0.8]\n";
const char* kTriangle =
    "Shape \"trianglemesh\" \"point3 P\" [0 0 0 2 0 0 0 3 1] \"integer indices\" [0 1 2]\n";

// The object's shapes under each placement, written out; and the same with ObjectInstance.
struct PbrtPair {
  std::string instanced, written_out;
};
PbrtPair pbrt_pair(const std::string& header, const std::string& object_body,
                   const std::vector<std::string>& placements) {
  PbrtPair p;
  p.instanced = header + "WorldBegin\nObjectBegin \"thing\"\n" + object_body + "ObjectEnd\n";
  p.written_out = header + "WorldBegin\n";
  for (const std::string& place : placements) {
    p.instanced += "AttributeBegin\n" + place + "ObjectInstance \"thing\"\nAttributeEnd\n";
    p.written_out += "AttributeBegin\n" + place + object_body + "AttributeEnd\n";
  }
  return p;
}

TEST(PbrtInstances, ObjectInstanceMakesInstances) {
  const std::string camera = "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\"\n";
  const PbrtPair p =
      pbrt_pair(camera,
                "Material \"diffuse\" \"rgb reflectance\" [0.2 0.3 0.4]\nTranslate 0 1 0\n" +
                    std::string(kQuad) + kTriangle,
                {"", "Translate 10 0 0\n", "Scale -1 2 1\nRotate 30 0 1 1\n"});
  Scene inst = load_pbrt(p.instanced);
  EXPECT_TRUE(inst.mesh.indices.empty());
  ASSERT_EQ(inst.instanced_meshes.size(), 1u);
  EXPECT_EQ(inst.instanced_meshes[0].mesh.indices.size(), 3u);
  // The shapes' shared Translate is the instances' part: the mesh is stored as written.
  EXPECT_EQ(inst.instanced_meshes[0].mesh.positions[0], vec3(0, 0, 0));
  ASSERT_EQ(inst.instances.size(), 3u);
  ASSERT_EQ(inst.objects.size(), 3u);
  EXPECT_EQ(inst.objects[1].name, "thing #2");
  EXPECT_EQ(inst.objects[1].kind, "instances");
  EXPECT_EQ(inst.objects[1].first, 1u);
  EXPECT_EQ(inst.objects[1].count, 1u);
  EXPECT_EQ(inst.objects[1].loc.line, 15);
  expect_near(inst.instances[1].world_from_object,
              inst.instances[0].world_from_object * glm::translate(mat4(1.0f), vec3(10, 0, 0)));
  for (uint32_t m : inst.instanced_meshes[0].mesh.materials)
    EXPECT_EQ(inst.materials[m].material.albedo, vec3(0.2f, 0.3f, 0.4f));
  const Scene flat = load_pbrt(p.written_out);
  flatten_instances(inst);
  expect_same_triangles(inst, flat, 1e-5f);
}

TEST(PbrtInstances, ShapesUnderTheirOwnTransforms) {
  // Shapes of one object under different transforms (one mirroring) keep them in the mesh.
  const PbrtPair p = pbrt_pair(
      "",
      "AttributeBegin\nTranslate 0 0 2\n" + std::string(kQuad) + "AttributeEnd\n" +
          "AttributeBegin\nScale 1 -1 1\nReverseOrientation\n" + kTriangle + "AttributeEnd\n",
      {"Translate 1 2 3\n", "Scale 1 1 -1\n", "Rotate 45 1 0 0\n"});
  Scene inst = load_pbrt(p.instanced);
  ASSERT_EQ(inst.instanced_meshes.size(), 1u);
  ASSERT_EQ(inst.instances.size(), 3u);
  const Scene flat = load_pbrt(p.written_out);
  flatten_instances(inst);
  expect_same_triangles(inst, flat, 1e-5f);
}

TEST(PbrtInstances, EmittersAndSpheresAreFlattened) {
  const Scene lit = load_pbrt(
      "WorldBegin\nObjectBegin \"lamp\"\nAreaLightSource \"diffuse\" \"rgb L\" [4 4 4]\n" +
      std::string(kTriangle) +
      "ObjectEnd\nObjectInstance \"lamp\"\nTranslate 5 0 0\n"
      "ObjectInstance \"lamp\"\n");
  EXPECT_TRUE(lit.instances.empty());
  EXPECT_EQ(lit.mesh.indices.size(), 2u);
  const Scene ball =
      load_pbrt("WorldBegin\nObjectBegin \"ball\"\nShape \"sphere\"\n" + std::string(kTriangle) +
                "ObjectEnd\nObjectInstance \"ball\"\nTranslate 5 0 0\nObjectInstance \"ball\"\n");
  EXPECT_TRUE(ball.instances.empty());
  EXPECT_EQ(ball.spheres.size(), 2u);
  EXPECT_EQ(ball.mesh.indices.size(), 2u);
}

// ---- Validation ----

// A scene of one instanced mesh (a unit quad) placed twice, lit by the sky.
Scene instanced_scene() {
  Scene s;
  s.source = "/nonexistent/built.json";
  s.add_material("grey", Material());
  s.environment.color = vec3(1.0f);
  TriangleMesh m;
  m.positions = {vec3(0, 0, 0), vec3(1, 0, 0), vec3(1, 1, 0), vec3(0, 1, 0)};
  m.indices = {uvec3(0, 1, 2), uvec3(0, 2, 3)};
  m.materials = {0, 0};
  s.instanced_meshes.push_back({"quad", m});
  s.instances.push_back({0, mat4(1.0f)});
  s.instances.push_back({0, glm::translate(mat4(1.0f), vec3(2, 0, 0))});
  ObjectInfo o;
  o.name = "quads";
  o.kind = "instances";
  o.is_instances = true;
  o.first = 0;
  o.count = 2;
  o.loc = {"/nonexistent/built.json", 4};
  s.objects.push_back(o);
  s.camera.position = vec3(1, 0.5f, 5);
  s.camera.look_at = vec3(1, 0.5f, 0);
  return s;
}

std::string validate_error(Scene s) {
  try {
    validate_scene(s);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(InstanceValidation, OnlyInstancesIsAScene) {
  Scene s = instanced_scene();
  ASSERT_NO_THROW(validate_scene(s));
  EXPECT_TRUE(s.diagnostics.warnings.empty());
}

TEST(InstanceValidation, BadDataIsAnErrorNamingTheObject) {
  const std::string at = "/nonexistent/built.json:4: object \"quads\"";
  Scene s = instanced_scene();
  s.instanced_meshes[0].mesh.indices[1].z = 4;
  EXPECT_TRUE(contains(validate_error(s), at + " has a vertex index out of range"));
  s = instanced_scene();
  s.instanced_meshes[0].mesh.materials[0] = 7;
  EXPECT_TRUE(contains(validate_error(s), at + " has material index 7 out of range"));
  s = instanced_scene();
  s.instanced_meshes[0].mesh.positions[1].y = NAN;
  EXPECT_TRUE(contains(validate_error(s), at + " has a non-finite vertex position"));
  s = instanced_scene();
  s.instanced_meshes[0].mesh.materials.pop_back();
  EXPECT_TRUE(contains(validate_error(s), at + " has 2 triangles, 1 material ids"));
  s = instanced_scene();
  Material lamp;
  lamp.emission = vec3(1.0f);
  s.instanced_meshes[0].mesh.materials[0] = s.add_material("lamp", lamp);
  EXPECT_TRUE(contains(validate_error(s), at + " is instanced but its material \"lamp\" emits"));
  s = instanced_scene();
  s.instances[1].mesh = 3;
  EXPECT_TRUE(contains(validate_error(s), at + " places instanced mesh 3, but the scene has 1"));
  s = instanced_scene();
  s.instances[1].world_from_object[1] = vec4(0.0f);
  EXPECT_TRUE(
      contains(validate_error(s), "the transform of instance 1 (object \"quads\") is singular"));
  s = instanced_scene();
  s.instances[0].world_from_object[3].x = INFINITY;
  EXPECT_TRUE(contains(validate_error(s), "is not finite"));
  s = instanced_scene();
  s.instances[0].world_from_object = glm::translate(mat4(1.0f), vec3(2e12f, 0, 0));
  EXPECT_TRUE(contains(validate_error(s), at + " reaches"));
}

TEST(InstanceValidation, DegenerateTrianglesAreRemoved) {
  Scene s = instanced_scene();
  s.instanced_meshes[0].mesh.indices.push_back(uvec3(0, 0, 1));
  s.instanced_meshes[0].mesh.materials.push_back(0);
  ASSERT_NO_THROW(validate_scene(s));
  EXPECT_EQ(s.instanced_meshes[0].mesh.indices.size(), 2u);
  ASSERT_EQ(s.diagnostics.warnings.size(), 1u);
  EXPECT_TRUE(contains(s.diagnostics.warnings[0], "1 zero-area triangle(s)"));
  // A mesh of nothing but degenerate triangles loses its instances; alone it is no scene.
  s = instanced_scene();
  s.instanced_meshes[0].mesh.indices = {uvec3(0, 1, 1)};
  s.instanced_meshes[0].mesh.materials = {0};
  EXPECT_TRUE(contains(validate_error(s), "the scene has no geometry"));
}

TEST(InstanceValidation, TotalPrimitivesBelow2To31) {
  Scene s = instanced_scene();
  TriangleMesh& m = s.instanced_meshes[0].mesh;
  // 100,000 triangles placed 21,475 times: 2,147,500,000 > 2^31.
  m.positions.clear();
  m.indices.clear();
  for (int i = 0; i <= 50000; ++i) {
    m.positions.push_back(vec3(float(i), 0, 0));
    m.positions.push_back(vec3(float(i), 1, 0));
  }
  for (uint32_t i = 0; i < 50000; ++i) {
    m.indices.push_back(uvec3(2 * i, 2 * i + 2, 2 * i + 3));
    m.indices.push_back(uvec3(2 * i, 2 * i + 3, 2 * i + 1));
  }
  m.materials.assign(m.indices.size(), 0);
  s.instances.resize(21475, s.instances[0]);
  s.objects[0].count = 21475;
  EXPECT_TRUE(contains(validate_error(s),
                       "the scene has 2147500000 primitives (2147500000 instanced triangles, 0 "
                       "other triangles and 0 spheres), more than the limit of 2^31"));
  s.instances.resize(21474);
  s.objects[0].count = 21474;
  EXPECT_EQ(validate_error(s), "(no error)");
}

}  // namespace
