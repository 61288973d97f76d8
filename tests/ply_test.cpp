// The PLY reader: ASCII and both binary byte orders read the same mesh, polygons are fanned,
// unknown elements and properties are skipped by their sizes, and broken files (truncated, lying
// counts, bad indices, NaN) fail with the file's name (and line) instead of crashing or
// allocating what the header claims.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <random>

#include "scene/loader.h"
#include "scene/ply_reader.h"
#include "test_util.h"

using namespace tracer;

namespace {

std::string temp_dir() {
  std::string tmpl = testing::TempDir() + "ply_test_XXXXXX";
  return std::string(mkdtemp(tmpl.data()));
}

std::string write_file(const std::string& dir, const std::string& name, const std::string& bytes) {
  const std::string path = dir + "/" + name;
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

// A triangle, a quad and a pentagon over 6 vertices with normals and uvs, in the given format.
// The binary bodies are built value by value in the file's byte order.
struct Writer {
  bool big = false;
  std::string out;
  template <typename T>
  void put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof v);
    if (big) std::reverse(b, b + sizeof v);
    out.append(b, sizeof v);
  }
};

const float kPos[6][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0, 0}, {2, 1, 0}};
const int kFaces[3][5] = {{0, 1, 2, -1, -1}, {0, 1, 2, 3, -1}, {1, 4, 5, 2, 3}};
const int kCounts[3] = {3, 4, 5};

std::string header(const std::string& format, const char* uv_u = "u", const char* uv_v = "v") {
  return "ply\nformat " + format +
         " 1.0\ncomment made by ply_test\nelement vertex 6\nproperty float x\nproperty float y\n"
         "property float z\nproperty uchar red\nproperty float nx\nproperty float ny\n"
         "property float nz\nproperty float " +
         uv_u + "\nproperty float " + uv_v +
         "\nelement edge 2\nproperty list uchar int vertex_pair\nproperty short crease\n"
         "element face 3\nproperty list uchar int vertex_indices\nproperty int face_id\n"
         "end_header\n";
}

std::string ascii_ply(const char* u = "u", const char* v = "v") {
  std::string s = header("ascii", u, v);
  for (int i = 0; i < 6; ++i)
    s += std::to_string(kPos[i][0]) + " " + std::to_string(kPos[i][1]) + " " +
         std::to_string(kPos[i][2]) + " 255 0 0 1 " + std::to_string(0.1 * i) + " 0.25\n";
  s += "2 0 1 7\n2 1 2 -3\n";
  for (int f = 0; f < 3; ++f) {
    s += std::to_string(kCounts[f]);
    for (int k = 0; k < kCounts[f]; ++k) s += " " + std::to_string(kFaces[f][k]);
    s += " " + std::to_string(f) + "\n";
  }
  return s;
}

std::string binary_ply(bool big) {
  Writer w;
  w.big = big;
  w.out = header(big ? "binary_big_endian" : "binary_little_endian");
  for (int i = 0; i < 6; ++i) {
    for (int k = 0; k < 3; ++k) w.put(kPos[i][k]);
    w.put(uint8_t(255));
    w.put(0.0f), w.put(0.0f), w.put(1.0f);
    w.put(float(0.1 * i)), w.put(0.25f);
  }
  for (int e = 0; e < 2; ++e) {
    w.put(uint8_t(2)), w.put(int32_t(e)), w.put(int32_t(e + 1)), w.put(int16_t(7));
  }
  for (int f = 0; f < 3; ++f) {
    w.put(uint8_t(kCounts[f]));
    for (int k = 0; k < kCounts[f]; ++k) w.put(int32_t(kFaces[f][k]));
    w.put(int32_t(f));
  }
  return w.out;
}

void expect_reference_mesh(const PlyMesh& m) {
  ASSERT_EQ(m.part.positions.size(), 6u);
  EXPECT_EQ(m.part.positions[5], vec3(2, 1, 0));
  ASSERT_EQ(m.part.normals.size(), 6u);
  EXPECT_EQ(m.part.normals[3], vec3(0, 0, 1));
  ASSERT_EQ(m.part.uvs.size(), 6u);
  // v is flipped into our convention (v down the image).
  EXPECT_NEAR(m.part.uvs[2].x, 0.2f, 1e-6f);
  EXPECT_NEAR(m.part.uvs[2].y, 0.75f, 1e-6f);
  // 1 + 2 + 3 triangles, fanned from each face's first corner.
  ASSERT_EQ(m.part.indices.size(), 6u);
  EXPECT_EQ(m.part.indices[1], uvec3(0, 1, 2));
  EXPECT_EQ(m.part.indices[2], uvec3(0, 2, 3));
  EXPECT_EQ(m.part.indices[5], uvec3(1, 2, 3));
  EXPECT_EQ(m.skipped_faces, 0u);
}

