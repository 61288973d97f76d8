// Renders lit by the environment and by distant lights: a convex diffuse object under a constant
// sky of radiance 1 renders its albedo (a furnace, with every estimator); importance-sampled maps
// render the mean that BSDF sampling alone renders (unbiased, both mappings, rotated); a plane
// under a sun renders rho E cos / pi; a sun of angular diameter 0 and a tiny one agree; shadow
// rays to the sky are blocked by a closed room's walls (the flat list keeps no hull then); and on
// the sunrise map MIS converges as 1/N and beats BSDF sampling by far more than 5x.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "scene/loader.h"
#include "scene_builders.h"
#include "test_util.h"

namespace {
using namespace test;
namespace fs = std::filesystem;

// A sphere of albedo rho at the origin (analytic, or a flat-faceted icosphere: both convex) seen
// from +z, under a constant environment.
Scene convex_under_sky(float rho, bool mesh, vec3 sky) {
  Scene s;
  s.source = "<convex under sky>";
  s.materials.push_back({"white", diffuse(vec3(rho))});
  if (mesh)
    add_icosphere(s.mesh, vec3(0.0f), 1.0f, 2, 0);
  else
    s.spheres.push_back({vec3(0.0f), 1.0f, 0});
  s.camera.position = vec3(0.0f, 0.0f, 3.2f);
  s.camera.look_at = vec3(0.0f);
  s.camera.vfov_deg = 50.0f;
  s.environment.color = sky;
  return s;
}

RenderSettings small_settings(int w, int h, bool nee, bool mis) {
  RenderSettings rs;
  rs.width = w;
  rs.height = h;
  rs.max_depth = 8;
  rs.nee = nee;
  rs.mis = mis;
  rs.jitter = false;            // each pixel is one direction: on the object or not
  rs.sampler = kSamplerRandom;  // independent samples for the z-tests
  return rs;
}

// Whether the centre ray of each pixel meets the scene.
std::vector<bool> hits(const Scene& s, const RenderSettings& rs) {
  const CompiledScene cs(s, rs.width, rs.height);
  std::vector<bool> out;
  for (int y = 0; y < rs.height; ++y)
    for (int x = 0; x < rs.width; ++x) {
      const Ray r = cs.view().camera.generate_ray(uint32_t(x), uint32_t(y), vec2(0.5f), vec2(0.5f));
      out.push_back(intersect_closest(cs.view(), r).valid());
    }
  return out;
}

// Every pixel and channel against its expected value (a z-test at an image-wide false-alarm rate
// of 1e-3, with a floor for the rounding of near-zero-variance estimates).
void expect_pixels(const PixelStats& ps, const std::vector<vec3>& expected,
                   const std::string& what) {
  EXPECT_EQ(ps.nonfinite, 0u) << what;
  const double zmax = sidak_z(1e-3, ps.mean.size() * 3);
  int failures = 0;
  for (size_t i = 0; i < ps.mean.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const double rounding = 1e-5 * (1.0 + expected[i][c]);
      const double se = std::sqrt(double(ps.var[i][c]) / ps.spp + rounding * rounding);
      const double z = (ps.mean[i][c] - expected[i][c]) / se;
      if (std::abs(z) > zmax && failures++ < 5)
        ADD_FAILURE() << what << ": pixel " << i << " channel " << c << " = " << ps.mean[i][c]
                      << ", expected " << expected[i][c] << " (z = " << z << ")";
    }
}

TEST(EnvLight, ConvexObjectUnderAConstantSkyRendersItsAlbedo) {
  const float rho = 0.5f;
  struct Mode {
    const char* name;
    bool nee, mis;
  };
  for (bool mesh : {false, true})
    for (const Mode& m :
         {Mode{"bsdf only", false, false}, Mode{"nee", true, false}, Mode{"nee+mis", true, true}}) {
      const Scene s = convex_under_sky(rho, mesh, vec3(1.0f));
      const RenderSettings rs = small_settings(12, 12, m.nee, m.mis);
      const std::vector<bool> on = hits(s, rs);
      std::vector<vec3> expected;
      for (bool h : on) expected.push_back(h ? vec3(rho) : vec3(1.0f));
      expect_pixels(render_pixel_stats(s, rs, 1024), expected,
                    std::string(mesh ? "icosphere " : "sphere ") + m.name);
    }
}

TEST(EnvLight, HiddenSkyStillLightsAndStrengthScales) {
  Scene s = convex_under_sky(0.5f, false, vec3(0.5f, 1.0f, 1.5f));
  s.environment.strength = 2.0f;
  s.environment.visible = false;
  s.environment.background = vec3(0.1f, 0.2f, 0.3f);
  const RenderSettings rs = small_settings(10, 10, true, true);
  const std::vector<bool> on = hits(s, rs);
  std::vector<vec3> expected;
  for (bool h : on)
    expected.push_back(h ? 0.5f * 2.0f * vec3(0.5f, 1.0f, 1.5f) : vec3(0.1f, 0.2f, 0.3f));
  expect_pixels(render_pixel_stats(s, rs, 1024), expected, "hidden sky, strength 2");
}

// A PFM map of a sky with a small bright sun (w x h, equirectangular or, when square, octahedral).
std::string sky_map(int w, int h, const std::string& name) {
  const std::string path = testing::TempDir() + "/envlight_" + name + ".pfm";
  std::ofstream f(path, std::ios::binary);
  f << "PF\n" << w << " " << h << "\n-1\n";
  for (int y = h - 1; y >= 0; --y)  // bottom row first
    for (int x = 0; x < w; ++x) {
      vec3 c = y < h / 2 ? vec3(0.3f, 0.5f, 0.9f) * (1.0f + 0.5f * float(x) / float(w))
                         : vec3(0.3f, 0.25f, 0.2f);
      if (x >= w / 3 && x < w / 3 + 2 && y >= h / 4 && y < h / 4 + 2) c = vec3(60.0f, 55.0f, 50.0f);
      f.write(reinterpret_cast<const char*>(&c), 12);
    }
  return path;
}

// Spheres (diffuse, rough conductor) on a ground quad under a map.
Scene map_scene(const std::string& map, EnvMapping mapping, float rotation) {
  Scene s;
  s.source = "<map scene>";
  s.materials.push_back({"ground", diffuse(vec3(0.5f))});
  s.materials.push_back({"clay", diffuse(vec3(0.8f, 0.4f, 0.3f))});
  Material metal;
  metal.type = MaterialType::kConductor;
  metal.albedo = vec3(0.9f, 0.8f, 0.5f);
  metal.roughness = 0.5f;
  s.materials.push_back({"metal", metal});
  add_quad(s.mesh, vec3(-6, 0, 6), vec3(12, 0, 0), vec3(0, 0, -12), 0);
  s.spheres.push_back({vec3(-0.9f, 0.8f, 0.0f), 0.8f, 1});
  s.spheres.push_back({vec3(0.9f, 0.8f, 0.0f), 0.8f, 2});
  s.camera.position = vec3(0.0f, 2.0f, 5.0f);
  s.camera.look_at = vec3(0.0f, 0.6f, 0.0f);
  s.camera.vfov_deg = 45.0f;
  s.environment.file = map;
  s.environment.mapping = mapping;
  s.environment.rotation_deg = rotation;
  EXPECT_EQ(refresh_environment(s), "");
  return s;
}

TEST(EnvLight, ImportanceSamplingIsUnbiased) {
  struct Case {
    const char* name;
    int w, h;
    EnvMapping mapping;
    float rotation;
  };
  for (const Case& c : {Case{"equirect", 64, 32, EnvMapping::kEquirect, 0.0f},
                        Case{"equirect rotated", 64, 32, EnvMapping::kEquirect, 75.0f},
                        Case{"octahedral", 48, 48, EnvMapping::kOctahedral, -30.0f}}) {
    const Scene s = map_scene(sky_map(c.w, c.h, c.name), c.mapping, c.rotation);
    RenderSettings rs = small_settings(32, 24, true, true);
    rs.jitter = true;
    const PixelStats mis = render_pixel_stats(s, rs, 256);
    rs.mis = false;  // light sampling alone for what NEE can reach
    const PixelStats nee = render_pixel_stats(s, rs, 256, 1u << 20);
    rs.nee = false;  // BSDF sampling alone: the map is only found by escaping rays
    const PixelStats bsdf = render_pixel_stats(s, rs, 2048, 1u << 21);
    expect_same_means(mis, bsdf, std::string(c.name) + ": MIS vs BSDF sampling");
    expect_same_means(nee, bsdf, std::string(c.name) + ": NEE vs BSDF sampling");
  }
}

// A ground plane of albedo rho filling the view under a sun of irradiance E, elevation 50 deg.
Scene plane_under_sun(float diameter) {
  Scene s;
  s.source = "<plane under sun>";
  s.materials.push_back({"ground", diffuse(vec3(0.6f))});
  add_quad(s.mesh, vec3(-50, 0, 50), vec3(100, 0, 0), vec3(0, 0, -100), 0);
  s.camera.position = vec3(0.0f, 3.0f, 0.0f);
  s.camera.look_at = vec3(0.0f, 0.0f, -0.5f);
  s.camera.vfov_deg = 40.0f;
  DistantLightDesc sun;
  const float e = glm::radians(50.0f);
  sun.direction = vec3(std::cos(e), std::sin(e), 0.3f * std::cos(e));
  sun.irradiance = vec3(3.0f, 2.5f, 2.0f);
  sun.angular_diameter_deg = diameter;
  s.distant_lights.push_back(sun);
  return s;
}

TEST(EnvLight, PlaneUnderASunRendersRhoECosOverPi) {
  for (float diameter : {0.0f, 0.53f, 5.0f}) {
    const Scene s = plane_under_sun(diameter);
    const vec3 dir = glm::normalize(s.distant_lights[0].direction);
    // A cone's irradiance on a plane tilted from its axis is E cos(axis) exactly while the cone
    // stays above the horizon (the mean cosine over a uniform disc is the axis' cosine).
    const vec3 expected = 0.6f * s.distant_lights[0].irradiance * dir.y / kPi;
    const RenderSettings rs = small_settings(8, 8, true, true);
    const PixelStats ps = render_pixel_stats(s, rs, 256);
    expect_pixels(ps, std::vector<vec3>(ps.mean.size(), expected),
                  "sun of diameter " + std::to_string(diameter));
  }
  // Without next-event estimation a delta sun is never found (a direction has no area).
  const RenderSettings no_nee = small_settings(4, 4, false, false);
  EXPECT_EQ(render_pixel_stats(plane_under_sun(0.0f), no_nee, 16).image_mean(), vec3(0.0f));
}

TEST(EnvLight, DeltaSunAndTinySunConvergeToTheSameImage) {
  auto scene = [](float diameter) {
    Scene s = plane_under_sun(diameter);
    s.materials.push_back({"clay", diffuse(vec3(0.8f, 0.5f, 0.3f))});
    s.spheres.push_back({vec3(0.0f, 0.5f, -2.0f), 0.5f, 1});
    s.camera.position = vec3(0.0f, 2.0f, 2.0f);
    s.camera.look_at = vec3(0.0f, 0.3f, -2.0f);
    s.camera.vfov_deg = 50.0f;
    return s;
  };
  RenderSettings rs = small_settings(32, 24, true, true);
  rs.jitter = true;
  const PixelStats delta = render_pixel_stats(scene(0.0f), rs, 512);
  const PixelStats tiny = render_pixel_stats(scene(0.1f), rs, 512, 1u << 20);
  // A 0.1 degree sun softens shadow edges by a thousandth of the distance to the caster, far
  // below a pixel here: the images agree within their noise.
  expect_same_means(delta, tiny, "delta sun vs 0.1 degree sun");
}

TEST(EnvLight, ClosedRoomBlocksTheSkyOnEveryTraversal) {
  // cornell_closed.json has a fourth wall: no path reaches the sky, so a sky outside changes
  // nothing, with the flat list (whose hull entries shadow rays to the sky must not skip) and
  // with the BVH.
  Scene room = load_scene(source_dir() + "/assets/scenes/cornell_closed.json");
  Scene sky = room;
  sky.environment.color = vec3(50.0f);
  RenderSettings rs = room.settings;
  rs.width = 24;
  rs.height = 24;
  rs.sampler = kSamplerRandom;
  const CompiledScene a(room, rs.width, rs.height), b(sky, rs.width, rs.height);
  ASSERT_TRUE(b.flat_list().enabled);
  EXPECT_EQ(b.flat_list().box_faces, 0u) << "no entry may be on the hull";
  EXPECT_GT(a.flat_list().box_faces, 0u) << "without the sky the walls are box faces";
  // The GPU's shadow queries over the flat list (shadow_blocked, flat_closest_and_any) skip the
  // hull for rays between two points of the scene; a ray to the sky leaves through it.
  {
    SceneView v = b.view();
    v.use_flat = 1;
    Pcg32 rng = make_path_rng(1, 2, 3, 4);
    for (int i = 0; i < 2000; ++i) {
      Ray r;
      r.o = vec3(50.0f + 450.0f * rng.next_float(), 20.0f + 500.0f * rng.next_float(),
                 -500.0f + 1000.0f * rng.next_float());
      r.d = sample_uniform_sphere(rng.next_2d());
      r.tmax = kInfinity;
      r.pad = 0.0f;
      const Hit closest = intersect_closest(v, r);
      if (!closest.valid()) continue;  // the point is outside the room (behind the camera wall)
      ASSERT_TRUE(shadow_blocked<kAllFeatures>(v, r, kInvalid)) << "ray " << i;
      bool blocked = false;
      Ray none = r;
      none.tmax = 0.0f;
      flat_closest_and_any<kAllFeatures>(v, none, kInvalid, r, kInvalid, kInvalid, blocked);
      ASSERT_TRUE(blocked) << "ray " << i;
    }
  }
  const IntegratorSettings cfg = make_integrator_settings(rs);
  for (uint32_t flat : {0u, 1u}) {
    SceneView va = a.view(), vb = b.view();
    va.use_flat = vb.use_flat = flat;
    double sa = 0, sb = 0;
    for (uint32_t p = 0; p < uint32_t(rs.width * rs.height); ++p)
      for (uint32_t k = 0; k < 64; ++k) {
        sa += luminance(trace_path(va, cfg, p, k));
        sb += luminance(trace_path(vb, cfg, p, k + 4096));
      }
    // The sky would add tens of units of radiance per pixel through any gap; noise is ~1%.
    EXPECT_NEAR(sb / sa, 1.0, 0.05) << (flat ? "flat list" : "BVH");
  }
}

// The sunrise map through `bench --error`: MIS converges as 1/N (random sampler, independent
// samples) and reaches an error more than 5x sooner than BSDF sampling alone (both measured
// against the same high-sample reference).
TEST(EnvLight, MisOnTheSunriseMapConvergesAndBeatsBsdfSampling) {
  const std::string map = std::string(kBlenderWorlds) + "/sunrise.exr";
  if (!fs::exists(map)) GTEST_SKIP() << map << " is absent (Debian package blender-data)";
  const std::string dir = testing::TempDir() + "/envlight_bench";
  fs::create_directories(dir);
  // Diffuse spheres on a ground, the sun (32,000 times the sky's radiance, 1 texel) behind the
  // camera, out of view: a visible sun makes its pixels' error pre-asymptotic for hundreds of
  // samples, and glossy surfaces add heavy tails of their own; neither is what is tested here.
  nlohmann::json scene = {
      {"camera", {{"position", {0, 1.6, 7}}, {"look_at", {0, 0.8, 0}}, {"vfov", 35}}},
      {"render", {{"width", 64}, {"height", 48}, {"max_depth", 4}}},
      {"environment", {{"file", map}, {"mapping", "equirect"}}},
      {"materials",
       {{"ground", {{"albedo", {0.45, 0.42, 0.38}}}}, {"clay", {{"albedo", {0.8, 0.3, 0.2}}}}}},
      {"objects",
       {{{"type", "quad"},
         {"corner", {-20, 0, 20}},
         {"edge1", {40, 0, 0}},
         {"edge2", {0, 0, -40}},
         {"material", "ground"}},
        {{"type", "sphere"}, {"center", {-1.2, 0.8, 0}}, {"radius", 0.8}, {"material", "clay"}},
        {{"type", "sphere"}, {"center", {1.2, 0.8, 0}}, {"radius", 0.8}, {"material", "clay"}}}}};
  const std::string path = dir + "/sunrise_diffuse.json";
  std::ofstream(path) << scene.dump(2);
  std::string log;
  const std::string cmd = pathtracer_exe() + " bench --error " + path +
                          " --backend cpu --reference-spp 4096 --max-spp 256 --flip off"
                          " --configs cpu+sampler=random,cpu+nee=off+sampler=random --out " +
                          dir;
  ASSERT_EQ(run_command(cmd, &log), 0) << log;
  std::printf("%s", log.c_str());
  std::ifstream f(dir + "/bench.json");
  const auto j = nlohmann::json::parse(f);
  const auto& mis = j["configs"][0];
  const auto& bsdf = j["configs"][1];
  EXPECT_FALSE(mis["biased"].get<bool>()) << mis["verdict"];
  EXPECT_NEAR(mis["slope"].get<double>(), -1.0, 0.15) << mis["verdict"];
  EXPECT_FALSE(bsdf["biased"].get<bool>()) << bsdf["verdict"];
  const double ratio = mis["efficiency"].get<double>() / bsdf["efficiency"].get<double>();
  std::printf("MIS is %.0fx as efficient as BSDF sampling (1 / (relMSE x time))\n", ratio);
  EXPECT_GT(ratio, 5.0);
}

}  // namespace
