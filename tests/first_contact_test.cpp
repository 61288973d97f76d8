// What a new user meets first with their own files: a mesh file opened without a camera is framed
// from the side it is meant to be seen from and lit when its own emitters are negligible; a JSON
// mesh object overrides the file's materials by name; --strict turns warnings into errors; info
// counts every material type.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "image/image.h"
#include "scene/loader.h"
#include "test_util.h"

namespace {

using tracer::vec3;

std::string tmpdir() {
  static std::string dir = [] {
    char tmpl[] = "/tmp/pathtracer_first_XXXXXX";
    return std::string(mkdtemp(tmpl));
  }();
  return dir;
}

std::string write_file(const std::string& name, const std::string& text) {
  const std::string path = tmpdir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

// An axis-aligned unit cube [0,1]^3 as OBJ quads wound outwards, leaving out the faces in `skip`
// ("-z" etc.); `inward` reverses every face (a room seen from inside).
std::string cube_obj(const std::string& skip = "", bool inward = false,
                     const std::string& header = "") {
  std::string s = header +
                  "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n";
  const struct {
    const char* name;
    int a, b, c, d;
  } faces[] = {{"-z", 1, 4, 3, 2}, {"+z", 5, 6, 7, 8}, {"-x", 1, 5, 8, 4},
               {"+x", 2, 3, 7, 6}, {"-y", 1, 2, 6, 5}, {"+y", 4, 8, 7, 3}};
  for (const auto& f : faces) {
    if (skip.find(f.name) != std::string::npos) continue;
    if (inward)
      s += "f " + std::to_string(f.d) + " " + std::to_string(f.c) + " " + std::to_string(f.b) +
           " " + std::to_string(f.a) + "\n";
    else
      s += "f " + std::to_string(f.a) + " " + std::to_string(f.b) + " " + std::to_string(f.c) +
           " " + std::to_string(f.d) + "\n";
  }
  return s;
}

vec3 view_direction(const tracer::Scene& s) {
  return glm::normalize(s.camera.position - s.camera.look_at);
}

bool has_note(const tracer::Scene& s, const std::string& text) {
  for (const std::string& n : s.diagnostics.notes)
    if (n.find(text) != std::string::npos) return true;
  return false;
}

bool has_material(const tracer::Scene& s, const std::string& name) {
  return s.find_material(name) != tracer::kInvalid;
}

// The mean of a small CPU render of `scene_path`.
double render_mean(const std::string& scene_path, const std::string& out) {
  std::string log;
  const int rc = test::run_command(test::pathtracer_exe() + " render -q --backend cpu --spp 8 " +
                                       "--width 48 --height 48 --out " + out + " " + scene_path,
                                   &log);
  EXPECT_EQ(rc, 0) << log;
  if (rc != 0) return -1.0;
  const tracer::ImageRGB img = tracer::read_image(out);
  double sum = 0.0;
  for (float v : img.pixels) sum += v;
  return sum / double(img.pixels.size());
}

TEST(Framing, ClosedModelGetsAThreeQuarterViewFromAboveTheFront) {
  const tracer::Scene s = tracer::load_scene(write_file("cube.obj", cube_obj()));
  const vec3 d = view_direction(s);
  EXPECT_GT(d.x, 0.2f);
  EXPECT_GT(d.y, 0.2f);
  EXPECT_GT(d.z, 0.5f);  // from the front (+z)
  // The bounding sphere (radius sqrt(3)/2 around the centre) fits the field of view.
  EXPECT_NEAR(glm::length(s.camera.look_at - vec3(0.5f)), 0.0f, 1e-5f);
  const float dist = glm::length(s.camera.position - s.camera.look_at);
  EXPECT_GE(dist * std::sin(glm::radians(0.5f * s.camera.vfov_deg)), 0.5f * std::sqrt(3.0f));
  EXPECT_TRUE(has_note(s, "three-quarter view")) << s.diagnostics.notes.size();
  EXPECT_TRUE(has_note(s, "no light in the file"));
  EXPECT_TRUE(s.diagnostics.warnings.empty());  // choices, not problems: --strict accepts them
}

TEST(Framing, OpenRoomIsSeenThroughItsOpening) {
  // A room without its front (-z) wall, faces wound inwards, like the classic Cornell box OBJ.
  const tracer::Scene s = tracer::load_scene(write_file("room.obj", cube_obj("-z", true)));
  const vec3 d = view_direction(s);
  EXPECT_LT(d.z, -0.8f) << d.x << " " << d.y << " " << d.z;
  EXPECT_TRUE(has_note(s, "open or one-sided"));
  // Seen from the front (+z) it would be the outside of the back wall: the render must show the
  // lit inside.
  EXPECT_GT(render_mean(write_file("room2.obj", cube_obj("-z", true)), tmpdir() + "/room.png"),
            0.05);
}

TEST(Framing, ASinglePlaneIsSeenFromTheSideItFaces) {
  // One quad facing down: from above (the default) only its unlit back would show.
  const std::string down = write_file("down.obj", "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 2 3 4\n");
  const tracer::Scene s = tracer::load_scene(down);
  EXPECT_LT(view_direction(s).y, -0.8f);
  EXPECT_GT(render_mean(down, tmpdir() + "/down.png"), 0.05);
  // An edge-on polygon in the yz plane, facing -x.
  const std::string side = write_file("side.obj", "v 0 0 0\nv 0 0 1\nv 0 1 1\nv 0 1 0\nf 1 2 3 4\n");
  EXPECT_LT(view_direction(tracer::load_scene(side)).x, -0.8f);
  EXPECT_GT(render_mean(side, tmpdir() + "/side.png"), 0.05);
}

TEST(Framing, DefaultLightIsAddedWhenTheFilesEmittersAreNegligible) {
  // A unit cube plus a 0.01 x 0.01 emissive label: a glow, not a light for the model.
  const std::string mtl = "newmtl grey\nKd 0.5 0.5 0.5\nnewmtl label\nKd 0 0 0\nKe 1 1 1\n";
  write_file("label.mtl", mtl);
  const std::string label =
      "mtllib label.mtl\n" + cube_obj("", false, "usemtl grey\n") +
      "usemtl label\nv 0.4 0.4 1.01\nv 0.41 0.4 1.01\nv 0.41 0.41 1.01\nv 0.4 0.41 1.01\n"
      "f 9 10 11 12\n";
  const tracer::Scene s = tracer::load_scene(write_file("label.obj", label));
  EXPECT_TRUE(has_material(s, "default light"));
  EXPECT_TRUE(has_note(s, "the file's emitters give")) << (s.diagnostics.notes.empty() ? "" : s.diagnostics.notes[0]);
  // A real lamp above the cube (2 x 2, radiance 5) is kept as the only light.
  const std::string lamp =
      "mtllib label.mtl\n" + cube_obj("", false, "usemtl grey\n") +
      "usemtl label\nv -0.5 3 -0.5\nv 1.5 3 -0.5\nv 1.5 3 1.5\nv -0.5 3 1.5\nf 9 12 11 10\n";
  write_file("lamp.mtl", "newmtl grey\nKd 0.5 0.5 0.5\nnewmtl label\nKd 0 0 0\nKe 5 5 5\n");
  std::string lamp_obj = lamp;
  lamp_obj.replace(0, std::string("mtllib label.mtl").size(), "mtllib lamp.mtl");
  const tracer::Scene t = tracer::load_scene(write_file("lamp.obj", lamp_obj));
  EXPECT_FALSE(has_material(t, "default light"));
}

const char* kOverrideScene = R"({
  "camera": {"position": [0.5, 0.5, 4], "look_at": [0.5, 0.5, 0.5]},
  "materials": {"white": {"albedo": [0.9, 0.9, 0.9]}},
  "objects": [
    {"type": "mesh", "file": "two.obj", "materials": %s}
  ]
})";

