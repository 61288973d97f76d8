// The feature buffers (integrator/aov.h) on analytic scenes, their export (EXR layers, PNGs
// beside, the sidecar) and the denoiser (image/denoise.h), which skips with the reason where
// Open Image Denoise is absent.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "cpu/cpu_backend.h"
#include "image/denoise.h"
#include "integrator/aov.h"
#include "integrator/export.h"
#include "scene/compiled_scene.h"
#include "scene/loader.h"
#include "scene_builders.h"
#include "test_util.h"

namespace tracer {
namespace {
using namespace test;

constexpr vec3 kPlaneAlbedo(0.7f, 0.5f, 0.3f);

// A diffuse plane z = 0 filling the view of a camera on the +z axis at distance 5.
Scene plane_scene() {
  Scene s;
  s.materials.push_back({"plane", diffuse(kPlaneAlbedo)});
  add_quad(s.mesh, vec3(-20.0f, -20.0f, 0.0f), vec3(40.0f, 0.0f, 0.0f), vec3(0.0f, 40.0f, 0.0f), 0);
  s.camera.position = vec3(0.0f, 0.0f, 5.0f);
  s.camera.look_at = vec3(0.0f);
  s.camera.vfov_deg = 20.0f;
  return s;
}

// The camera looks down -z at a mirror in the plane y + z = 0 (normal (0, 1, 1)/sqrt 2), which
// sends every ray up (+y) to a diffuse ceiling y = 3 of another colour.
constexpr vec3 kCeilingAlbedo(0.2f, 0.6f, 0.9f);
Scene mirror_scene() {
  Scene s;
  Material mirror;
  mirror.type = MaterialType::kMirror;
  mirror.albedo = vec3(0.9f);
  s.materials.push_back({"mirror", mirror});
  s.materials.push_back({"ceiling", diffuse(kCeilingAlbedo)});
  add_quad(s.mesh, vec3(-5.0f, -2.0f, 2.0f), vec3(10.0f, 0.0f, 0.0f), vec3(0.0f, 4.0f, -4.0f), 0);
  add_quad(s.mesh, vec3(-20.0f, 3.0f, -20.0f), vec3(40.0f, 0.0f, 0.0f), vec3(0.0f, 0.0f, 40.0f), 1);
  s.camera.position = vec3(0.0f, 0.0f, 5.0f);
  s.camera.look_at = vec3(0.0f);
  s.camera.vfov_deg = 10.0f;
  return s;
}

AovImages render_aovs(const Scene& scene, int w, int h, uint32_t spp, CpuRenderer* r = nullptr) {
  CpuRenderer local(2);
  CpuRenderer& rr = r ? *r : local;
  const CompiledScene cs(scene, w, h);
  RenderSettings rs;
  rs.width = w;
  rs.height = h;
  rr.set_scene(cs, make_integrator_settings(rs));
  rr.set_aovs(true);
  rr.render(spp);
  return rr.aov_images();
}

TEST(Aov, DiffusePlaneGivesItsAlbedoNormalAndDistance) {
  const AovImages a = render_aovs(plane_scene(), 16, 16, 4);
  ASSERT_FALSE(a.empty());
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) {
      const vec3 al = a.albedo.at(x, y), n = a.normal.at(x, y);
      EXPECT_NEAR(al.x, kPlaneAlbedo.x, 1e-6f);
      EXPECT_NEAR(al.y, kPlaneAlbedo.y, 1e-6f);
      EXPECT_NEAR(al.z, kPlaneAlbedo.z, 1e-6f);
      EXPECT_NEAR(n.x, 0.0f, 1e-6f);
      EXPECT_NEAR(n.y, 0.0f, 1e-6f);
      EXPECT_NEAR(n.z, 1.0f, 1e-6f);  // facing the camera
      // The distance along each camera ray: 5 / cos(angle to the axis), at most 10 degrees off.
      const float d = a.depth[size_t(y) * 16 + x];
      EXPECT_GE(d, 5.0f * 0.9999f);
      EXPECT_LE(d, 5.0f / std::cos(glm::radians(15.0f)));
      EXPECT_EQ(a.material[size_t(y) * 16 + x], 0u);
      EXPECT_LT(a.prim[size_t(y) * 16 + x], 2u);  // one of the quad's two triangles
    }
  }
  EXPECT_NEAR(a.depth[8 * 16 + 8], 5.0f, 0.01f);  // near the axis
}

