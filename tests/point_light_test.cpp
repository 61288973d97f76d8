// Point and spot lights: a diffuse plane under a point light renders rho I cos / (pi d^2) in every
// pixel, and under a spot light pbrt-v4's smooth-step falloff across the cone's edge; a point
// light at the centre of a closed diffuse sphere renders the furnace's rho I / (pi R^2 (1 - rho));
// lights are chosen by flux; the flat list keeps a wall with a light behind it as a blocker;
// scenes lit only by delta lights are lit; the scene format's point, spot and disk entries with
// their errors; lights.NAME.FIELD edits, the "lights" written back, and the workbench.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "image/image.h"
#include "integrator/black_image.h"
#include "scene/loader.h"
#include "scene_builders.h"
#include "test_util.h"
#include "ui/workbench.h"

namespace {
using namespace test;

RenderSettings settings(int w, int h) {
  RenderSettings rs;
  rs.width = w;
  rs.height = h;
  rs.max_depth = 8;
  rs.jitter = false;            // each pixel is one point of the plane
  rs.sampler = kSamplerRandom;  // independent samples for the z-tests
  return rs;
}

// A ground plane of albedo rho (y = 0, facing up) filling the view of a camera looking down.
Scene plane(float rho) {
  Scene s;
  s.source = "<plane>";
  s.materials.push_back({"ground", diffuse(vec3(rho))});
  add_quad(s.mesh, vec3(-50, 0, 50), vec3(100, 0, 0), vec3(0, 0, -100), 0);
  s.camera.position = vec3(0.2f, 4.0f, 0.3f);
  s.camera.look_at = vec3(0.0f, 0.0f, 0.0f);
  s.camera.up = vec3(0.0f, 0.0f, -1.0f);
  s.camera.vfov_deg = 60.0f;
  return s;
}

PointLightDesc point(vec3 p, vec3 i) {
  PointLightDesc d;
  d.name = "point";
  d.position = p;
  d.intensity = i;
  return d;
}

PointLightDesc spot(vec3 p, vec3 dir, vec3 i, float cone, float delta) {
  PointLightDesc d = point(p, i);
  d.name = "spot";
  d.spot = true;
  d.direction = dir;
  d.cone_angle_deg = cone;
  d.cone_delta_angle_deg = delta;
  return d;
}

// pbrt-v4's spot falloff, written out in double: smoothstep(cos, cos end, cos start).
double pbrt_falloff(const PointLightDesc& d, glm::dvec3 w) {
  if (!d.spot) return 1.0;
  const double c = glm::dot(w, glm::normalize(glm::dvec3(d.direction)));
  const double ce = std::cos(glm::radians(double(d.cone_angle_deg)));
  const double cs = std::cos(glm::radians(double(d.cone_angle_deg - d.cone_delta_angle_deg)));
  if (cs == ce) return c < ce ? 0.0 : 1.0;
  const double t = glm::clamp((c - ce) / (cs - ce), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Each pixel's radiance: the plane point its centre ray meets, lit directly by every light,
// rho / pi * I falloff cos(theta) / d^2 (nothing else is there to reflect light).
std::vector<vec3> expected_plane(const Scene& s, const RenderSettings& rs, float rho) {
  const CompiledScene cs(s, rs.width, rs.height);
  std::vector<vec3> out;
  for (int y = 0; y < rs.height; ++y)
    for (int x = 0; x < rs.width; ++x) {
      const Ray r = cs.view().camera.generate_ray(uint32_t(x), uint32_t(y), vec2(0.5f), vec2(0.5f));
      const Hit hit = intersect_closest(cs.view(), r);
      EXPECT_TRUE(hit.valid());
      const glm::dvec3 p = glm::dvec3(r.o) + double(hit.t) * glm::dvec3(r.d);
      glm::dvec3 sum(0.0);
      for (const PointLightDesc& d : s.point_lights) {
        const glm::dvec3 to_p = p - glm::dvec3(d.position);
        const double dist = glm::length(to_p);
        const double cos_t = std::max(0.0, -to_p.y / dist);
        sum += double(rho) / M_PI * glm::dvec3(d.intensity) * pbrt_falloff(d, to_p / dist) * cos_t /
               (dist * dist);
      }
      out.push_back(vec3(sum));
    }
  return out;
}

// Every pixel and channel against its expected value: a z-test at an image-wide false-alarm
// rate of 1e-3, with a floor for float rounding (a single light's estimate has no variance; the
// falloff's smooth step of float cosines is good to about 1e-5 of the light's peak).
void expect_pixels(const PixelStats& ps, const std::vector<vec3>& expected,
                   const std::string& what) {
  EXPECT_EQ(ps.nonfinite, 0u) << what;
  const double zmax = sidak_z(1e-3, ps.mean.size() * 3);
  float peak = 0.0f;
  for (const vec3& e : expected) peak = std::max(peak, max_component(e));
  int failures = 0;
  for (size_t i = 0; i < ps.mean.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const double rounding = 2e-5 * expected[i][c] + 1e-5 * peak;
      const double se = std::sqrt(double(ps.var[i][c]) / ps.spp + rounding * rounding);
      const double z = (ps.mean[i][c] - expected[i][c]) / se;
      if (std::abs(z) > zmax && failures++ < 5)
        ADD_FAILURE() << what << ": pixel " << i << " channel " << c << " = " << ps.mean[i][c]
                      << ", expected " << expected[i][c] << " (z = " << z << ")";
    }
}

TEST(PointLight, PlaneRendersRhoICosOverPiD2) {
  Scene s = plane(0.6f);
  s.point_lights.push_back(point(vec3(0.3f, 1.5f, -0.2f), vec3(3.0f, 2.0f, 1.0f)));
  const RenderSettings rs = settings(12, 12);
  for (const bool mis : {true, false}) {
    RenderSettings r = rs;
    r.mis = mis;  // a delta light is never weighted: MIS changes nothing
    expect_pixels(render_pixel_stats(s, r, 4), expected_plane(s, rs, 0.6f),
                  mis ? "one point light" : "one point light, no MIS");
  }
  // Two lights: each sample chooses one by flux; the mean is their sum.
  s.point_lights.push_back(point(vec3(-1.0f, 0.7f, 0.5f), vec3(0.5f, 1.0f, 2.0f)));
  expect_pixels(render_pixel_stats(s, rs, 512), expected_plane(s, rs, 0.6f), "two point lights");
  // Without next-event estimation nothing finds a point light.
  RenderSettings no_nee = settings(4, 4);
  no_nee.nee = false;
  EXPECT_EQ(render_pixel_stats(s, no_nee, 8).image_mean(), vec3(0.0f));
}

TEST(SpotLight, FalloffMatchesPbrtAcrossTheCone) {
  // The profile itself: full inside cone - delta, none beyond cone, the smooth step between.
  const PointLightDesc d = spot(vec3(0.0f), vec3(0, -2, 0), vec3(1.0f), 30.0f, 10.0f);
  const PointLight pl = make_point_light(d);
  auto at = [&](double deg) {
    const double a = glm::radians(deg);
    return point_light_intensity(pl, vec3(float(std::sin(a)), float(-std::cos(a)), 0.0f)).x;
  };
  EXPECT_FLOAT_EQ(at(0.0), 1.0f);
  EXPECT_FLOAT_EQ(at(19.9), 1.0f);
  EXPECT_FLOAT_EQ(at(30.1), 0.0f);
  EXPECT_FLOAT_EQ(at(120.0), 0.0f);
  for (double deg = 20.0; deg <= 30.0; deg += 0.5) {
    const double a = glm::radians(deg);
    EXPECT_NEAR(at(deg), pbrt_falloff(d, glm::dvec3(std::sin(a), -std::cos(a), 0.0)), 2e-5) << deg;
  }
  // cos halfway between the two cosines: the smooth step's midpoint.
  const double mid = std::acos(0.5 * (std::cos(glm::radians(20.0)) + std::cos(glm::radians(30.0))));
  EXPECT_NEAR(at(glm::degrees(mid)), 0.5, 1e-4);
  // On the plane: the lit disc, its soft edge and the dark outside, pixel by pixel; a point
  // light beside it (the choice between the two by flux).
  Scene s = plane(0.5f);
  s.point_lights.push_back(
      spot(vec3(0.1f, 2.0f, 0.0f), vec3(0.1f, -1.0f, 0.05f), vec3(4.0f, 3.0f, 2.0f), 30.0f, 10.0f));
  const RenderSettings rs = settings(24, 24);
  const std::vector<vec3> expected = expected_plane(s, rs, 0.5f);
  int dark = 0, soft = 0, full = 0;
  const vec3 peak = expected[size_t(rs.width) * 12 + 12];
  for (const vec3& e : expected) {
    if (e.x == 0.0f)
      ++dark;
    else if (e.x < 0.6f * peak.x)
      ++soft;
    else
      ++full;
  }
  EXPECT_GT(dark, 50) << "the view reaches past the cone";
  EXPECT_GT(soft, 20) << "the view crosses the falloff";
  EXPECT_GT(full, 20);
  expect_pixels(render_pixel_stats(s, rs, 4), expected, "spot light");
  s.point_lights.push_back(point(vec3(-1.0f, 1.0f, 1.0f), vec3(0.3f)));
  expect_pixels(render_pixel_stats(s, rs, 512), expected_plane(s, rs, 0.5f),
                "spot and point light");
}

TEST(PointLight, FurnaceSphereRendersRhoIOverPiR2OneMinusRho) {
  // Inside a closed diffuse sphere of radius R with a point light at its centre, the direct
  // irradiance is I / R^2 everywhere and the sphere sees only itself (irradiance pi L), so
  // L = rho (I / R^2 + pi L) / pi: L = rho I / (pi R^2 (1 - rho)).
  const float rho = 0.5f, radius = 2.0f;
  const vec3 intensity(2.0f, 3.0f, 4.0f);
  Scene s;
  s.source = "<furnace>";
  s.materials.push_back({"wall", diffuse(vec3(rho))});
  s.spheres.push_back({vec3(0.0f), radius, 0});
  s.point_lights.push_back(point(vec3(0.0f), intensity));
  s.camera.position = vec3(0.3f, 0.2f, 1.0f);
  s.camera.look_at = vec3(0.0f, 0.0f, -1.0f);
  s.camera.vfov_deg = 90.0f;
  RenderSettings rs = settings(8, 8);
  rs.max_depth = 64;  // rho^63: nothing left
  const vec3 expected = rho * intensity / (float(M_PI) * radius * radius * (1.0f - rho));
  const PixelStats ps = render_pixel_stats(s, rs, 1024);
  expect_pixels(ps, std::vector<vec3>(ps.mean.size(), expected), "furnace");
}

TEST(PointLight, ChosenByFluxAndListedAsLights) {
  Scene s = plane(0.5f);
  s.materials.push_back({"lamp", diffuse(vec3(0.0f), vec3(2.0f))});
  add_quad(s.mesh, vec3(3, 2, 3), vec3(0, 0, -1), vec3(1, 0, 0), 1);  // area 1, facing down
  s.point_lights.push_back(point(vec3(0, 1, 0), vec3(1.0f)));
  s.point_lights.push_back(spot(vec3(1, 1, 0), vec3(0, -1, 0), vec3(2.0f), 30.0f, 5.0f));
  s.point_lights.push_back(point(vec3(2, 1, 0), vec3(0.0f)));  // black: left out
  const CompiledScene cs(s, 4, 4);
  ASSERT_EQ(cs.lights().size(), 4u);  // two triangles, the point and the spot light
  ASSERT_EQ(cs.point_lights().size(), 2u);
  EXPECT_TRUE(cs.features() & kFeaturePointLights);
  EXPECT_EQ(spec_for_features(cs.features()) & (kSpecSpecular | kSpecLights), kSpecSpecular | kSpecLights)
      << "point lights run the kernels that have their code";
  // power = flux / pi: the emitter L A, the point light 4 pi I / pi, the spot light
  // 2 pi I (1 - (cos 25 + cos 30) / 2) / pi.
  const double spot_k =
      2.0 * M_PI * (1.0 - 0.5 * (std::cos(glm::radians(25.0)) + std::cos(glm::radians(30.0))));
  EXPECT_NEAR(point_light_solid_angle(s.point_lights[1]), spot_k, 1e-9);
  EXPECT_DOUBLE_EQ(point_light_solid_angle(s.point_lights[0]), 4.0 * M_PI);
  const double powers[4] = {1.0, 1.0, 4.0, 2.0 * spot_k / M_PI};  // the lamp's two halves first
  double total = 0.0;
  for (double p : powers) total += p;
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_NEAR(cs.lights()[i].power, powers[i], 1e-5 * powers[i]) << i;
    EXPECT_NEAR(cs.light_cdf()[i + 1] - cs.light_cdf()[i], powers[i] / total, 1e-6) << i;
  }
  EXPECT_EQ(cs.lights()[2].kind, uint32_t(kLightPoint));
  EXPECT_EQ(cs.lights()[3].kind, uint32_t(kLightSpot));
  EXPECT_EQ(cs.point_lights()[1].light, 3u);
  EXPECT_EQ(describe_point_lights(s.point_lights), "2 point lights, 1 spot light");
}

TEST(PointLight, OnlyDeltaLightsStillLightTheScene) {
  Scene s = plane(0.5f);
  s.point_lights.push_back(spot(vec3(0, 1, 0), vec3(0, 1, 0), vec3(1.0f), 20.0f, 5.0f));
  validate_scene(s);
  for (const std::string& w : s.diagnostics.warnings)
    EXPECT_EQ(w.find("no light"), std::string::npos) << w;
  const CompiledScene cs(s, 4, 4);
  EXPECT_EQ(cs.lights().size(), 1u);
  // The spot points at the sky: black, and the reason is not "no light".
  const std::string why = explain_black_image(s, cs);
  EXPECT_EQ(why.find("has no light"), std::string::npos) << why;
  EXPECT_NE(why.find("no light reaches the camera"), std::string::npos) << why;
  Scene dark = plane(0.5f);
  dark.point_lights.push_back(point(vec3(0, 1, 0), vec3(0.0f)));
  validate_scene(dark);
  bool warned = false;
  for (const std::string& w : dark.diagnostics.warnings)
    warned |= w.find("no light") != std::string::npos;
  EXPECT_TRUE(warned) << "a black point light lights nothing";
  const CompiledScene dcs(dark, 4, 4);
  EXPECT_NE(explain_black_image(dark, dcs).find("has no light"), std::string::npos);
}

TEST(PointLight, FlatListKeepsAWallWithALightBehindIt) {
  // Two parallel quads, a floor and a ceiling: every entry is on the hull (shadow rays between
  // two points of the scene cannot cross them) until a light sits above the ceiling.
  auto scene = [](float light_y) {
    Scene s = plane(0.5f);
    s.mesh = TriangleMesh();
    add_quad(s.mesh, vec3(-2, 0, 2), vec3(4, 0, 0), vec3(0, 0, -4), 0);  // floor, facing up
    add_quad(s.mesh, vec3(-2, 2, -2), vec3(4, 0, 0), vec3(0, 0, 4), 0);  // ceiling, facing down
    s.point_lights.push_back(point(vec3(0.1f, light_y, 0.2f), vec3(1.0f)));
    return s;
  };
  const CompiledScene inside(scene(1.0f), 4, 4), above(scene(3.0f), 4, 4);
  ASSERT_TRUE(inside.flat_list().enabled);
  ASSERT_TRUE(above.flat_list().enabled);
  EXPECT_EQ(inside.flat_list().quad_blockers, 0u);
  EXPECT_EQ(above.flat_list().quad_blockers, 1u) << "the ceiling blocks the light above it";
  SceneView v = above.view();
  v.use_flat = 1;
  const vec3 from = offset_ray_origin(vec3(0.3f, 0.0f, -0.1f), vec3(0, 1, 0));
  const vec3 to = vec3(0.1f, 3.0f, 0.2f);
  Ray r{from, glm::length(to - from), glm::normalize(to - from), 0.0f};
  EXPECT_TRUE(shadow_blocked<kAllFeatures>(v, r, kInvalid));
  // And the render: the floor under the ceiling, seen from between the two, stays black (direct
  // light only) with the flat list and with the BVH.
  Scene s = scene(3.0f);
  s.camera.position = vec3(0.2f, 1.5f, 0.3f);
  RenderSettings rs = settings(6, 6);
  rs.max_depth = 2;
  const CompiledScene cs(s, rs.width, rs.height);
  const IntegratorSettings cfg = make_integrator_settings(rs);
  for (uint32_t flat : {0u, 1u}) {
    SceneView view = cs.view();
    view.use_flat = flat;
    double sum = 0.0;
    for (uint32_t p = 0; p < 36; ++p) sum += luminance(trace_path(view, cfg, p, 0));
    EXPECT_EQ(sum, 0.0) << (flat ? "flat list" : "BVH");
  }
}

// ---- Scene format ------------------------------------------------------------------------------

const char* kObjects =
    R"("materials": {"white": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
       "objects": [{"type": "quad", "corner": [-1, 0, 1], "edge1": [2, 0, 0],
                    "edge2": [0, 0, -2], "material": "white"}])";

std::string load_error(const std::string& text, const std::string& path) {
  try {
    load_scene_from_json(text, path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(PointLightScene, PointAndSpotEntries) {
  const Scene s = load_scene_from_json(
      R"({"lights": [
            {"type": "point", "name": "bulb", "position": [1, 2, 3], "intensity": [4, 5, 6]},
            {"type": "point", "position": [0, 1, 0], "power": [12.566371, 0, 0]},
            {"type": "spot", "name": "stage", "position": [0, 3, 0], "look_at": [0, 0, 1],
             "power": [10, 10, 10], "cone_angle": 40, "cone_delta_angle": 15},
            {"type": "spot", "position": [0, 3, 0], "direction": [0, -1, 0]},
            {"type": "distant", "direction": [0, 1, 0]}], )" +
          std::string(kObjects) + "}",
      "lights.json");
  ASSERT_EQ(s.point_lights.size(), 4u);
  ASSERT_EQ(s.distant_lights.size(), 1u);
  const PointLightDesc& bulb = s.point_lights[0];
  EXPECT_EQ(bulb.name, "bulb");
  EXPECT_FALSE(bulb.spot);
  EXPECT_EQ(bulb.position, vec3(1, 2, 3));
  EXPECT_EQ(bulb.intensity, vec3(4, 5, 6));
  EXPECT_EQ(s.point_lights[1].name, "light 1");
  EXPECT_NEAR(s.point_lights[1].intensity.x, 1.0f, 1e-6f) << "power / 4 pi";
  const PointLightDesc& stage = s.point_lights[2];
  EXPECT_TRUE(stage.spot);
  EXPECT_EQ(stage.direction, vec3(0, -3, 1));
  EXPECT_FLOAT_EQ(stage.cone_angle_deg, 40.0f);
  EXPECT_FLOAT_EQ(stage.cone_delta_angle_deg, 15.0f);
  const double k =
      2.0 * M_PI * (1.0 - 0.5 * (std::cos(glm::radians(25.0)) + std::cos(glm::radians(40.0))));
  EXPECT_NEAR(stage.intensity.y, 10.0 / k, 1e-5);
  EXPECT_FLOAT_EQ(s.point_lights[3].cone_angle_deg, 30.0f) << "pbrt's defaults";
  EXPECT_FLOAT_EQ(s.point_lights[3].cone_delta_angle_deg, 5.0f);
  // The "lights" section written back (the sidecar, Save scene) reads back the same.
  const nlohmann::json j = lights_to_json(s.distant_lights, s.point_lights);
  ASSERT_EQ(j.size(), 5u);
  const Scene back = load_scene_from_json(
      "{\"lights\": " + j.dump() + ", " + std::string(kObjects) + "}", "back.json");
  ASSERT_EQ(back.point_lights.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(back.point_lights[i].name, s.point_lights[i].name);
    EXPECT_EQ(back.point_lights[i].spot, s.point_lights[i].spot);
    EXPECT_EQ(back.point_lights[i].position, s.point_lights[i].position);
    EXPECT_EQ(back.point_lights[i].intensity, s.point_lights[i].intensity);
    EXPECT_EQ(back.point_lights[i].direction, s.point_lights[i].direction) << i;
    EXPECT_EQ(back.point_lights[i].cone_angle_deg, s.point_lights[i].cone_angle_deg);
  }
}

TEST(PointLightScene, BadEntriesNameFileAndLine) {
  struct Bad {
    const char* light;
    const char* expected;
  };
  for (const Bad& b : {
           Bad{R"({"type": "pont", "position": [0, 1, 0]})",
               "lights.json:2: unknown light type \"pont\" (did you mean \"point\"?)"},
           Bad{R"({"type": "point"})", "light 0 has no \"position\""},
           Bad{R"({"type": "point", "position": [0, 1]})", "must be an array of 3 numbers"},
           Bad{R"({"type": "point", "position": [0, 1, 0], "intensity": [1, -1, 1]})",
               "\"intensity\" of light 0 must be >= 0"},
           Bad{R"({"type": "point", "position": [0, 1, 0], "intensity": [1, 1, 1],
                   "power": [1, 1, 1]})",
               "has both \"intensity\" and \"power\""},
           Bad{R"({"type": "point", "position": [0, 1, 0], "direction": [0, -1, 0]})",
               "unknown key \"direction\" in light 0"},
           Bad{R"({"type": "spot", "position": [0, 1, 0]})", "has no \"direction\" or \"look_at\""},
           Bad{R"({"type": "spot", "position": [0, 1, 0], "look_at": [0, 1, 0]})",
               "\"look_at\" of light 0 must differ from its \"position\""},
           Bad{R"({"type": "spot", "position": [0, 1, 0], "direction": [0, -1, 0],
                   "look_at": [0, 0, 0]})",
               "has both \"direction\" and \"look_at\""},
           Bad{R"({"type": "spot", "position": [0, 1, 0], "direction": [0, -1, 0],
                   "cone_angle": 0})",
               "\"cone_angle\" of light 0 must be in (0, 180] degrees"},
           Bad{R"({"type": "spot", "position": [0, 1, 0], "direction": [0, -1, 0],
                   "cone_angle": 20, "cone_delta_angle": 25})",
               "\"cone_delta_angle\" of light 0 must be in [0, cone_angle] degrees"},
       }) {
    const std::string e = load_error(
        std::string("{\"lights\": [\n") + b.light + "], " + kObjects + "}", "lights.json");
    EXPECT_NE(e.find(b.expected), std::string::npos) << b.light << "\n" << e;
    EXPECT_EQ(e.rfind("lights.json:", 0), 0u) << e;
  }
  // A black light is allowed, with a warning.
  const Scene s = load_scene_from_json(
      R"({"lights": [{"type": "point", "position": [0, 1, 0], "intensity": [0, 0, 0]}], )" +
          std::string(kObjects) + "}",
      "black.json");
  bool warned = false;
  for (const std::string& w : s.diagnostics.warnings)
    warned |= w.find("light 0 has zero intensity; it lights nothing") != std::string::npos;
  EXPECT_TRUE(warned);
}