tracer::Scene load_override(const std::string& overrides) {
  write_file("two.mtl",
             "newmtl red\nKd 0.8 0.1 0.1\nnewmtl light\nKd 0 0 0\nKe 2 2 2\n");
  write_file("two.obj", "mtllib two.mtl\n" + cube_obj("", false, "usemtl red\n") +
                            "usemtl light\nv 0 2 0\nv 1 2 0\nv 1 2 1\nv 0 2 1\nf 9 12 11 10\n");
  char text[1024];
  snprintf(text, sizeof text, kOverrideScene, overrides.c_str());
  return tracer::load_scene(write_file("override.json", text));
}

TEST(MaterialOverride, AMeshObjectEditsOrReplacesTheFilesMaterialsByName) {
  const tracer::Scene s = load_override(
      R"({"light": {"emission_strength": 3, "two_sided": true}, "red": "white"})");
  const tracer::Material& light = s.materials[s.find_material("light")].material;
  EXPECT_EQ(light.emission, vec3(6.0f));  // the file's Ke 2, three times as bright
  EXPECT_TRUE(light.flags & tracer::kMaterialTwoSidedEmission);
  // "red" is replaced by the scene's "white": the cube's triangles now use it.
  const uint32_t white = s.find_material("white");
  EXPECT_EQ(s.mesh.materials[0], white);
  const uint32_t red = s.find_material("red");
  for (uint32_t m : s.mesh.materials) EXPECT_NE(m, red);
  // Keys not given keep the file's values.
  const tracer::Scene t = load_override(R"({"red": {"type": "conductor", "roughness": 0.3}})");
  const tracer::Material& metal = t.materials[t.find_material("red")].material;
  EXPECT_EQ(metal.type, tracer::MaterialType::kConductor);
  EXPECT_NEAR(metal.albedo.x, 0.8f, 1e-6f);
  EXPECT_NEAR(metal.roughness, 0.3f, 1e-6f);
}