TEST(Aov, ThroughAMirrorTheyAreTheMirroredObjects) {
  const AovImages a = render_aovs(mirror_scene(), 12, 12, 4);
  ASSERT_FALSE(a.empty());
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 12; ++x) {
      const vec3 al = a.albedo.at(x, y), n = a.normal.at(x, y);
      EXPECT_NEAR(al.x, kCeilingAlbedo.x, 1e-6f);
      EXPECT_NEAR(al.y, kCeilingAlbedo.y, 1e-6f);
      EXPECT_NEAR(al.z, kCeilingAlbedo.z, 1e-6f);
      EXPECT_NEAR(n.y, -1.0f, 1e-5f);  // the ceiling's normal, facing the reflected ray
      EXPECT_EQ(a.material[size_t(y) * 12 + x], 1u);
      // The distance is the camera ray's, to the mirror: 5 / (cos t - sin t) for a ray t off the
      // axis towards +y, at most 5 degrees: 4.6 to 5.5.
      EXPECT_NEAR(a.depth[size_t(y) * 12 + x], 5.0f, 0.6f);
    }
  }
}

TEST(Aov, EscapedRaysGiveZerosAndNoIds) {
  Scene s = plane_scene();
  s.camera.position = vec3(0.0f, 0.0f, -5.0f);  // behind the plane, looking away from it
  s.camera.look_at = vec3(0.0f, 0.0f, -10.0f);
  const AovImages a = render_aovs(s, 8, 8, 2);
  ASSERT_FALSE(a.empty());
  for (size_t i = 0; i < a.depth.size(); ++i) {
    EXPECT_EQ(a.depth[i], 0.0f);
    EXPECT_EQ(a.material[i], kInvalid);
    EXPECT_EQ(a.albedo.pixels[3 * i], 0.0f);
    EXPECT_EQ(a.normal.pixels[3 * i + 2], 0.0f);
  }
}

TEST(Aov, TurningThemOnKeepsTheColourAndHalvesAddUp) {
  Scene s = builtin_default_scene();
  CpuRenderer r(2);
  const CompiledScene cs(s, 16, 12);
  RenderSettings rs;
  rs.width = 16;
  rs.height = 12;
  r.set_scene(cs, make_integrator_settings(rs));
  EXPECT_TRUE(r.aov_images().empty());  // off by default
  r.render(3);
  const ImageRGB before = r.image();
  r.set_aovs(true);
  EXPECT_EQ(r.samples_done(), 3u);  // the colour is kept
  EXPECT_EQ(r.image().pixels, before.pixels);
  EXPECT_EQ(r.aov_samples(), 0u);
  EXPECT_TRUE(r.aov_images().empty());
  r.render(3);  // samples 3, 4, 5: two odd, one even
  EXPECT_EQ(r.samples_done(), 6u);
  EXPECT_EQ(r.aov_samples(), 3u);
  const AovImages all = r.aov_images(), even = r.aov_images(0), odd = r.aov_images(1);
  ASSERT_FALSE(all.empty());
  for (size_t i = 0; i < all.depth.size(); ++i)
    EXPECT_NEAR(all.depth[i], (1.0f * even.depth[i] + 2.0f * odd.depth[i]) / 3.0f,
                1e-4f * (1.0f + all.depth[i]));
  r.reset();
  EXPECT_TRUE(r.aovs());
  EXPECT_EQ(r.aov_samples(), 0u);
  r.set_aovs(false);
  r.render(1);
  EXPECT_TRUE(r.aov_images().empty());
}

TEST(Aov, TheyLineUpWithThePathsGlassChoices) {
  // A smooth glass slab in front of the plane: each AOV sample follows the reflection or the
  // refraction its path chooses, so over many samples the albedo is a mix of the plane's (through
  // the glass) and nothing (reflected into the empty sky), weighted by the Fresnel reflectance.
  Scene s = plane_scene();
  Material glass;
  glass.type = MaterialType::kDielectric;
  glass.ior = 1.5f;
  s.materials.push_back({"glass", glass});
  add_box(s.mesh, vec3(-20.0f, -20.0f, 1.0f), vec3(20.0f, 20.0f, 1.5f), 1);
  const AovImages a = render_aovs(s, 4, 4, 256);
  ASSERT_FALSE(a.empty());
  // Normal incidence into and out of the slab: R = 0.04 at each face; the plane's albedo is
  // seen through both faces with probability (1 - R)^2 (internal reflections bounce back to the
  // plane after more segments: they count the plane too, a little, through max_depth 8).
  const float seen = a.albedo.at(2, 2).x / kPlaneAlbedo.x;
  EXPECT_GT(seen, 0.85f);
  EXPECT_LT(seen, 0.99f);
}