TEST(DiskObject, AreaPowerAndIrradiance) {
  // A disk is pbrt's disk mesh, a polygon of 96 segments: area (96 / 2) r^2 sin(2 pi / 96),
  // 0.07% short of pi r^2, and an emissive one is sampled by area as its triangles.
  const float r = 0.5f, h = 1.0f;
  const Scene s = load_scene_from_json(
      R"({"materials": {"white": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]},
                        "lamp": {"type": "diffuse", "albedo": [0, 0, 0],
                                 "emission": [2, 3, 4]}},
          "camera": {"position": [0, 0.4, 2], "look_at": [0, 0, 0], "vfov": 1},
          "objects": [
            {"type": "quad", "corner": [-5, 0, 5], "edge1": [10, 0, 0], "edge2": [0, 0, -10],
             "material": "white"},
            {"type": "disk", "name": "lamp", "center": [0, 1, 0], "normal": [0, -1, 0],
             "radius": 0.5, "material": "lamp"}]})",
      "disk.json");
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.objects[1].kind, "disk");
  EXPECT_EQ(s.objects[1].count, 96u);
  double area = 0.0;
  vec3 normal(0.0f);
  for (uint32_t t = s.objects[1].first; t < s.objects[1].first + s.objects[1].count; ++t) {
    const uvec3 i = s.mesh.indices[t];
    const vec3 c = glm::cross(s.mesh.positions[i.y] - s.mesh.positions[i.x],
                              s.mesh.positions[i.z] - s.mesh.positions[i.x]);
    area += 0.5 * glm::length(c);
    normal += c;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.mesh.positions[i[k]].y, 1.0f, 1e-6f);
  }
  const double polygon = 48.0 * r * r * std::sin(2.0 * M_PI / 96.0);
  EXPECT_NEAR(area, polygon, 1e-6);
  EXPECT_NEAR(area / (M_PI * r * r), 0.99929, 1e-5);
  EXPECT_LT(glm::normalize(normal).y, -0.999f) << "it faces its normal";
  // Emitted power: the light list's powers (flux / pi) add up to L A.
  const CompiledScene cs(s, 8, 8);
  double power = 0.0;
  for (const Light& l : cs.lights()) power += l.power;
  EXPECT_NEAR(power, double(luminance(vec3(2, 3, 4))) * polygon, 1e-4 * power);
  // The plane point under it sees the disk's irradiance, E = pi L r^2 / (h^2 + r^2) for a
  // circle: the pixels (a 1 degree view of the origin) render rho E / pi, within the polygon's
  // 0.07% and the noise.
  RenderSettings rs = settings(8, 8);
  rs.sampler = kSamplerSobol;
  const PixelStats ps = render_pixel_stats(s, rs, 256);
  const vec3 expected = 0.5f * vec3(2, 3, 4) * (r * r / (h * h + r * r));
  const vec3 got = ps.image_mean();
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], expected[c], 0.005 * expected[c]) << c;
  // Its errors.
  for (const char* bad : {R"({"type": "disk", "radius": 0, "material": "white"})",
                          R"({"type": "disk", "normal": [0, 0, 0], "material": "white"})"}) {
    const std::string e =
        load_error(std::string(R"({"materials": {"white": {"type": "diffuse"}}, "objects": [
)") + bad + "]}",
                   "disk.json");
    EXPECT_EQ(e.rfind("disk.json:2: ", 0), 0u) << e;
  }
}