TEST(MaterialOverride, UnknownNamesAndConflictsAreErrorsWithTheLine) {
  try {
    load_override(R"({"lihgt": {"two_sided": true}})");
    FAIL() << "an unknown file material was accepted";
  } catch (const tracer::InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("override.json:5"), std::string::npos) << what;
    EXPECT_NE(what.find("did you mean \"light\""), std::string::npos) << what;
  }
  EXPECT_THROW(load_override(R"({"red": "no such material"})"), tracer::InputError);
  EXPECT_THROW(load_override(R"({"red": {"albdo": [1, 1, 1]}})"), tracer::InputError);
  EXPECT_THROW(load_override(R"(["red"])"), tracer::InputError);
  write_file("both.json", R"({"materials": {"white": {}}, "objects": [
    {"type": "mesh", "file": "two.obj", "material": "white", "materials": {"red": "white"}}]})");
  EXPECT_THROW(tracer::load_scene(tmpdir() + "/both.json"), tracer::InputError);
}

TEST(Strict, EveryWarningBecomesAnErrorBeforeRendering) {
  // A clamped albedo is a warning: rendered normally, refused under --strict.
  const std::string scene = write_file("warn.json", R"({
    "render": {"width": 8, "height": 8, "spp": 1},
    "materials": {"hot": {"albedo": [1.5, 0.5, 0.5]}, "lamp": {"emission": [1, 1, 1]}},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "hot"},
                {"type": "sphere", "center": [0, 3, 0], "radius": 1, "material": "lamp"}]})");
  const std::string out = tmpdir() + "/strict.png";
  const std::string base = test::pathtracer_exe() + " render --backend cpu --out " + out + " ";
  std::string log;
  EXPECT_EQ(test::run_command(base + scene, &log), 0) << log;
  EXPECT_NE(log.find("warning: "), std::string::npos) << log;
  unlink(out.c_str());
  EXPECT_EQ(test::run_command(base + "--strict " + scene, &log), 1) << log;
  EXPECT_NE(log.find("--strict"), std::string::npos) << log;
  EXPECT_NE(log.find("albedo"), std::string::npos) << log;
  EXPECT_NE(access(out.c_str(), F_OK), 0) << "--strict rendered anyway";
  EXPECT_EQ(test::run_command(base + "--set render.strict=on " + scene, &log), 1) << log;
  // The scene file can ask for it; the command line can take it back.
  const std::string strict_scene = write_file("strict.json", R"({
    "render": {"width": 8, "height": 8, "spp": 1, "strict": true},
    "materials": {"hot": {"albedo": [1.5, 0.5, 0.5]}, "lamp": {"emission": [1, 1, 1]}},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "hot"},
                {"type": "sphere", "center": [0, 3, 0], "radius": 1, "material": "lamp"}]})");
  EXPECT_EQ(test::run_command(base + strict_scene, &log), 1) << log;
  EXPECT_EQ(test::run_command(base + "--set render.strict=off " + strict_scene, &log), 0) << log;
  // Notes (a framing camera, a default light) are not warnings: a clean mesh passes.
  EXPECT_EQ(test::run_command(base + "--strict --width 8 --height 8 --spp 1 " +
                                  write_file("clean.obj", cube_obj()), &log), 0) << log;
  EXPECT_NE(log.find("note: "), std::string::npos) << log;
}

// Renders `scene` (8x8, 2 spp, CPU) with `flags` and returns the exit status and stderr.
int render_log(const std::string& scene, const std::string& flags, std::string* log) {
  return test::run_command(test::pathtracer_exe() + " render -q --backend cpu --width 8 " +
                               "--height 8 --spp 2 --out " + tmpdir() + "/black.png " + flags +
                               " " + scene,
                           log);
}