TEST(Aov, ExportWritesLayersPngsAndTheSidecar) {
  const std::string dir = ::testing::TempDir() + "aov_export";
  std::filesystem::remove_all(dir);
  Scene s = plane_scene();
  s.source = "<test>";
  CpuRenderer r(2);
  const AovImages a = render_aovs(s, 8, 6, 2, &r);
  AovRequest req;
  std::string problem;
  ASSERT_TRUE(parse_aov_list("albedo, depth,id", &req, &problem)) << problem;
  EXPECT_TRUE(req.albedo && req.depth && req.id && !req.normal);
  EXPECT_FALSE(parse_aov_list("albedo,normals", &req, &problem));
  EXPECT_NE(problem.find("normals"), std::string::npos);
  ASSERT_TRUE(parse_aov_list("all", &req, &problem));

  const ExportResult exr = export_render(dir + "/x.exr", r.image(), &a, req, s, SidecarRun());
  std::ifstream f(dir + "/x.exr", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  for (const char* name : {"albedo.R", "normal.Z", "depth.Z", "id.material", "id.object"})
    EXPECT_NE(bytes.find(std::string(name) + '\0'), std::string::npos) << name;
  const ImageRGB back = read_image(dir + "/x.exr");  // R, G, B are the colour
  EXPECT_EQ(back.pixels, r.image().pixels);
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.albedo.png"));  // layers, not PNGs

  export_render(dir + "/y.png", r.image(), &a, req, s, SidecarRun());
  for (const char* name : {"albedo", "normal", "depth", "id"})
    EXPECT_TRUE(std::filesystem::exists(dir + "/y." + name + ".png")) << name;
  const ImageRGB albedo_png = read_image(dir + "/y.albedo.png");
  EXPECT_NEAR(albedo_png.at(3, 3).x, kPlaneAlbedo.x, 0.01f);
  std::ifstream side(dir + "/y.png.json");
  const nlohmann::json j = nlohmann::json::parse(side);
  EXPECT_EQ(j["aovs"]["layers"].size(), 4u);
  EXPECT_FALSE(j.contains("denoise"));
  EXPECT_EQ(aov_png_path("a/b.c/x.exr", "depth"), "a/b.c/x.depth.png");
  EXPECT_EQ(denoised_path("out/x.png"), "out/x.denoised.png");
}

TEST(Aov, ExportWithoutTheDenoiserFailsBeforeWritingAnything) {
  if (denoiser_available()) GTEST_SKIP() << "the denoiser is present: " << denoiser_status();
  const std::string dir = ::testing::TempDir() + "aov_nodenoise";
  std::filesystem::remove_all(dir);
  Scene s = plane_scene();
  s.display.denoise = DenoiseMode::kBoth;
  CpuRenderer r(2);
  const AovImages a = render_aovs(s, 8, 6, 2, &r);
  EXPECT_THROW(export_render(dir + "/x.png", r.image(), &a, AovRequest(), s, SidecarRun()),
               std::exception);
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.png"));
}

// ---- The denoiser (skips where Open Image Denoise is absent) ----------------------------------

#define REQUIRE_DENOISER() \
  if (!denoiser_available()) GTEST_SKIP() << "denoiser absent: " << denoiser_status()

TEST(Denoise, KeepsAFlatImageFlatAndAnEdgeSharp) {
  REQUIRE_DENOISER();
  const int w = 64, h = 64;
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 0.15f);
  ImageRGB color = make_image(w, h), albedo = make_image(w, h), normal = make_image(w, h);
  double noisy_err = 0.0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      // Left half dark grey, right half light: the albedo shows the edge without noise.
      const float truth = x < w / 2 ? 0.1f : 0.8f;
      const float v = std::max(0.0f, truth + noise(rng));
      color.set(x, y, vec3(v));
      albedo.set(x, y, vec3(truth));
      normal.set(x, y, vec3(0.0f, 0.0f, 1.0f));
      noisy_err += double(v - truth) * (v - truth);
    }
  }
  DenoiseInfo info;
  const ImageRGB out = denoise_image(color, &albedo, &normal, &info);
  EXPECT_EQ(info.inputs, "color+albedo+normal");
  EXPECT_FALSE(info.denoiser.empty());
  double err = 0.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float truth = x < w / 2 ? 0.1f : 0.8f;
      const float v = out.at(x, y).x;
      err += double(v - truth) * (v - truth);
    }
  EXPECT_LT(err, 0.1 * noisy_err);  // at least 10x less squared error
  // The edge stays an edge: the columns beside it keep their sides' levels.
  for (int y = 8; y < h - 8; y += 8) {
    EXPECT_NEAR(out.at(w / 2 - 2, y).x, 0.1f, 0.05f) << y;
    EXPECT_NEAR(out.at(w / 2 + 1, y).x, 0.8f, 0.1f) << y;
  }
}