// ---- Edits -------------------------------------------------------------------------------------

TEST(PointLightEdits, AssignmentsAndWorkbench) {
  const std::string file = std::string(::testing::TempDir()) + "/plights_edit.json";
  write_text_atomic(file, R"({"lights": [{"type": "point", "name": "bulb", "position": [0, 1, 0]},
                     {"type": "spot", "name": "spot", "position": [0, 2, 0],
                      "direction": [0, -1, 0]},
                     {"type": "distant", "name": "sun", "direction": [0, 1, 0]}], )" +
                              std::string(kObjects) + "}");
  Scene s = load_scene(file);
  EXPECT_EQ(set_setting_assignment(s, "lights.bulb.intensity=1,2,3"), "");
  EXPECT_EQ(s.point_lights[0].intensity, vec3(1, 2, 3));
  EXPECT_EQ(set_setting_assignment(s, "lights.bulb.position=0.5,1.5,-1"), "");
  EXPECT_EQ(s.point_lights[0].position, vec3(0.5f, 1.5f, -1.0f));
  EXPECT_EQ(set_setting_assignment(s, "lights.spot.cone_angle=45"), "");
  EXPECT_EQ(set_setting_assignment(s, "lights.spot.cone_delta_angle=10"), "");
  EXPECT_EQ(set_setting_assignment(s, "lights.spot.direction=1,-1,0"), "");
  EXPECT_FLOAT_EQ(s.point_lights[1].cone_angle_deg, 45.0f);
  EXPECT_EQ(set_setting_assignment(s, "lights.sun.irradiance=2,2,2"), "");
  EXPECT_EQ(s.distant_lights[0].irradiance, vec3(2.0f));
  struct Bad {
    const char* assignment;
    const char* expected;
  };
  for (const Bad& b :
       {Bad{"lights.bulp.intensity=1,1,1", "no light \"bulp\" (did you mean \"bulb\"?)"},
        Bad{"lights.bulb.intensity=1,-1,1", "components must be >= 0"},
        Bad{"lights.bulb.intensity=1,1", "expected three finite numbers"},
        Bad{"lights.bulb.direction=0,1,0", "unknown field \"direction\" of point light"},
        Bad{"lights.spot.direction=0,0,0", "non-zero direction"},
        Bad{"lights.spot.cone_angle=200", "(0, 180]"},
        Bad{"lights.spot.cone_delta_angle=50", "[0, cone_angle]"},
        Bad{"lights.sun.position=0,0,0", "unknown field \"position\" of distant"}}) {
    const Scene before = s;
    const std::string e = set_setting_assignment(s, b.assignment);
    EXPECT_NE(e.find(b.expected), std::string::npos) << b.assignment << ": " << e;
    EXPECT_EQ(s.point_lights[0].intensity, before.point_lights[0].intensity);
    EXPECT_EQ(s.point_lights[1].cone_angle_deg, before.point_lights[1].cone_angle_deg);
  }
  // Every edit restarts the image in the workbench; Save scene keeps the lights as edited.
  s.settings.width = s.settings.height = 8;
  ui::Workbench wb(s, BackendChoice::kCpu, 1);
  std::string err;
  for (const char* edit : {"lights.bulb.intensity=3,3,3", "lights.bulb.position=0,0.5,0",
                           "lights.spot.cone_angle=60", "lights.sun.direction=1,1,0"}) {
    wb.update();
    const uint64_t before = wb.stats().resets;
    ASSERT_TRUE(wb.apply(edit, &err)) << err;
    wb.update();
    EXPECT_EQ(wb.stats().resets, before + 1) << edit;
  }
  EXPECT_FALSE(wb.apply("lights.bulb.intensity=x", &err));
  const std::string saved = std::string(::testing::TempDir()) + "/plights_saved.json";
  ASSERT_EQ(wb.save_scene(saved), "");
  const Scene back = load_scene(saved);
  ASSERT_EQ(back.point_lights.size(), 2u);
  EXPECT_EQ(back.point_lights[0].intensity, vec3(3.0f));
  EXPECT_EQ(back.point_lights[0].position, vec3(0.0f, 0.5f, 0.0f));
  EXPECT_FLOAT_EQ(back.point_lights[1].cone_angle_deg, 60.0f);
  ASSERT_EQ(back.distant_lights.size(), 1u);
  EXPECT_EQ(back.distant_lights[0].direction, vec3(1, 1, 0));
}

}  // namespace