TEST(BlackImage, AnEntirelyBlackRenderSaysWhy) {
  std::string log;
  // The camera inside a closed box, the light outside.
  const std::string inside = write_file("inside.json", R"({
    "camera": {"position": [0, 0, 0], "look_at": [0, 0, -1]},
    "materials": {"grey": {}, "lamp": {"emission": [5, 5, 5]}},
    "objects": [{"type": "box", "name": "crate", "min": [-1, -1, -1], "max": [1, 1, 1],
                 "material": "grey"},
                {"type": "sphere", "center": [0, 5, 0], "radius": 1, "material": "lamp"}]})");
  EXPECT_EQ(render_log(inside, "", &log), 0) << log;
  EXPECT_NE(log.find("entirely black: the camera at [0, 0, 0] is inside a closed object (\"crate\")"),
            std::string::npos) << log;
  EXPECT_EQ(render_log(inside, "--strict", &log), 1) << log;  // a warning, so --strict fails
  // A one-sided lamp above a floor, facing the sky.
  const std::string away = write_file("away.json", R"({
    "camera": {"position": [0, 1, 3], "look_at": [0, 0, 0]},
    "materials": {"grey": {}, "lamp": {"emission": [5, 5, 5]}},
    "objects": [{"type": "quad", "corner": [-2, 0, 2], "edge1": [4, 0, 0], "edge2": [0, 0, -4],
                 "material": "grey"},
                {"type": "quad", "corner": [-0.5, 2, -0.5], "edge1": [0, 0, 1],
                 "edge2": [1, 0, 0], "material": "lamp"}]})");
  EXPECT_EQ(render_log(away, "", &log), 0) << log;
  EXPECT_NE(log.find("every light faces away"), std::string::npos) << log;
  // The same lamp facing down lights the floor: no warning.
  std::string lit_text = R"({
    "camera": {"position": [0, 1, 3], "look_at": [0, 0, 0]},
    "materials": {"grey": {}, "lamp": {"emission": [5, 5, 5]}},
    "objects": [{"type": "quad", "corner": [-2, 0, 2], "edge1": [4, 0, 0], "edge2": [0, 0, -4],
                 "material": "grey"},
                {"type": "quad", "corner": [-0.5, 2, -0.5], "edge1": [1, 0, 0],
                 "edge2": [0, 0, 1], "material": "lamp"}]})";
  EXPECT_EQ(render_log(write_file("lit.json", lit_text), "", &log), 0) << log;
  EXPECT_EQ(log.find("black"), std::string::npos) << log;
  // Light arrives, but the exposure hides it in the PNG.
  EXPECT_EQ(render_log("", "--exposure -20", &log), 0) << log;
  EXPECT_NE(log.find("black after the display transform (display.exposure -20"),
            std::string::npos) << log;
}

TEST(ObjEncoding, Utf16FilesAreNamedAsSuch) {
  // "v 0 0 0" in UTF-16 big endian with a byte-order mark, as assimp's box_UTF16BE.obj.
  std::string text = "\xFE\xFF";
  for (char c : std::string("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")) text += std::string(1, '\0') + c;
  const std::string path = write_file("utf16.obj", text);
  try {
    tracer::load_scene(path);
    FAIL() << "a UTF-16 OBJ loaded";
  } catch (const tracer::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("utf16.obj: the file is UTF-16"), std::string::npos)
        << e.what();
  }
}

TEST(Info, CountsEveryMaterialTypeAndShowsTheCamera) {
  const std::string scene = write_file("types.json", R"({
    "materials": {"a": {"type": "conductor", "roughness": 0.2}, "b": {"type": "conductor"},
                  "c": {"type": "subsurface"}, "d": {}, "e": {"type": "mirror"},
                  "f": {"type": "dielectric"}, "lamp": {"emission": [1, 1, 1]}},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "a"},
                {"type": "sphere", "center": [0, 3, 0], "radius": 1, "material": "lamp"}]})");
  std::string log;
  ASSERT_EQ(test::run_command(test::pathtracer_exe() + " info --json " + scene + " 2>/dev/null",
                              &log), 0) << log;
  const auto j = nlohmann::json::parse(log);
  EXPECT_EQ(j["materials"]["conductor"], 2);
  EXPECT_EQ(j["materials"]["subsurface"], 1);
  EXPECT_EQ(j["materials"]["diffuse"], 2);  // d and the lamp
  EXPECT_EQ(j["materials"]["mirror"], 1);
  EXPECT_EQ(j["materials"]["dielectric"], 1);
  EXPECT_EQ(j["materials"]["total"], 7);
  EXPECT_TRUE(j["camera"].contains("position"));
  ASSERT_EQ(test::run_command(test::pathtracer_exe() + " info " + scene, &log), 0) << log;
  EXPECT_NE(log.find("2 conductor, 1 subsurface"), std::string::npos) << log;
  EXPECT_NE(log.find("conductors, plastics and sheets"), std::string::npos) << log;
  EXPECT_NE(log.find("camera "), std::string::npos) << log;
}

}  // namespace