TEST(Denoise, ARenderDenoisedIsCloserToTheReference) {
  REQUIRE_DENOISER();
  const Scene s = builtin_default_scene();
  const CompiledScene cs(s, 48, 48);
  RenderSettings rs;
  rs.width = 48;
  rs.height = 48;
  CpuRenderer r(2);
  r.set_scene(cs, make_integrator_settings(rs));
  r.render(512);
  const ImageRGB ref = r.image();
  IntegratorSettings cfg = make_integrator_settings(rs);
  cfg.seed = 99;
  r.set_settings(cfg);
  r.set_aovs(true);
  r.render(4);
  const AovImages a = r.aov_images();
  const ImageRGB raw = r.image();
  const ImageRGB den = denoise_image(raw, &a.albedo, &a.normal);
  const double e_raw = compare_images(raw, ref).relmse, e_den = compare_images(den, ref).relmse;
  EXPECT_LT(e_den, 0.5 * e_raw) << "raw " << e_raw << ", denoised " << e_den;
}

TEST(Denoise, CliWritesBothImagesAndRecordsTheDenoiser) {
  REQUIRE_DENOISER();
  const std::string dir = ::testing::TempDir() + "cli_denoise";
  std::filesystem::remove_all(dir);
  std::string log;
  ASSERT_EQ(run_command(pathtracer_exe() +
                            " render --spp 4 --width 32 --height 24 --backend cpu --denoise both "
                            "--aov albedo --out " + dir + "/x.png",
                        &log),
            0)
      << log;
  EXPECT_TRUE(std::filesystem::exists(dir + "/x.png"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/x.denoised.png"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/x.albedo.png"));
  std::ifstream side(dir + "/x.png.json");
  const nlohmann::json j = nlohmann::json::parse(side);
  ASSERT_TRUE(j.contains("denoise")) << j.dump();
  EXPECT_EQ(j["denoise"]["inputs"], "color+albedo+normal");
  EXPECT_EQ(j["denoise"]["output"], dir + "/x.denoised.png");
  EXPECT_NE(log.find("biased"), std::string::npos) << log;
}

TEST(Denoise, AnAbsentLibraryStopsTheRenderBeforeItStarts) {
  const std::string out = ::testing::TempDir() + "no_oidn/x.png";
  std::filesystem::remove_all(::testing::TempDir() + "no_oidn");
  std::string log;
  EXPECT_NE(run_command("TRACER_OIDN_LIBRARY=/nonexistent/oidn " + pathtracer_exe() +
                            " render --spp 1 --width 16 --height 16 --backend cpu --denoise on "
                            "--out " + out,
                        &log),
            0);
  EXPECT_NE(log.find("denoiser is absent"), std::string::npos) << log;
  EXPECT_NE(log.find("/nonexistent/oidn/libOpenImageDenoise.so.2"), std::string::npos) << log;
  EXPECT_NE(log.find("nothing was rendered"), std::string::npos) << log;
  EXPECT_FALSE(std::filesystem::exists(out));
}

TEST(Aov, CliChecksTheList) {
  std::string log;
  EXPECT_NE(run_command(pathtracer_exe() + " render --spp 1 --aov albedo,shiny --out " +
                            ::testing::TempDir() + "bad.png",
                        &log),
            0);
  EXPECT_NE(log.find("shiny"), std::string::npos) << log;
  EXPECT_NE(run_command(pathtracer_exe() + " render --spp 1 --aov-png --out " +
                            ::testing::TempDir() + "bad.exr",
                        &log),
            0);
  EXPECT_NE(log.find("--aov-png needs --aov"), std::string::npos) << log;
}

}  // namespace
}  // namespace tracer
