// Light tracing of caustics (render.light_tracing, integrator/light_path.h): the camera mapping it
// inverts, the filter's splat weights, and the split with the path tracer, which must keep every
// scene's mean (block z-test against plain path tracing) while lowering the noise of caustics.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <thread>

#include "cpu/cpu_backend.h"
#include "integrator/gpu_options.h"
#include "integrator/light_path.h"
#include "integrator/renderer.h"
#include "scene/compiled_scene.h"
#include "scene/loader.h"
#include "scene_builders.h"

namespace {
using namespace tracer;

// camera_film_point inverts Camera::generate_ray: a point along a camera ray lands where the ray
// left the film, through a pinhole and through a thin lens (from the ray's own lens point).
TEST(LightPath, FilmPointInvertsTheCameraRay) {
  for (float lens : {0.0f, 0.3f}) {
    Camera c = make_camera(vec3(1.0f, 2.0f, 3.0f), vec3(-2.0f, 0.5f, -4.0f), vec3(0, 1, 0), 50.0f,
                           lens, 6.0f, 320, 200);
    Pcg32 rng(7, 11);
    for (int i = 0; i < 2000; ++i) {
      const uint32_t x = rng.next_u32() % c.width, y = rng.next_u32() % c.height;
      const vec2 j = rng.next_2d(), l = rng.next_2d();
      const Ray r = c.generate_ray(x, y, j, l);
      const vec3 p = r.o + (0.5f + 20.0f * rng.next_float()) * r.d;
      vec2 fp;
      ASSERT_TRUE(camera_film_point(c, r.o, p, &fp));
      EXPECT_NEAR(fp.x, float(x) + j.x, 2e-3f) << "lens " << lens;
      EXPECT_NEAR(fp.y, float(y) + j.y, 2e-3f) << "lens " << lens;
    }
    vec2 fp;
    EXPECT_FALSE(camera_film_point(c, c.position, c.position - c.forward, &fp));  // behind
  }
}

// A splat gives pixel j the weight filter(dx) filter(dy) / integral^2 of its offset from j's
// centre: pixel j's estimate is then the filtered integral that the camera's samples, drawn from
// the normalised filter about j, estimate. (Their sum over pixels is 1 only for filters whose
// shifted copies add up to 1, as box and tent do; a narrow Blackman-Harris sums to 1.46.)
// The aimed first direction's density (light_target_choice): over two overlapping cones and a
// third partly behind the light, E[g / pdf] is the integral of g over the cones' union (g = 1:
// its solid angle; g = the light's cosine where positive: the flux factor), both against uniform
// directions over the sphere; and no direction falls outside the union.
TEST(LightPath, AimedDirectionsIntegrateOverTheTargetsCones) {
  const LightTarget targets[3] = {{vec3(0.3f, 0.2f, 2.0f), 0.8f},
                                  {vec3(0.9f, 0.0f, 2.2f), 0.7f},
                                  {vec3(3.0f, 0.5f, -0.4f), 1.0f}};
  SceneView s;
  s.light_targets = targets;
  s.light_target_count = 3;
  const vec3 p(0.0f), n(0.0f, 0.0f, 1.0f);
  auto in_union = [&](vec3 d) {
    for (const LightTarget& t : targets) {
      TargetCone c;
      if (light_target_cone(t, p, &c) && glm::dot(d, c.axis) >= c.cos_max) return true;
    }
    return false;
  };
  Pcg32 rng;
  rng.seed_with(7, 11);
  constexpr int kN = 400000;
  double aimed[2] = {0, 0}, uniform[2] = {0, 0};
  int outside = 0;
  for (int i = 0; i < kN; ++i) {
    vec3 d;
    float pdf;
    ASSERT_TRUE(light_target_choice(s, p, n, rng.next_float(), rng.next_2d(), &d, &pdf));
    ASSERT_GT(pdf, 0.0f);
    d = glm::normalize(d);
    outside += in_union(d) ? 0 : 1;
    aimed[0] += 1.0 / pdf;
    aimed[1] += std::max(0.0f, glm::dot(d, n)) / pdf;
    const vec3 u = sample_uniform_sphere(rng.next_2d());
    if (in_union(u)) {
      uniform[0] += 4.0 * kPi;
      uniform[1] += 4.0 * kPi * std::max(0.0f, glm::dot(u, n));
    }
  }
  EXPECT_LE(outside, kN / 10000);  // (the rim's rounding)
  for (int k = 0; k < 2; ++k)
    EXPECT_NEAR(aimed[k] / kN, uniform[k] / kN, 0.01 * uniform[k] / kN) << k;
  // From inside a target: no aim (the cosine); with every cone behind the light: pdf -1.
  vec3 d;
  float pdf;
  EXPECT_FALSE(light_target_choice(s, vec3(0.3f, 0.2f, 1.8f), n, 0.5f, vec2(0.5f), &d, &pdf));
  EXPECT_EQ(pdf, 0.0f);
  const LightTarget below = {vec3(0.0f, 0.0f, -3.0f), 1.0f};
  s.light_targets = &below;
  s.light_target_count = 1;
  EXPECT_FALSE(light_target_choice(s, p, n, 0.5f, vec2(0.5f), &d, &pdf));
  EXPECT_EQ(pdf, -1.0f);
}

// The targets scenes get: a sphere per caster ball (the rough materials' two narrow gold balls
// and the frosted one; the rough gold ball is no caster), none where the light lies in one (the
// lamp inside its glass) or where nothing casts.
TEST(LightPath, TargetsBoundTheCasters) {
  auto targets = [](const std::string& name) {
    return CompiledScene(load_scene(std::string(TRACER_SOURCE_DIR) + "/assets/scenes/" + name),
                         16, 16)
        .light_targets();
  };
  const std::vector<LightTarget> rough = targets("rough_materials.json");
  ASSERT_EQ(rough.size(), 3u);
  EXPECT_NEAR(rough[2].radius, 90.0f, 0.1f);  // the frosted ball
  EXPECT_EQ(targets("cornell_spheres.json").size(), 2u);
  EXPECT_EQ(targets("glass_lamp.json").size(), 0u);
  EXPECT_EQ(targets("cornell_box.json").size(), 0u);
}

TEST(LightPath, SplatWeightsAreTheNormalisedFilter) {
  // The profiles' integrals in closed form: Gaussian (bell minus its edge value), and the
  // Blackman-Harris window (its cosines integrate to 0 over the window).
  const float r = 1.5f, sigma = r / 3.0f, edge = std::exp(-4.5f);
  const float gauss = (sigma * std::sqrt(2.0f * kPi) * std::erf(r / (sigma * std::sqrt(2.0f))) -
                       2.0f * r * edge) / (1.0f - edge);
  EXPECT_NEAR(filter_profile_integral(PixelFilter::kGaussian, r), gauss, 1e-4f);
  EXPECT_NEAR(filter_profile_integral(PixelFilter::kBlackmanHarris, 1.0f), 2.0f * 0.35875f, 1e-4f);
  EXPECT_FLOAT_EQ(filter_profile_integral(PixelFilter::kTent, 1.0f), 1.0f);
  EXPECT_FLOAT_EQ(filter_profile_integral(PixelFilter::kBox, 0.5f), 1.0f);
  Pcg32 rng(3, 5);
  for (PixelFilter f : {PixelFilter::kBox, PixelFilter::kTent, PixelFilter::kGaussian,
                        PixelFilter::kBlackmanHarris}) {
    for (float radius : {default_filter_radius(f), 2.0f}) {
      IntegratorSettings cfg;
      cfg.width = 40;
      cfg.height = 30;
      cfg.filter = f;
      cfg.filter_radius = radius;
      const float norm = filter_profile_integral(f, radius);
      for (int i = 0; i < 200; ++i) {
        // Near the edges too: pixels outside the image get nothing.
        const vec2 fp(-2.0f + 44.0f * rng.next_float(), -2.0f + 34.0f * rng.next_float());
        std::vector<double> got(cfg.width * cfg.height, 0.0);
        double total = 0.0;
        splat_film_point(cfg, fp, vec3(1.0f), norm, [&](uint32_t p, vec3 v) {
          ASSERT_LT(p, got.size());
          got[p] += v.x;
          total += v.x;
        });
        double expected_total = 0.0;
        for (uint32_t y = 0; y < cfg.height; ++y)
          for (uint32_t x = 0; x < cfg.width; ++x) {
            const double w = filter_profile(f, radius, fp.x - (x + 0.5f)) *
                             filter_profile(f, radius, fp.y - (y + 0.5f)) / (norm * norm);
            expected_total += w;
            EXPECT_NEAR(got[y * cfg.width + x], w, 1e-5) << int(f) << " radius " << radius;
          }
        const bool inside = fp.x > radius && fp.x < 40 - radius && fp.y > radius && fp.y < 30 - radius;
        if (inside && (f == PixelFilter::kBox || (f == PixelFilter::kTent && radius == 1.0f)))
          EXPECT_NEAR(total, 1.0, 1e-5) << int(f);
        EXPECT_NEAR(total, expected_total, 1e-5);
      }
    }
  }
}

// Per-sample images (camera paths plus, with cfg.light_tracing, the sample's light paths) of a
// scene, summed per pixel and per 4x4 block: a block's variance from its per-sample sums counts
// the splats' correlation between pixels.
struct SampleStats {
  int width = 0, height = 0;
  uint32_t spp = 0;
  std::vector<glm::dvec3> sum, sum2;    // per pixel
  std::vector<glm::dvec3> bsum, bsum2;  // per block of kBlock x kBlock pixels
  static constexpr int kBlock = 4;
  glm::dvec3 mean(size_t i) const { return sum[i] / double(spp); }
  glm::dvec3 var(size_t i) const {
    const glm::dvec3 m = mean(i);
    return glm::max((sum2[i] - double(spp) * m * m) / double(spp - 1), glm::dvec3(0.0));
  }
  double image_mean() const {
    double s = 0.0;
    for (const glm::dvec3& v : sum) s += luminance(vec3(v));
    return s / (double(spp) * sum.size());
  }
};

SampleStats sample_stats(const CompiledScene& cs, const IntegratorSettings& cfg, uint32_t spp,
                         uint32_t first) {
  SampleStats st;
  st.width = int(cfg.width);
  st.height = int(cfg.height);
  st.spp = spp;
  const uint32_t n = cfg.width * cfg.height;
  const int bw = st.width / SampleStats::kBlock, bh = st.height / SampleStats::kBlock;
  st.sum.assign(n, glm::dvec3(0.0));
  st.sum2 = st.sum;
  st.bsum.assign(size_t(bw) * bh, glm::dvec3(0.0));
  st.bsum2 = st.bsum;
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  const float norm = filter_profile_integral(cfg.filter, cfg.filter_radius);
  std::vector<std::vector<vec3>> images(threads, std::vector<vec3>(n));
  for (uint32_t k = 0; k < spp; ++k) {
    const uint32_t sample = first + k;
    std::atomic<uint32_t> next{0}, next_light{0};
    auto work = [&](unsigned t) {
      std::vector<vec3>& img = images[t];
      std::fill(img.begin(), img.end(), vec3(0.0f));
      for (uint32_t p; (p = next.fetch_add(1)) < n;) {
        const vec3 L = trace_path(cs.view(), cfg, p, sample);
        if (is_finite(L)) img[p] += L;
      }
      if (!cfg.light_tracing) return;
      const uint32_t nl = light_paths_per_sample(cs.view(), n);
      for (uint32_t i; (i = next_light.fetch_add(1)) < nl;)
        trace_light_path<kAllFeatures>(cs.view(), cfg, i, sample, nl, norm,
                                       [&](uint32_t p, vec3 v) { img[p] += v; });
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, t);
    work(0);
    for (auto& th : pool) th.join();
    std::vector<glm::dvec3> blocks(st.bsum.size(), glm::dvec3(0.0));
    for (uint32_t p = 0; p < n; ++p) {
      glm::dvec3 v(0.0);
      for (unsigned t = 0; t < threads; ++t) v += glm::dvec3(images[t][p]);
      st.sum[p] += v;
      st.sum2[p] += v * v;
      const int bx = int(p % cfg.width) / SampleStats::kBlock;
      const int by = int(p / cfg.width) / SampleStats::kBlock;
      if (bx < bw && by < bh) blocks[size_t(by) * bw + bx] += v;
    }
    for (size_t b = 0; b < blocks.size(); ++b) {
      st.bsum[b] += blocks[b];
      st.bsum2[b] += blocks[b] * blocks[b];
    }
  }
  return st;
}

// The block z-test of two estimates' means (Sidak-corrected, as test::expect_same_means) and the
// image means within 2%.
void expect_same_block_means(const SampleStats& a, const SampleStats& b, const std::string& what) {
  std::vector<double> zs;
  for (size_t i = 0; i < a.bsum.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      auto stats = [&](const SampleStats& s, double* var) {
        const double m = s.bsum[i][c] / s.spp;
        *var = std::max(s.bsum2[i][c] / s.spp - m * m, 0.0) / (s.spp - 1);
        return m;
      };
      double va, vb;
      const double ma = stats(a, &va), mb = stats(b, &vb);
      zs.push_back((ma - mb) / std::sqrt(std::max(va + vb, 1e-20)));
    }
  const double zmax = test::sidak_z(1e-3, zs.size());
  int failures = 0;
  for (size_t i = 0; i < zs.size(); ++i)
    if (std::abs(zs[i]) > zmax && failures++ < 5)
      ADD_FAILURE() << what << ": block " << i / 3 << " channel " << i % 3 << " z = " << zs[i];
  EXPECT_NEAR(a.image_mean(), b.image_mean(), 0.02 * b.image_mean()) << what;
}

// The summed relative variance per sample (each pixel's over its mean squared plus 0.01, as
// relMSE weighs it; the means of `ref`).
double relative_variance(const SampleStats& s, const SampleStats& ref) {
  double sum = 0.0;
  for (size_t i = 0; i < s.sum.size(); ++i) {
    const double m = luminance(vec3(ref.mean(i)));
    sum += luminance(vec3(s.var(i))) / (m * m + 1e-2);
  }
  return sum;
}

// Light tracing against plain path tracing on a scene: the same means (block z-test), and the
// relative variance per sample at most `limit` of plain's (printed with the times: their product
// is the ratio at equal time). LT_SCENE, LT_SIZE and LT_SPP measure another scene.
void expect_light_tracing_keeps_the_mean(const std::string& default_scene, int default_size,
                                         uint32_t plain_spp, uint32_t lt_spp, double limit,
                                         const std::function<void(Scene&, RenderSettings&)>& edit =
                                             nullptr) {
  const char* file = std::getenv("LT_SCENE");
  const std::string path =
      file ? file : std::string(TRACER_SOURCE_DIR) + "/assets/scenes/" + default_scene;
  const char* size = std::getenv("LT_SIZE");
  const char* spp_text = std::getenv("LT_SPP");
  const int k = size ? std::atoi(size) : default_size;
  if (spp_text) plain_spp = lt_spp = uint32_t(std::atoi(spp_text));
  Scene scene = load_scene(path);
  RenderSettings rs;
  rs.width = rs.height = k;
  if (edit && !file) edit(scene, rs);
  const CompiledScene cs(scene, rs.width, rs.height);
  IntegratorSettings plain = make_integrator_settings(rs);
  // (The estimator itself, also where the renderers would skip it for its low yield.)
  ASSERT_GE(light_path_yield(cs, plain), 0.0f) << path;
  IntegratorSettings lt = plain;
  lt.light_tracing = 1;
  const auto t0 = std::chrono::steady_clock::now();
  const SampleStats a = sample_stats(cs, plain, plain_spp, 0);
  const auto t1 = std::chrono::steady_clock::now();
  const SampleStats b = sample_stats(cs, lt, lt_spp, 100000);
  const auto t2 = std::chrono::steady_clock::now();
  expect_same_block_means(b, a, "light tracing vs plain");
  const double ra = relative_variance(a, a), rb = relative_variance(b, a);
  const double ta = std::chrono::duration<double>(t1 - t0).count() / plain_spp;
  const double tb = std::chrono::duration<double>(t2 - t1).count() / lt_spp;
  std::printf("  %s: light tracing / plain: relative variance per sample %.4f, time per sample "
              "%.2f, product %.4f; means %.4f / %.4f\n",
              path.c_str(), rb / ra, tb / ta, rb / ra * tb / ta, b.image_mean(), a.image_mean());
  if (!file) EXPECT_LT(rb, limit * ra);
}

// The lamp behind glass: the whole room is lit through the slab (light -> glass -> room), which
// only BSDF-sampled paths found.
TEST(LightPath, LampBehindGlassKeepsItsMeanWithLessNoise) {
  expect_light_tracing_keeps_the_mean("glass_lamp.json", 32, 1024, 256, 0.2);
}

// The glass and mirror balls: their caustics on the floor and walls (light -> ball -> room).
TEST(LightPath, GlassAndMirrorBallsKeepTheirMeanWithLessNoise) {
  expect_light_tracing_keeps_the_mean("cornell_spheres.json", 32, 1024, 512, 0.8);
}

// The rough materials: gold balls of roughness 0.05 and 0.25 and a frosted glass ball (0.3) light
// the walls through highlights and a blurred focus that BSDF samples find only by chance; light
// paths start at them (glossy casters), aimed at the balls (light targets).
TEST(LightPath, GlossyCastersKeepTheirMeanWithLessNoise) {
  expect_light_tracing_keeps_the_mean("rough_materials.json", 32, 1024, 512, 0.5);
}

// The same with every other kind of light beside the lamp: a point light, a spot, a sun through
// the open front and a constant sky. At a glossy caster on a light-traced path the path tracer
// samples every light but the area lights, with MIS against its BSDF samples, and the area light
// a BSDF sample reaches there is the light tracer's. (The mean; the variance bounded only from
// above: light paths leave from the lamp alone, chosen among all the lights by power, so the
// sun and the sky take most of them here.)
TEST(LightPath, GlossyCastersBesideOtherLightsKeepTheirMean) {
  expect_light_tracing_keeps_the_mean(
      "rough_materials.json", 24, 1024, 512, 2.0,
      [](Scene& scene, RenderSettings&) { test::add_other_lights(scene); });
}

// A thin lens and a wide tent filter: the connections land on the lens and are splatted over
// four pixels, as the camera's samples are drawn.
void thin_lens_and_tent(Scene& scene, RenderSettings& rs) {
  scene.camera.aperture_radius = 20.0f;
  rs.filter = PixelFilter::kTent;
  rs.filter_radius = 1.5f;
}
TEST(LightPath, ThinLensAndTentFilterKeepTheMean) {
  expect_light_tracing_keeps_the_mean("cornell_spheres.json", 24, 1024, 512, 1.0,
                                      thin_lens_and_tent);
}

// smallpt: a sphere light (points by area over the whole sphere, light leaving outwards), a
// mirror and a glass ball, paths up to 64 segments. The mean holds; the noise does not drop:
// its light is a large cap under the ceiling, which the path tracer's BSDF samples through the
// balls find easily, while few light paths leave the cap and pass a ball (measured 4.0x the
// relative variance per sample: where light tracing loses; the bound only catches worse).
TEST(LightPath, SmallptsSphereLightKeepsItsMean) {
  expect_light_tracing_keeps_the_mean("smallpt.json", 32, 1024, 512, 6.0);
}

// Metals smooth and rough, plastics with a smooth coat (light paths start at the coat's delta
// events and connect at its diffuse base) and rough, a lampshade of diffuse transmission. The
// mean holds; the noise is about the same (measured 1.18x the relative variance per sample).
TEST(LightPath, MaterialsKeepTheirMean) {
  expect_light_tracing_keeps_the_mean("materials.json", 32, 1024, 512, 1.6);
}

// A two-sided light (either face chosen evenly), its light through the glass ball from both
// (measured 0.52x the relative variance per sample).
TEST(LightPath, TwoSidedLightKeepsItsMean) {
  expect_light_tracing_keeps_the_mean(
      "cornell_spheres.json", 24, 1024, 512, 0.8, [](Scene& scene, RenderSettings&) {
        for (NamedMaterial& m : scene.materials)
          if (m.material.is_emissive()) m.material.flags |= kMaterialTwoSidedEmission;
      });
}

// Instances (the BVH's second level): glass balls placed, moved, scaled and mirrored, through
// which the lamp's light reaches the room (the GPU's instances variant of the light kernel runs
// the same code). Measured 0.63x the relative variance per sample.
TEST(LightPath, InstancedGlassKeepsItsMean) {
  expect_light_tracing_keeps_the_mean(
      "cornell_box.json", 24, 1024, 512, 0.85,
      [](Scene& scene, RenderSettings&) { scene = test::instanced_scene(true); });
}

// Frosted glass behind the glass ball's caustic (the mirror ball made rough glass of roughness
// 0.4): light paths through the glass ball go on through the frosted ball (rough transmission by
// the path tracer's BSDF with its arguments reversed) and are joined to the camera on it (a wide
// lobe), both ways through its surface.
TEST(LightPath, FrostedGlassKeepsItsMean) {
  expect_light_tracing_keeps_the_mean(
      "cornell_spheres.json", 24, 2048, 1024, 1.2, [](Scene& scene, RenderSettings&) {
        for (NamedMaterial& nm : scene.materials)
          if (nm.name == "mirror") {
            nm.material = Material();
            nm.material.type = MaterialType::kDielectric;
            nm.material.ior = 1.5f;
            nm.material.roughness = 0.4f;
            nm.material.albedo = vec3(1.0f);
          }
      });
}

// A water tank (tank.json: a box of water filling the room's lower part, its faces other than
// the front and the top hidden behind the walls) seen through its flat front: the floor, the
// walls and the short block in the water are lit through the water's top (light -> water ->
// floor), and the camera sees them through the front (camera -> front -> floor): light tracing
// joins them to the camera through the front's refraction (window_path), and the path tracer
// leaves those paths to it (path_behind_window). The same mean, less noise.
TEST(LightPath, TankSeenThroughItsFrontKeepsItsMean) {
  const Scene s = load_scene(std::string(TRACER_SOURCE_DIR) + "/assets/scenes/tank.json");
  const CompiledScene cs(s, 16, 16);
  EXPECT_EQ(cs.view().window_plane_count, 6u) << "the water box's six faces";
  expect_light_tracing_keeps_the_mean("tank.json", 32, 1024, 256, 0.5);
}

// The tank through a thin lens and a tent filter of radius 1.5: each connection through the
// window solved from its own lens point, splatted over several pixels.
TEST(LightPath, TankThroughALensKeepsItsMean) {
  expect_light_tracing_keeps_the_mean(
      "tank.json", 24, 1024, 256, 0.6, [](Scene& scene, RenderSettings& rs) {
        thin_lens_and_tent(scene, rs);
        scene.camera.focus_distance = 1000.0f;
      });
}

// Which scenes light tracing finds paths worth tracing in (light_path_yield's pilot): the lamp
// behind glass (66% of its light paths reach the camera), the glass and mirror balls (7%), glass
// balls placed as instances (0.44%); none at all in the diffuse box or among rough metals and
// frosted glass; too few in smallpt (its lamp mostly outside the room: none), where it would
// lose. There the CPU traces no light paths and the image is the one without them, byte for
// byte.
TEST(LightPath, ScenesWithAndWithoutLightPaths) {
  auto yield = [](const std::string& name) {
    const Scene s = load_scene(std::string(TRACER_SOURCE_DIR) + "/assets/scenes/" + name);
    RenderSettings rs = s.settings;
    rs.width = rs.height = 64;
    return light_path_yield(CompiledScene(s, 64, 64), make_integrator_settings(rs));
  };
  EXPECT_GT(yield("glass_lamp.json"), 0.3f);
  EXPECT_GT(yield("cornell_spheres.json"), 0.03f);
  EXPECT_EQ(yield("cornell_box.json"), -1.0f);
  EXPECT_GT(yield("rough_materials.json"), 0.3f);  // (its glossy casters, aimed at)
  EXPECT_LT(yield("smallpt.json"), kLightTracingMinYield);
  EXPECT_GE(yield("smallpt.json"), 0.0f);
  {
    const Scene s = test::instanced_scene(true);
    RenderSettings rs = s.settings;
    rs.width = rs.height = 64;
    EXPECT_GT(light_path_yield(CompiledScene(s, 64, 64), make_integrator_settings(rs)),
              kLightTracingMinYield);
  }
  for (const char* name : {"cornell_box.json", "smallpt.json"}) {
    const Scene s = load_scene(std::string(TRACER_SOURCE_DIR) + "/assets/scenes/" + name);
    const CompiledScene cs(s, 24, 24);
    RenderSettings rs = s.settings;
    rs.width = rs.height = 24;
    IntegratorSettings cfg = make_integrator_settings(rs);
    ImageRGB img[2];
    for (int on = 0; on < 2; ++on) {
      cfg.light_tracing = uint32_t(on);
      CpuRenderer r(2);
      r.set_scene(cs, cfg);
      r.render(4);
      img[on] = r.image();
    }
    EXPECT_EQ(img[0].pixels, img[1].pixels) << name;
  }
}

// Without jitter a pixel is its centre's radiance, which no splat gives: light tracing does not
// run, and the CPU's image is the one without it, byte for byte.
TEST(LightPath, NeedsJitter) {
  RenderSettings rs;
  rs.light_tracing = true;
  rs.width = rs.height = 24;
  IntegratorSettings cfg = make_integrator_settings(rs);
  EXPECT_TRUE(light_tracing_runs(cfg, true));
  EXPECT_FALSE(light_tracing_runs(cfg, false));
  cfg.jitter = 0;
  EXPECT_FALSE(light_tracing_runs(cfg, true));
  const Scene s = load_scene(std::string(TRACER_SOURCE_DIR) + "/assets/scenes/glass_lamp.json");
  const CompiledScene cs(s, 24, 24);
  ImageRGB img[2];
  for (int on = 0; on < 2; ++on) {
    cfg.light_tracing = uint32_t(on);
    CpuRenderer r(2);
    r.set_scene(cs, cfg);
    r.render(4);
    img[on] = r.image();
  }
  EXPECT_EQ(img[0].pixels, img[1].pixels);
}

}  // namespace