std::string error_of(const std::string& bytes, const std::string& name = "bad.ply") {
  try {
    parse_ply(bytes, name);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for " << name;
  return "";
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

}  // namespace

TEST(Ply, AsciiAndBothBinaryOrdersReadTheSameMesh) {
  expect_reference_mesh(parse_ply(ascii_ply(), "a.ply"));
  expect_reference_mesh(parse_ply(binary_ply(false), "le.ply"));
  expect_reference_mesh(parse_ply(binary_ply(true), "be.ply"));
}

TEST(Ply, EveryUvNamingIsRead) {
  const char* names[][2] = {
      {"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}};
  for (const auto& n : names) {
    const PlyMesh m = parse_ply(ascii_ply(n[0], n[1]), "uv.ply");
    ASSERT_EQ(m.part.uvs.size(), 6u) << n[0];
    EXPECT_NEAR(m.part.uvs[4].x, 0.4f, 1e-6f) << n[0];
  }
  // An unrecognised pair is skipped like any other property.
  EXPECT_TRUE(parse_ply(ascii_ply("p", "q"), "uv.ply").part.uvs.empty());
}

TEST(Ply, IndexListsOfEveryIntegerType) {
  for (const char* count : {"uchar", "char", "ushort", "short", "uint", "int"}) {
    for (const char* item : {"uchar", "ushort", "short", "uint32", "int", "int8"}) {
      Writer w;
      w.out = std::string("ply\nformat binary_little_endian 1.0\nelement vertex 3\n") +
              "property double x\nproperty double y\nproperty double z\nelement face 1\n" +
              "property list " + count + " " + item + " vertex_index\nend_header\n";
      const double p[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
      for (const auto& v : p)
        for (double c : v) w.put(c);
      auto put_as = [&](const char* type, int v) {
        const std::string t = type;
        if (t == "uchar" || t == "int8" || t == "char")
          w.put(uint8_t(v));
        else if (t == "ushort" || t == "short")
          w.put(uint16_t(v));
        else
          w.put(uint32_t(v));
      };
      put_as(count, 3);
      for (int k = 0; k < 3; ++k) put_as(item, k);
      const PlyMesh m = parse_ply(w.out, "types.ply");
      ASSERT_EQ(m.part.indices.size(), 1u) << count << " " << item;
      EXPECT_EQ(m.part.indices[0], uvec3(0, 1, 2));
      EXPECT_TRUE(m.part.normals.empty());
    }
  }
}

TEST(Ply, FacesWithFewerThanThreeCornersAreCountedAndSkipped) {
  const std::string s =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 3\nproperty list uchar uint vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n2 0 1\n0\n";
  const PlyMesh m = parse_ply(s, "short.ply");
  EXPECT_EQ(m.part.indices.size(), 1u);
  EXPECT_EQ(m.skipped_faces, 2u);
}

TEST(Ply, BrokenFilesFailWithPathAndWhere) {
  // Not a PLY file, an unknown format, a missing end_header, a property before any element.
  EXPECT_TRUE(contains(error_of("solid x\n", "a.ply"), "a.ply:1: not a PLY file"));
  EXPECT_TRUE(
      contains(error_of("ply\nformat utf8 1.0\nend_header\n"), "bad.ply:2: unknown PLY format"));
  EXPECT_TRUE(contains(error_of("ply\nformat ascii 1.0\nelement vertex 1\n"), "no end_header"));
  EXPECT_TRUE(contains(error_of("ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
                       "bad.ply:3: \"property\" before any \"element\""));
  EXPECT_TRUE(
      contains(error_of("ply\nformat ascii 1.0\nelement vertex 1\nproperty flot x\nend_header\n"),
               "unknown property type \"flot\""));
  EXPECT_TRUE(contains(error_of(""), "the file is empty"));

  // Truncated binary data: the element and its index, no line.
  const std::string bin = binary_ply(false);
  const std::string cut = error_of(bin.substr(0, bin.size() - 2), "cut.ply");
  EXPECT_TRUE(contains(cut, "cut.ply: element \"face\" 2 of 3")) << cut;
  EXPECT_TRUE(contains(cut, "ends early")) << cut;

  // A header that claims more than the file can hold is refused before anything is allocated.
  std::string lying = bin;
  lying.replace(lying.find("element vertex 6"), 16, "element vertex 4000000000");
  const std::string huge = error_of(lying, "lying.ply");
  EXPECT_TRUE(contains(huge, "lying.ply:4: element \"vertex\" declares 4000000000 instances"))
      << huge;
  std::string lying_list = ascii_ply();
  lying_list.replace(lying_list.rfind("\n3 0 1 2"), 8, "\n4000000000 0 1 2");
  EXPECT_TRUE(contains(error_of(lying_list), "more than the rest of the file holds"));

  // Index out of range and NaN in an ASCII file: the line.
  std::string bad_index = ascii_ply();
  bad_index.replace(bad_index.rfind("\n4 0 1 2 3"), 10, "\n4 0 1 2 9");
  const std::string idx = error_of(bad_index, "idx.ply");
  EXPECT_TRUE(contains(
      idx, "idx.ply:30: element \"face\" 1 of 3: refers to vertex 9, but the file has 6 vertices"))
      << idx;
  std::string nan = ascii_ply();
  nan.replace(nan.find("\n1.000000 1.000000 0.000000"), 27, "\n1.000000 nan 0.000000");
  const std::string n = error_of(nan, "nan.ply");
  EXPECT_TRUE(
      contains(n, "nan.ply:23: element \"vertex\" 2 of 6: property \"y\" is not a finite number"))
      << n;
  std::string word = ascii_ply();
  word.replace(word.find(" 255 "), 5, " red ");
  EXPECT_TRUE(contains(error_of(word), "\"red\" is not a number"));

  // Negative indices, float index lists, no vertex element, missing coordinates.
  std::string neg = ascii_ply();
  neg.replace(neg.rfind("\n3 0 1 2"), 8, "\n3 0 -1 2");
  EXPECT_TRUE(contains(error_of(neg), "refers to vertex -1"));
  EXPECT_TRUE(contains(
      error_of("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
               "property float z\nelement face 1\nproperty list uchar float vertex_indices\n"
               "end_header\n0 0 0\n3 0 0 0\n"),
      "floating-point numbers, not indices"));
  EXPECT_TRUE(contains(error_of("ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int "
                                "vertex_indices\nend_header\n"),
                       "no \"vertex\" element"));
  EXPECT_TRUE(contains(
      error_of("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n"),
      "bad.ply:3: the vertex element lacks one of the properties x, y, z"));
}

// Every prefix of a valid binary file, and random byte damage, either loads or fails with an
// InputError: never a crash, a hang or a huge allocation.
TEST(Ply, TruncationsAndDamageNeverCrash) {
  for (const std::string& good : {binary_ply(false), binary_ply(true), ascii_ply()}) {
    for (size_t n = 0; n < good.size(); ++n) {
      try {
        parse_ply(good.substr(0, n), "t.ply");
      } catch (const InputError&) {
      }
    }
    std::mt19937 rng(7);
    for (int trial = 0; trial < 2000; ++trial) {
      std::string s = good;
      for (int k = 0; k < 3; ++k) s[rng() % s.size()] = char(rng() & 0xff);
      try {
        parse_ply(s, "d.ply");
      } catch (const InputError&) {
      }
    }
  }
}

TEST(Ply, OpensDirectlyAndAsAJsonMeshObject) {
  const std::string dir = temp_dir();
  const std::string ply = write_file(dir, "tri.ply", binary_ply(false));
  const Scene direct = load_scene(ply);
  EXPECT_EQ(direct.objects.front().name, "tri.ply");
  EXPECT_EQ(direct.objects.front().count, 6u);
  EXPECT_FALSE(direct.diagnostics.notes.empty());  // framing camera and default light
  write_file(dir, "scene.json",
             R"({"materials": {"red": {"type": "diffuse", "albedo": [0.8, 0.1, 0.1]},
                 "lamp": {"type": "diffuse", "albedo": [0, 0, 0], "emission": [5, 5, 5]}},
                 "objects": [{"type": "mesh", "file": "tri.ply", "material": "red",
                              "transform": {"translate": [0, 0, -3]}},
                             {"type": "sphere", "center": [0, 4, 0], "radius": 1, "material": "lamp"}]})");
  const Scene s = load_scene(dir + "/scene.json");
  ASSERT_EQ(s.mesh.indices.size(), 6u);
  EXPECT_EQ(s.mesh.positions[s.mesh.indices[0].x].z, -3.0f);
  EXPECT_EQ(s.materials[s.mesh.materials[0]].name, "red");
  // A broken PLY referenced from JSON names both files.
  write_file(dir, "cut.ply", binary_ply(false).substr(0, 300));
  write_file(dir, "cut.json", R"({"objects": [{"type": "mesh", "file": "cut.ply"}]})");
  try {
    load_scene(dir + "/cut.json");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "cut.ply")) << e.what();
    EXPECT_TRUE(contains(e.what(), "(mesh referenced at " + dir + "/cut.json:1)")) << e.what();
  }
}
