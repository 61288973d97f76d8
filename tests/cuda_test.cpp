// GPU tests (ctest label `gpu`): the CUDA backend renders what the CPU backend renders. With the
// same seed both trace the same paths, so most pixels agree to rounding; with different seeds the
// images agree statistically (4x4-block z-test against CPU variances). Compaction, material
// sorting, the first-bounce cache, the flat list, the tail and the megakernel never change the
// image. Every test skips, saying why, when no CUDA device is present.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>

#include "cpu/cpu_backend.h"
#include "integrator/distributed.h"
#include "cuda/cuda_renderer.h"
#include "cuda/device_buffer.h"
#include "cuda/film.h"
#include "scene/loader.h"
#include "scene_builders.h"
#include "test_util.h"

namespace {
using namespace test;

std::unique_ptr<Renderer> gpu_or_skip_reason(std::string* why) {
  return make_cuda_renderer(why, 0);
}

#define REQUIRE_GPU(r)                                                   \
  std::string why_no_gpu;                                                \
  auto r = gpu_or_skip_reason(&why_no_gpu);                              \
  if (!r) GTEST_SKIP() << "no CUDA device, GPU test skipped: " << why_no_gpu

// The batches' summed per-channel variance about their mean; with `ref`, each pixel's relative to
// ref's mean (over its square plus 0.01, as relMSE weighs it).
double batch_variance(const std::vector<ImageRGB>& batches, const PixelStats* ref = nullptr) {
  double sum = 0.0;
  for (size_t i = 0; i < batches[0].pixels.size(); ++i) {
    double m = 0, v = 0;
    for (const ImageRGB& img : batches) m += img.pixels[i];
    m /= batches.size();
    for (const ImageRGB& img : batches) v += (img.pixels[i] - m) * (img.pixels[i] - m);
    if (ref) {
      const double r = luminance(ref->mean[i / 3]);
      v /= r * r + 1e-2;
    }
    sum += v;
  }
  return sum;
}

struct BlockZ {
  double chi2_per_dof, limit;
};

// 8x8-block z statistics of GPU batch means (independent seeds) against CPU stats. The GPU's
// variance comes from the spread of its batches, which stays honest where single pixels see rare
// bright caustic paths.
BlockZ block_z(const std::vector<ImageRGB>& batches, const PixelStats& ref) {
  constexpr int k = 8;
  const double nb = double(batches.size());
  double z2 = 0;
  size_t n = 0;
  for (int by = 0; by + k <= ref.height; by += k)
    for (int bx = 0; bx + k <= ref.width; bx += k)
      for (int c = 0; c < 3; ++c) {
        std::vector<double> means;
        double ref_mean = 0, ref_var = 0;
        for (const ImageRGB& img : batches) {
          double m = 0;
          for (int y = by; y < by + k; ++y)
            for (int x = bx; x < bx + k; ++x) m += img.pixels[3 * (size_t(y) * ref.width + x) + c];
          means.push_back(m / (k * k));
        }
        for (int y = by; y < by + k; ++y)
          for (int x = bx; x < bx + k; ++x) {
            const size_t i = size_t(y) * ref.width + x;
            ref_mean += ref.mean[i][c];
            ref_var += ref.var[i][c] / ref.spp;
          }
        ref_mean /= k * k;
        ref_var /= double(k * k) * (k * k);
        double gm = 0, gv = 0;
        for (double m : means) gm += m;
        gm /= nb;
        for (double m : means) gv += (m - gm) * (m - gm);
        gv /= (nb - 1.0) * nb;  // variance of the mean of the batches
        const double d = gm - ref_mean;
        z2 += d * d / std::max(gv + ref_var, 1e-12);
        ++n;
      }
  return {z2 / n, 1.0 + 5.0 * std::sqrt(2.0 / n)};
}

// Fraction of pixel values that agree to a relative 1e-3 (same seed: same paths).
double identical_fraction(const ImageRGB& a, const ImageRGB& b) {
  size_t same = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i)
    if (std::abs(a.pixels[i] - b.pixels[i]) <= 1e-3f * (1.0f + std::abs(b.pixels[i]))) ++same;
  return double(same) / a.pixels.size();
}

ImageRGB render_gpu(Renderer& r, const Scene& s, const RenderSettings& rs, uint32_t spp,
                    const GpuOptions& o, FrameStats* stats = nullptr) {
  const CompiledScene cs(s, rs.width, rs.height);
  r.set_gpu_options(o);
  r.set_scene(cs, make_integrator_settings(rs));
  const FrameStats st = r.render(spp);
  if (stats) *stats = st;
  EXPECT_EQ(r.samples_done(), spp);
  return r.image();
}

// An asset scene, and its settings at 96x64: the size of the tests that compare GPU switches.
Scene small_asset(const char* name, RenderSettings* rs) {
  Scene s = load_scene(source_dir() + "/assets/scenes/" + name);
  *rs = s.settings;
  rs->width = 96;
  rs->height = 64;
  return s;
}

// An asset scene, edited, and its settings at 64x64 with seed 7: the size of the tests of the
// caustic estimators (manifold NEE, light tracing) against the CPU.
Scene caustic_asset(const std::string& name, const std::function<void(Scene&)>& edit,
                    RenderSettings* rs) {
  Scene s = load_scene(source_dir() + "/assets/scenes/" + name);
  if (edit) edit(s);
  *rs = s.settings;
  rs->width = 64;
  rs->height = 64;
  rs->seed = 7;
  return s;
}

// The GPU renders what the CPU renders, in the wavefront and the megakernel: with the same seed
// (the same paths) over 90% of the pixel values agree to 1e-3, and 16 batches of independent
// seeds pass the block z-test against the CPU's per-pixel mean and variance.
void expect_gpu_matches_cpu(Renderer& gpu, const std::string& name, const Scene& s,
                            const RenderSettings& rs) {
  const PixelStats cpu = render_pixel_stats(s, rs, 1024);
  ImageRGB cpu_img = make_image(rs.width, rs.height);
  for (size_t i = 0; i < cpu.mean.size(); ++i)
    cpu_img.set(int(i % rs.width), int(i / rs.width), cpu.mean[i]);
  for (KernelMode mode : {KernelMode::kWavefront, KernelMode::kMegakernel}) {
    GpuOptions o;
    o.kernel = mode;
    const double same = identical_fraction(render_gpu(gpu, s, rs, 1024, o), cpu_img);
    std::vector<ImageRGB> batches;
    for (uint32_t b = 0; b < 16; ++b) {
      RenderSettings other = rs;
      other.seed = 100 + b;
      batches.push_back(render_gpu(gpu, s, other, 128, o));
    }
    const BlockZ z = block_z(batches, cpu);
    std::printf("%-42s %-10s same-seed identical %.4f, independent chi2/dof %.3f (limit %.3f)\n",
                name.c_str(), mode == KernelMode::kWavefront ? "wavefront" : "megakernel", same,
                z.chi2_per_dof, z.limit);
    EXPECT_GT(same, 0.9) << name;
    EXPECT_LT(z.chi2_per_dof, z.limit) << name;
  }
}

const char* kScenes[] = {"cornell_box.json",    "cornell_spheres.json", "depth_of_field.json",
                         "obj_scene.json",      "gltf_scene.gltf",      "cornell_closed.json",
                         "rough_materials.json", "subsurface.json",      "textured.gltf",
                         "materials.json",      "many_lights.json"};

TEST(Gpu, MatchesCpuOnEveryAsset) {
  REQUIRE_GPU(gpu);
  std::printf("device: %s\n", gpu->device_name().c_str());
  for (const char* name : kScenes) {
    const Scene s = load_scene(source_dir() + "/assets/scenes/" + name);
    RenderSettings rs = s.settings;
    rs.width = 64;
    rs.height = 64;
    rs.seed = 5;
    expect_gpu_matches_cpu(*gpu, name, s, rs);
  }
}

// Instanced meshes (the BVH's second level) on the GPU: the instanced room of the two-level
// BVH's tests, with diffuse and with glass balls (the specular kernels), against the CPU.
TEST(Gpu, InstancesMatchCpu) {
  REQUIRE_GPU(gpu);
  for (bool glass : {false, true}) {
    const Scene s = instanced_scene(glass);
    RenderSettings rs;
    rs.width = 64;
    rs.height = 64;
    rs.max_depth = 6;
    rs.seed = 5;
    expect_gpu_matches_cpu(*gpu, glass ? "instances, glass balls" : "instances", s, rs);
  }
}

// The feature buffers on the GPU are the CPU's: the same camera rays and the same choices at
// mirrors and glass (same seed), in both kernels, on scenes with glass, textures, depth of field
// and the flat list; the colour is the same with AOVs on as off.
TEST(Gpu, AovsMatchCpu) {
  REQUIRE_GPU(gpu);
  for (const char* name : {"cornell_spheres.json", "textured.gltf", "depth_of_field.json",
                           "cornell_box.json"}) {
    RenderSettings rs;
    const Scene s = small_asset(name, &rs);
    const CompiledScene cs(s, rs.width, rs.height);
    CpuRenderer cpu(0);
    cpu.set_scene(cs, make_integrator_settings(rs));
    cpu.set_aovs(true);
    cpu.render(16);
    const AovImages c = cpu.aov_images();
    for (KernelMode mode : {KernelMode::kWavefront, KernelMode::kMegakernel}) {
      GpuOptions o;
      o.kernel = mode;
      gpu->set_gpu_options(o);
      gpu->set_scene(cs, make_integrator_settings(rs));
      gpu->render(16);
      const ImageRGB off = gpu->image();
      gpu->set_aovs(true);
      gpu->reset();
      gpu->render(16);
      const ImageRGB on = gpu->image();
      const AovImages g = gpu->aov_images();
      gpu->set_aovs(false);
      ASSERT_FALSE(g.empty());
      EXPECT_EQ(identical_fraction(on, off), 1.0) << name;
      const double albedo = identical_fraction(g.albedo, c.albedo),
                   normal = identical_fraction(g.normal, c.normal);
      size_t ids = 0, depth = 0;
      for (size_t i = 0; i < g.depth.size(); ++i) {
        ids += g.material[i] == c.material[i];
        depth += std::abs(g.depth[i] - c.depth[i]) <= 1e-3f * (1.0f + c.depth[i]);
      }
      std::printf("%-24s %-10s AOVs identical to the CPU's: albedo %.4f normal %.4f depth %.4f "
                  "material %.4f\n",
                  name, mode == KernelMode::kWavefront ? "wavefront" : "megakernel", albedo,
                  normal, double(depth) / g.depth.size(), double(ids) / g.depth.size());
      EXPECT_GT(albedo, 0.98) << name;
      EXPECT_GT(normal, 0.98) << name;
      EXPECT_GT(double(depth) / g.depth.size(), 0.98) << name;
      EXPECT_GT(double(ids) / g.depth.size(), 0.98) << name;
    }
  }
}

// A PFM sky of w x h texels (equirectangular, or octahedral when square) with a small bright sun.
std::string write_sky(int w, int h, const std::string& name) {
  const std::string path = testing::TempDir() + "/cuda_" + name + ".pfm";
  FILE* f = std::fopen(path.c_str(), "wb");
  std::fprintf(f, "PF\n%d %d\n-1\n", w, h);
  for (int y = h - 1; y >= 0; --y)
    for (int x = 0; x < w; ++x) {
      vec3 c = y < h / 2 ? vec3(0.3f, 0.5f, 0.9f) * (1.0f + 0.5f * float(x) / float(w))
                         : vec3(0.3f, 0.25f, 0.2f);
      if (x >= w / 3 && x < w / 3 + 2 && y >= h / 4 && y < h / 4 + 2) c = vec3(60.0f, 55.0f, 50.0f);
      std::fwrite(&c, 4, 3, f);
    }
  std::fclose(f);
  return path;
}

// Lights at infinity on the GPU: an equirectangular and an octahedral map (rotated), a cone sun
// and a delta sun, a constant sky hidden behind a background, and the sunrise asset when
// blender-data is installed; in the wavefront and the megakernel, against the CPU by the same
// seed (the same paths) and by the block z-test over independent seeds.
TEST(Gpu, EnvironmentAndSunsMatchCpu) {
  REQUIRE_GPU(gpu);
  struct Case {
    std::string name;
    Scene scene;
  };
  std::vector<Case> cases;
  auto base = [](const std::string& map, EnvMapping mapping, float rotation) {
    Scene s;
    s.source = "<env>";
    s.materials.push_back({"ground", diffuse(vec3(0.5f))});
    s.materials.push_back({"clay", diffuse(vec3(0.8f, 0.4f, 0.3f))});
    Material metal;
    metal.type = MaterialType::kConductor;
    metal.albedo = vec3(0.9f, 0.8f, 0.5f);
    metal.roughness = 0.4f;
    s.materials.push_back({"metal", metal});
    Material glass;
    glass.type = MaterialType::kDielectric;
    glass.ior = 1.5f;
    glass.albedo = vec3(1.0f);
    s.materials.push_back({"glass", glass});
    add_quad(s.mesh, vec3(-6, 0, 6), vec3(12, 0, 0), vec3(0, 0, -12), 0);
    s.spheres.push_back({vec3(-1.6f, 0.6f, 0.0f), 0.6f, 1});
    s.spheres.push_back({vec3(0.0f, 0.6f, 0.0f), 0.6f, 2});
    add_icosphere(s.mesh, vec3(1.6f, 0.6f, 0.0f), 0.6f, 2, 3);
    s.camera.position = vec3(0.0f, 2.0f, 5.0f);
    s.camera.look_at = vec3(0.0f, 0.5f, 0.0f);
    s.camera.vfov_deg = 45.0f;
    s.environment.file = map;
    s.environment.mapping = mapping;
    s.environment.rotation_deg = rotation;
    EXPECT_EQ(refresh_environment(s), "");
    return s;
  };
  cases.push_back(
      {"equirect map", base(write_sky(64, 32, "equirect"), EnvMapping::kEquirect, 30.0f)});
  cases.push_back(
      {"octahedral map", base(write_sky(48, 48, "octa"), EnvMapping::kOctahedral, -60.0f)});
  {
    Scene s = base("", EnvMapping::kAuto, 0.0f);
    s.environment.color = vec3(0.2f, 0.3f, 0.5f);
    s.environment.visible = false;
    s.environment.background = vec3(0.05f);
    DistantLightDesc cone, delta;
    cone.direction = vec3(1.0f, 1.5f, 0.5f);
    cone.irradiance = vec3(4.0f, 3.5f, 3.0f);
    cone.angular_diameter_deg = 2.0f;
    delta.direction = vec3(-1.0f, 1.0f, 1.0f);
    delta.irradiance = vec3(0.5f, 0.5f, 1.0f);
    s.distant_lights = {cone, delta};
    cases.push_back({"constant sky hidden, two suns", s});
  }
  if (std::FILE* f = std::fopen((std::string(kBlenderWorlds) + "/sunrise.exr").c_str(), "rb")) {
    std::fclose(f);
    cases.push_back(
        {"env_sunrise.json", load_scene(source_dir() + "/assets/scenes/env_sunrise.json")});
  } else {
    std::printf("env_sunrise.json skipped: %s is absent (Debian package blender-data)\n",
                kBlenderWorlds);
  }
  for (const Case& c : cases) {
    RenderSettings rs = c.scene.settings;
    rs.width = 64;
    rs.height = 48;
    rs.max_depth = 6;
    rs.seed = 5;
    expect_gpu_matches_cpu(*gpu, c.name, c.scene, rs);
  }
}

// Point and spot lights on the GPU: the Cornell box lit by a point light and a spot light
// instead of its lamp (diffuse kernels' scene, the flat list with the lights inside its hull), and
// spheres, a conductor and glass under a point light, a spot light, a delta sun and an emissive
// disk; in the wavefront and the megakernel, against the CPU by the same seed and by the block
// z-test over independent seeds.
TEST(Gpu, PointAndSpotLightsMatchCpu) {
  REQUIRE_GPU(gpu);
  struct Case {
    std::string name;
    Scene scene;
  };
  std::vector<Case> cases;
  {
    Scene s = load_scene(source_dir() + "/assets/scenes/cornell_box.json");
    s.materials[s.find_material("light")].material.emission = vec3(0.0f);
    PointLightDesc bulb;
    bulb.position = vec3(278.0f, 450.0f, 278.0f);
    bulb.intensity = vec3(60000.0f, 50000.0f, 40000.0f);
    PointLightDesc stage = bulb;
    stage.spot = true;
    stage.position = vec3(100.0f, 500.0f, 100.0f);
    stage.direction = vec3(270.0f, -500.0f, 250.0f);
    stage.intensity = vec3(50000.0f, 200000.0f, 400000.0f);
    stage.cone_angle_deg = 20.0f;
    stage.cone_delta_angle_deg = 8.0f;
    s.point_lights = {bulb, stage};
    cases.push_back({"cornell box, point + spot", s});
  }
  {
    Scene s;
    s.source = "<point lights>";
    s.materials.push_back({"ground", diffuse(vec3(0.5f))});
    s.materials.push_back({"clay", diffuse(vec3(0.8f, 0.4f, 0.3f))});
    Material metal;
    metal.type = MaterialType::kConductor;
    metal.albedo = vec3(0.9f, 0.8f, 0.5f);
    metal.roughness = 0.4f;
    s.materials.push_back({"metal", metal});
    Material glass;
    glass.type = MaterialType::kDielectric;
    glass.ior = 1.5f;
    glass.albedo = vec3(1.0f);
    s.materials.push_back({"glass", glass});
    s.materials.push_back({"lamp", diffuse(vec3(0.0f), vec3(3.0f, 2.0f, 1.0f))});
    add_quad(s.mesh, vec3(-6, 0, 6), vec3(12, 0, 0), vec3(0, 0, -12), 0);
    s.spheres.push_back({vec3(-1.6f, 0.6f, 0.0f), 0.6f, 1});
    s.spheres.push_back({vec3(0.0f, 0.6f, 0.0f), 0.6f, 2});
    add_icosphere(s.mesh, vec3(1.6f, 0.6f, 0.0f), 0.6f, 2, 3);
    add_quad(s.mesh, vec3(-2.5f, 2.5f, -1.0f), vec3(0.6f, 0, 0), vec3(0, 0, 0.6f),
             4);  // facing down
    s.camera.position = vec3(0.0f, 2.0f, 5.0f);
    s.camera.look_at = vec3(0.0f, 0.5f, 0.0f);
    s.camera.vfov_deg = 45.0f;
    PointLightDesc bulb;
    bulb.position = vec3(1.0f, 2.5f, 1.5f);
    bulb.intensity = vec3(4.0f, 3.5f, 3.0f);
    PointLightDesc stage;
    stage.spot = true;
    stage.position = vec3(-2.0f, 3.0f, 2.0f);
    stage.direction = vec3(2.0f, -3.0f, -2.0f);
    stage.intensity = vec3(5.0f, 10.0f, 20.0f);
    stage.cone_angle_deg = 25.0f;
    stage.cone_delta_angle_deg = 10.0f;
    s.point_lights = {bulb, stage};
    DistantLightDesc sun;
    sun.direction = vec3(-1.0f, 1.0f, 1.0f);
    sun.irradiance = vec3(0.5f, 0.5f, 1.0f);
    s.distant_lights = {sun};
    cases.push_back({"spheres, glass, point + spot + sun + lamp", s});
  }
  for (const Case& c : cases) {
    RenderSettings rs = c.scene.settings;
    rs.width = 64;
    rs.height = 48;
    rs.max_depth = 6;
    rs.seed = 5;
    const CompiledScene cs(c.scene, rs.width, rs.height);
    EXPECT_TRUE(cs.features() & kFeaturePointLights) << c.name;
    expect_gpu_matches_cpu(*gpu, c.name, c.scene, rs);
  }
}

// Every combination of the switches that a scene's resolution tells apart (kernel x compaction x
// sorting x first-bounce cache x flat list x tail) renders the image of the plain wavefront (the
// same seed: the same paths, so the same pixels to rounding), runs the design that
// resolve_gpu_options chose and reports it. The megakernel ignores the wavefront's switches: it
// runs with and without the flat list. (Dynamic fetch, specialisation, rays at ids and the
// unfused stages are build variants, no longer switches: a variant build runs this test through
// its own paths, against its own plain wavefront.)
TEST(Gpu, SwitchesNeverChangeTheImage) {
  REQUIRE_GPU(gpu);
  RenderSettings rs;
  const Scene s = small_asset("cornell_spheres.json", &rs);
  rs.jitter = false;  // (else the first-bounce cache never runs)
  const CompiledScene cs(s, rs.width, rs.height);
  // The scene is small enough for the flat list. Through the BVH a different (watertight) test
  // rounds differently, so a few paths that graze an edge may go elsewhere: the same images to
  // rounding, alive counts not compared.
  ASSERT_TRUE(cs.flat_list().enabled);
  const GpuSceneTraits traits = gpu_scene_traits(cs, make_integrator_settings(rs));
  GpuOptions plain;
  plain.kernel = KernelMode::kWavefront;
  plain.compaction = Compaction::kOff;
  plain.first_bounce_cache = false;
  FrameStats base_stats;
  const ImageRGB base = render_gpu(*gpu, s, rs, 64, plain, &base_stats);
  EXPECT_NE(base_stats.specialization.find("flat list"), std::string::npos)
      << base_stats.specialization;
  std::printf("build variant %s\n", gpu_build_variant().c_str());
  std::vector<EffectiveGpuOptions> ran;  // the distinct designs, each rendered once
  auto same_design = [](const EffectiveGpuOptions& a, const EffectiveGpuOptions& b) {
    return a.options == b.options && a.rays_at_slots == b.rays_at_slots &&
           a.fused_trace == b.fused_trace && a.fused_tail == b.fused_tail &&
           a.dynamic_fetch == b.dynamic_fetch && a.spec == b.spec;
  };
  for (const KernelMode kernel : {KernelMode::kWavefront, KernelMode::kMegakernel})
    for (const Compaction compaction :
         {Compaction::kOff, Compaction::kAuto, Compaction::kShade, Compaction::kCub})
      for (const bool sort : {false, true})
        for (const bool cache : {false, true})
          for (const bool flat : {true, false})
            for (const float tail : {0.0f, GpuOptions().tail_fraction, 0.6f}) {
              GpuOptions o;
              o.kernel = kernel;
              o.compaction = compaction;
              o.sort_materials = sort;
              o.first_bounce_cache = cache;
              o.flat_list = flat;
              o.tail_fraction = tail;  // 0.6: the tail from an early bounce on
              if (kernel == KernelMode::kMegakernel &&
                  (compaction != Compaction::kOff || sort || cache || tail != 0.0f))
                continue;
              const EffectiveGpuOptions want = resolve_gpu_options(o, traits);
              if (std::any_of(ran.begin(), ran.end(),
                              [&](const EffectiveGpuOptions& e) { return same_design(e, want); }))
                continue;
              ran.push_back(want);
              FrameStats st;
              const ImageRGB img = render_gpu(*gpu, s, rs, 64, o, &st);
              const std::string what = want.describe();
              const double same = identical_fraction(img, base);
              std::printf("identical %.4f: %s\n", same, what.c_str());
              EXPECT_GT(same, 0.97) << what;
              ASSERT_TRUE(st.gpu.has_value()) << what;
              EXPECT_TRUE(same_design(*st.gpu, want)) << what << "\nran: " << st.gpu->describe();
              EXPECT_EQ(st.kernel, kernel == KernelMode::kWavefront ? "wavefront" : "megakernel");
              EXPECT_EQ(st.specialization.find("BVH") != std::string::npos, !want.options.flat_list)
                  << what;
              if (kernel != KernelMode::kWavefront) continue;
              EXPECT_EQ(st.stages.rays_at_slots, want.rays_at_slots) << what;
              EXPECT_EQ(st.stages.fused_trace, want.fused_trace) << what;
              // With a tail the counts end at the bounce it took over (the first call's first
              // sample has no estimate yet, so only later calls use it): a prefix of the plain
              // wavefront's.
              if (!base_stats.alive_per_bounce.empty() && want.options.flat_list) {
                ASSERT_LE(st.alive_per_bounce.size(), base_stats.alive_per_bounce.size()) << what;
                EXPECT_TRUE(std::equal(st.alive_per_bounce.begin(), st.alive_per_bounce.end(),
                                       base_stats.alive_per_bounce.begin()))
                    << what;
              }
            }
  // Off: 2 sortings x 2 caches x 2 accelerations; shade (= auto here) and CUB: 2 x 2 x 2 x 3
  // tails each; the megakernel: 2 accelerations.
  std::printf("%zu designs\n", ran.size());
  EXPECT_EQ(ran.size(), 8u + 2 * 24u + 2u);
}

// With compaction in the shade kernel the shade kernel also queues the paths that have a shadow
// ray, and finishes there the paths that end without one; the shadow stage traces the queue
// only. Every shadow ray must be in a queue (the queues' lengths add up to the sample's shadow
// rays), and the image and counts must be those of CUB's compaction, whose shadow stage passes
// over every path of the bounce.
TEST(Gpu, ShadowQueueHoldsEveryShadowRay) {
  REQUIRE_GPU(gpu);
  for (const char* name : {"cornell_box.json", "cornell_spheres.json", "subsurface.json"}) {
    RenderSettings rs;
    const Scene s = small_asset(name, &rs);
    const CompiledScene cs(s, rs.width, rs.height);
    GpuOptions o;
    o.kernel = KernelMode::kWavefront;
    o.tail_fraction = 0.0f;
    FrameStats one, queued, cub;
    auto run = [&](Compaction by, FrameStats* st, uint32_t spp) {
      o.compaction = by;
      gpu->set_gpu_options(o);
      gpu->set_scene(cs, make_integrator_settings(rs));
      *st = gpu->render(spp);
      return gpu->image();
    };
    run(Compaction::kShade, &one, 1);
    uint64_t queued_rays = 0;
    for (uint32_t k : one.shadow_per_bounce) queued_rays += k;
    EXPECT_EQ(queued_rays, one.rays.shadow) << name;
    EXPECT_GT(one.shadow_per_bounce.size(), 1u) << name;
    // The paths finished without a shadow ray are among those that ended at their bounce.
    ASSERT_FALSE(one.finished_per_bounce.empty()) << name;
    for (size_t b = 0; b < one.finished_per_bounce.size(); ++b) {
      const uint32_t in = b < one.alive_per_bounce.size() ? one.alive_per_bounce[b] : 0;
      const uint32_t on = b + 1 < one.alive_per_bounce.size() ? one.alive_per_bounce[b + 1] : 0;
      EXPECT_LE(one.finished_per_bounce[b], in - on) << name << " bounce " << b;
    }
    const ImageRGB a = run(Compaction::kShade, &queued, 32);
    const ImageRGB b = run(Compaction::kCub, &cub, 32);
    EXPECT_TRUE(cub.shadow_per_bounce.empty()) << name;
    const double same = identical_fraction(a, b);
    std::printf("%-22s shadow queue against CUB's pass: identical %.4f, shadow rays %llu / %llu\n",
                name, same, (unsigned long long)queued.rays.shadow,
                (unsigned long long)cub.rays.shadow);
    EXPECT_GT(same, 0.999) << name;
    EXPECT_EQ(queued.rays.shadow, cub.rays.shadow) << name;
    EXPECT_EQ(queued.rays.extension, cub.rays.extension) << name;
    EXPECT_EQ(queued.nonfinite, cub.nonfinite) << name;
    EXPECT_EQ(queued.rays.walk_capped, cub.rays.walk_capped) << name;
  }
}

// The tail kernel takes over the paths of a short queue and runs their remaining bounces: the
// same paths as the stages would trace (same image, same extension and shadow ray counts), for
// both compactions, through the flat list and the BVH, and on a scene with random walks.
TEST(Gpu, TailRunsTheSamePaths) {
  REQUIRE_GPU(gpu);
  for (const char* name : {"cornell_box.json", "subsurface.json"}) {
    RenderSettings rs;
    const Scene s = small_asset(name, &rs);
    const CompiledScene cs(s, rs.width, rs.height);
    for (const bool flat : {true, false}) {
      for (const bool cub : {false, true}) {
        GpuOptions o;
        o.kernel = KernelMode::kWavefront;
        o.flat_list = flat;
        o.compaction = cub ? Compaction::kCub : Compaction::kShade;
        o.tail_fraction = 0.0f;
        FrameStats plain, tail;
        auto run = [&](const GpuOptions& opts, FrameStats* st) {
          gpu->set_gpu_options(opts);
          gpu->set_scene(cs, make_integrator_settings(rs));
          gpu->render(1);  // the first call measures the queues the tail is chosen from
          *st = gpu->render(31);
          return gpu->image();
        };
        const ImageRGB a = run(o, &plain);
        o.tail_fraction = 0.6f;
        const ImageRGB b = run(o, &tail);
        const std::string what = std::string(name) + (flat ? ", flat list" : ", BVH") +
                                 (cub ? ", CUB" : ", in shade");
        EXPECT_EQ(plain.stages.tail_from, 0u) << what;
        EXPECT_GT(tail.stages.tail_from, 0u) << what;
        EXPECT_GT(tail.stages.tail, 0.0) << what;
        EXPECT_GT(identical_fraction(a, b), 0.97) << what;
        EXPECT_EQ(tail.rays.extension, plain.rays.extension) << what;
        EXPECT_EQ(tail.rays.shadow, plain.rays.shadow) << what;
        EXPECT_EQ(tail.nonfinite, plain.nonfinite) << what;
        ASSERT_EQ(tail.alive_per_bounce.size(), size_t(tail.stages.tail_from) + 1) << what;
        EXPECT_TRUE(std::equal(tail.alive_per_bounce.begin(), tail.alive_per_bounce.end(),
                               plain.alive_per_bounce.begin()))
            << what;
        std::printf("%-36s tail from bounce %u: %.3f ms of the sample, identical %.4f\n",
                    what.c_str(), tail.stages.tail_from, tail.stages.tail,
                    identical_fraction(a, b));
      }
    }
  }
}

// The fused trace stage runs a bounce's shadow stage and the next bounce's intersect stage in
// one launch (also when the tail takes the next bounce: the tail then starts by shading the
// traced hits): the same work, so the same image (each pixel's film sum is added once per
// sample, whatever the order of launches), the same queues and the same ray counts as the two
// stages apart; with a tail and without one, with and without spheres. Its time is reported
// per bounce. The stages run apart where material sorting keeps the rays at their paths' ids
// (the same shade kernel's queues, shadow queue and flat list; sorting reorders only the shade
// kernel's paths, each shaded as before). A build without the fused stage (the unfused and
// rays-at-ids variants) skips the test; one without the tail's fusion (unfused-tail) checks the
// tail traced by the tail itself.
TEST(Gpu, FusedTraceStageIsTheTwoStages) {
  REQUIRE_GPU(gpu);
  for (const char* name : {"cornell_box.json", "cornell_spheres.json", "smallpt.json"}) {
    RenderSettings rs;
    const Scene s = small_asset(name, &rs);
    rs.max_depth = 8;  // every bounce staged without a tail (no early stop before the last)
    const CompiledScene cs(s, rs.width, rs.height);
    ASSERT_TRUE(cs.flat_list().enabled) << name;
    for (const float tail : {0.0f, 0.3f}) {
      GpuOptions o;
      o.kernel = KernelMode::kWavefront;
      o.compaction = Compaction::kShade;
      o.tail_fraction = tail;
      FrameStats fused, apart;
      auto run = [&](bool fuse, FrameStats* st) {
        o.sort_materials = !fuse;
        gpu->set_gpu_options(o);
        gpu->set_scene(cs, make_integrator_settings(rs));
        gpu->render(1);  // the tail's estimate
        *st = gpu->render(31);
        return gpu->image();
      };
      const ImageRGB a = run(true, &fused);
      const ImageRGB b = run(false, &apart);
      ASSERT_TRUE(fused.gpu.has_value() && apart.gpu.has_value());
      if (!fused.gpu->fused_trace)
        GTEST_SKIP() << "no fused trace stage in this build: " << fused.gpu->describe();
      const bool tail_fused = fused.gpu->fused_tail;
      const std::string what = std::string(name) + (tail == 0.0f ? ", no tail"
                                                    : tail_fused ? ", tail"
                                                                 : ", tail not fused");
      EXPECT_TRUE(fused.stages.fused_trace) << what;
      EXPECT_FALSE(apart.gpu->rays_at_slots) << what;
      EXPECT_FALSE(apart.stages.fused_trace) << what;
      EXPECT_EQ(apart.stages.trace, 0.0) << what;
      // Bounce 0 is traced alone; each later bounce by the fused stage, with fused_tail the
      // tail's too (which then only shades), so that no shadow stage runs alone but the last
      // bounce's without a tail.
      const std::vector<BounceTimes>& t = fused.stages.bounces;
      EXPECT_EQ(fused.stages.tail_from, apart.stages.tail_from) << what;
      if (tail == 0.0f || !tail_fused) {
        if (tail == 0.0f) EXPECT_EQ(fused.stages.tail_from, 0u) << what;
        else ASSERT_GT(fused.stages.tail_from, 0u) << what;
        EXPECT_EQ(t.size(), tail == 0.0f ? size_t(rs.max_depth) : fused.stages.tail_from) << what;
        EXPECT_EQ(apart.stages.bounces.size(), t.size()) << what;
        EXPECT_GT(t.back().shadow, 0.0) << what;
      } else {
        ASSERT_GT(fused.stages.tail_from, 0u) << what;
        EXPECT_GT(fused.stages.tail, 0.0) << what;
        EXPECT_EQ(t.size(), size_t(fused.stages.tail_from) + 1) << what;
        EXPECT_EQ(apart.stages.bounces.size(), size_t(fused.stages.tail_from)) << what;
        EXPECT_EQ(t.back().shade, 0.0) << what << ": the tail shades its bounce";
      }
      ASSERT_GT(t.size(), 1u) << what;
      EXPECT_GT(fused.stages.trace, 0.0) << what;
      EXPECT_GT(t[0].intersect, 0.0) << what;
      for (size_t k = 1; k < t.size(); ++k) {
        EXPECT_EQ(t[k].intersect, 0.0) << what << " bounce " << k;
        EXPECT_GT(t[k].trace, 0.0) << what << " bounce " << k;
        EXPECT_EQ(t[k - 1].shadow, 0.0) << what << " bounce " << k - 1;
      }
      const double same = identical_fraction(a, b);
      std::printf("%-28s fused trace against two stages: identical %.4f, trace %.3f ms\n",
                  what.c_str(), same, fused.stages.trace);
      EXPECT_EQ(same, 1.0) << what;
      EXPECT_EQ(fused.rays.extension, apart.rays.extension) << what;
      EXPECT_EQ(fused.rays.shadow, apart.rays.shadow) << what;
      EXPECT_EQ(fused.nonfinite, apart.nonfinite) << what;
      EXPECT_EQ(fused.alive_per_bounce, apart.alive_per_bounce) << what;
      EXPECT_EQ(fused.shadow_per_bounce, apart.shadow_per_bounce) << what;
      EXPECT_EQ(fused.finished_per_bounce, apart.finished_per_bounce) << what;
    }
  }
}

TEST(Gpu, FirstBounceCacheNeedsAFixedCamera) {
  REQUIRE_GPU(gpu);
  const Scene s = builtin_default_scene();
  RenderSettings rs = s.settings;
  rs.width = 64;
  rs.height = 64;
  rs.jitter = false;
  GpuOptions on, off;
  on.kernel = off.kernel = KernelMode::kWavefront;
  off.first_bounce_cache = false;
  FrameStats st;
  const ImageRGB a = render_gpu(*gpu, s, rs, 32, on, &st);
  EXPECT_EQ(st.note.find("disabled"), std::string::npos) << st.note;
  ASSERT_TRUE(st.gpu.has_value());
  EXPECT_TRUE(st.gpu->options.first_bounce_cache) << st.gpu->describe();
  const ImageRGB b = render_gpu(*gpu, s, rs, 32, off);
  EXPECT_GT(identical_fraction(a, b), 0.999);
  rs.jitter = true;
  render_gpu(*gpu, s, rs, 4, on, &st);
  EXPECT_NE(st.note.find("jitter"), std::string::npos) << "the reason must be reported";
  ASSERT_TRUE(st.gpu.has_value());
  ASSERT_NE(st.gpu->find("first_bounce_cache"), nullptr) << st.gpu->describe();
  EXPECT_NE(st.gpu->find("first_bounce_cache")->reason.find("jitter"), std::string::npos);
}

TEST(Gpu, ResetIsComplete) {
  REQUIRE_GPU(gpu);
  const Scene s = builtin_default_scene();
  RenderSettings rs = s.settings;
  rs.width = 48;
  rs.height = 32;
  const CompiledScene cs(s, rs.width, rs.height);
  gpu->set_scene(cs, make_integrator_settings(rs));
  gpu->render(8);
  const ImageRGB a = gpu->image();
  gpu->render(8);
  gpu->reset();
  EXPECT_EQ(gpu->samples_done(), 0u);
  gpu->render(8);
  EXPECT_EQ(identical_fraction(gpu->image(), a), 1.0);
}

// Distributed rendering's ranks render any ranges of sample numbers (set_next_sample): out of
// order, or starting with an odd one (its film written first), they sum to the contiguous
// render, on both designs, and the CPU's ranges match the GPU's.
TEST(Gpu, SampleRangesInAnyOrderAddUpToOneRender) {
  REQUIRE_GPU(gpu);
  const Scene s = builtin_default_scene();
  RenderSettings rs = s.settings;
  rs.width = 48;
  rs.height = 32;
  const CompiledScene cs(s, rs.width, rs.height);
  for (KernelMode mode : {KernelMode::kWavefront, KernelMode::kMegakernel}) {
    GpuOptions o = s.gpu;
    o.kernel = mode;
    gpu->set_gpu_options(o);
    gpu->set_scene(cs, make_integrator_settings(rs));
    gpu->set_aovs(true);
    gpu->render(9);
    const ImageRGB whole = gpu->image();
    ImageRGB we, wo;
    gpu->half_images(&we, &wo);
    gpu->reset();
    for (SampleRange r : {SampleRange{5, 4}, SampleRange{0, 3}, SampleRange{3, 2}}) {
      gpu->set_next_sample(r.first);
      gpu->render(r.count);
    }
    EXPECT_EQ(gpu->samples_done(), 9u);
    EXPECT_EQ(gpu->half_samples(0), 5u);
    EXPECT_EQ(gpu->half_samples(1), 4u);
    const ImageRGB shuffled = gpu->image();
    ASSERT_EQ(shuffled.pixels.size(), whole.pixels.size());
    for (size_t i = 0; i < whole.pixels.size(); ++i)
      ASSERT_NEAR(shuffled.pixels[i], whole.pixels[i], 1e-5f * (1.0f + whole.pixels[i])) << i;
    // One odd-numbered sample alone: the odd film holds it, the even one nothing.
    gpu->reset();
    gpu->set_next_sample(7);
    gpu->render(1);
    ImageRGB e, od;
    gpu->half_images(&e, &od);
    const ImageRGB only = gpu->image();
    EXPECT_EQ(gpu->half_samples(0), 0u);
    EXPECT_EQ(identical_fraction(only, od), 1.0) << "the mean of one odd sample is that sample";
    std::vector<uint32_t> rgba;
    gpu->display_rgba8(rgba, 1.0f, ToneMap::kNone);
    size_t lit = 0;
    for (uint32_t p : rgba) lit += (p & 0xffffffu) != 0;
    EXPECT_GT(lit, rgba.size() / 2) << "the display reads the film that holds the sample";
    // The CPU renders sample 7 the same.
    CpuRenderer cpu(2);
    cpu.set_scene(cs, make_integrator_settings(rs));
    cpu.set_next_sample(7);
    cpu.render(1);
    const Accumulation acc = accumulation_of(*gpu, rs.width, rs.height);
    EXPECT_EQ(acc.count[1], 1u);
    EXPECT_GT(identical_fraction(only, cpu.image()), 0.9) << "CPU and GPU trace sample 7 apart";
  }
}

TEST(Gpu, TooLargeForTheDeviceSaysWhatItNeedsAndHasFree) {
  REQUIRE_GPU(gpu);
  const Scene s = builtin_default_scene();
  RenderSettings rs = s.settings;
  rs.width = 48;
  rs.height = 32;
  const CompiledScene cs(s, rs.width, rs.height);
  gpu->set_scene(cs, make_integrator_settings(rs));
  RenderSettings huge = rs;
  huge.width = 65536;  // 2^31 pixels: over 400 GiB of path state
  huge.height = 32768;
  try {
    gpu->set_settings(make_integrator_settings(huge));
    FAIL() << "a 65536x32768 image fitted in GPU memory";
  } catch (const std::runtime_error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("65536x32768 image needs"), std::string::npos) << m;
    EXPECT_NE(m.find("free of"), std::string::npos) << m;
  }
  // Nothing was allocated: the renderer goes on at a size that fits.
  gpu->set_settings(make_integrator_settings(rs));
  gpu->render(2);
  EXPECT_EQ(gpu->samples_done(), 2u);
}

TEST(Gpu, SubsurfaceSlabMatchesAnalyticAlbedo) {
  // The CPU test's semi-infinite slab seen from straight above through a 0.2 degree lens: every
  // camera ray arrives at normal incidence, so the image mean is R for light at normal incidence.
  REQUIRE_GPU(gpu);
  const struct {
    float albedo;
    double expected;
  } cases[] = {{0.5f, 0.1152}, {0.9f, 0.4150}, {0.99f, 0.7527}};
  // The smooth exit by BSDF sampling, and the diffuse exit with light sampling at the exit
  // point (under the uniform sky the exit's direction does not change the total).
  for (bool smooth : {true, false})
  for (const auto& c : cases) {
    Scene s = slab_scene(c.albedo, 1, smooth);
    s.camera.position = vec3(0.0f, 1.0f, 0.0f);
    s.camera.look_at = vec3(0.0f);
    s.camera.up = vec3(0.0f, 0.0f, 1.0f);
    s.camera.vfov_deg = 0.2f;
    RenderSettings rs;
    rs.width = rs.height = 64;
    rs.nee = !smooth;
    rs.mis = !smooth;
    rs.max_depth = 64;
    std::vector<double> means;
    for (KernelMode mode : {KernelMode::kWavefront, KernelMode::kMegakernel}) {
      for (uint32_t b = 0; b < 8; ++b) {
        rs.seed = 1000 + b;
        GpuOptions o;
        o.kernel = mode;
        FrameStats st;
        const ImageRGB img = render_gpu(*gpu, s, rs, 64, o, &st);
        double m = 0;
        for (size_t i = 0; i < img.pixels.size(); i += 3) m += img.pixels[i];
        means.push_back(m / (img.pixels.size() / 3));
        EXPECT_EQ(st.rays.medium_leaks, 0u);
      }
    }
    double mean = 0, var = 0;
    for (double m : means) mean += m / means.size();
    for (double m : means) var += (m - mean) * (m - mean) / (means.size() - 1);
    const double se = std::sqrt(var / means.size());
    std::printf("GPU slab, %s exit, albedo %.2f: R = %.4f +- %.4f (analytic %.4f)\n",
                smooth ? "smooth" : "diffuse (NEE)", c.albedo, mean, se, c.expected);
    EXPECT_NEAR(mean, c.expected, 4.0 * se + 0.004) << "albedo " << c.albedo;
  }
}

TEST(Gpu, SubsurfaceSlabUnderDiffuseLight) {
  // Under uniform diffuse light the slab reflects 2 * integral of R(mu) mu dmu, where R(mu) is the
  // albedo at incidence cos(theta) = mu. By reciprocity R(mu) is what a camera sees looking at the
  // slab from that angle under a uniform sky, so 8 narrow cameras at Gauss-Legendre angles give
  // the diffuse albedo (0.1465, 0.4780, 0.7946 analytic).
  REQUIRE_GPU(gpu);
  static const double kNodes[8] = {0.0198550717512319, 0.1016667612931866, 0.2372337950418355,
                                   0.4082826787521751, 0.5917173212478249, 0.7627662049581645,
                                   0.8983332387068134, 0.9801449282487681};
  static const double kWeights[8] = {0.0506142681451881, 0.1111905172266872, 0.1568533229389436,
                                     0.1813418916891810, 0.1813418916891810, 0.1568533229389436,
                                     0.1111905172266872, 0.0506142681451881};
  const struct {
    float albedo;
    double expected;
  } cases[] = {{0.5f, 0.1465}, {0.9f, 0.4780}, {0.99f, 0.7946}};
  for (const auto& c : cases) {
    Scene s = slab_scene(c.albedo, 1);
    s.materials[1].material.emission = vec3(1.0f);  // the uniform sky
    double r = 0.0, var = 0.0;
    for (int k = 0; k < 8; ++k) {
      const double mu = kNodes[k];
      const float sin_t = float(std::sqrt(1.0 - mu * mu));
      s.camera.look_at = vec3(0.0f);
      s.camera.position = vec3(sin_t, float(mu), 0.0f);
      s.camera.up = vec3(0.0f, 0.0f, 1.0f);
      s.camera.vfov_deg = 0.05f;
      RenderSettings rs;
      rs.width = rs.height = 32;
      rs.nee = false;
      rs.mis = false;
      rs.max_depth = 64;
      std::vector<double> means;
      for (uint32_t b = 0; b < 8; ++b) {
        rs.seed = 2000 + 10 * k + b;
        GpuOptions o;
        o.kernel = KernelMode::kMegakernel;
        const ImageRGB img = render_gpu(*gpu, s, rs, 64, o);
        double m = 0;
        for (size_t i = 0; i < img.pixels.size(); i += 3) m += img.pixels[i];
        means.push_back(m / (img.pixels.size() / 3));
      }
      double mean = 0, v = 0;
      for (double m : means) mean += m / means.size();
      for (double m : means) v += (m - mean) * (m - mean) / (means.size() - 1) / means.size();
      r += 2.0 * kWeights[k] * mu * mean;
      var += (2.0 * kWeights[k] * mu) * (2.0 * kWeights[k] * mu) * v;
    }
    std::printf("GPU slab albedo %.2f, diffuse light: R = %.4f +- %.4f (analytic %.4f)\n",
                c.albedo, r, std::sqrt(var), c.expected);
    EXPECT_NEAR(r, c.expected, 4.0 * std::sqrt(var) + 0.004) << "albedo " << c.albedo;
  }
}

TEST(Gpu, NewMaterialsConserveEnergyInAFurnace) {
  // The CPU's furnaces of issue 21's materials on both GPU designs: inside a sphere that emits 1
  // with albedo 0.5 (radiance 2 everywhere), a white plastic (smooth clear coat over albedo 1) and
  // thin sheets with reflectance + transmittance = 1 change nothing; an anisotropic gold sphere
  // (which absorbs) must darken the pixels that see it, as on the CPU.
  REQUIRE_GPU(gpu);
  auto furnace = [] {
    Scene s;
    s.source = "<gpu furnace>";
    s.materials.push_back({"wall", diffuse(vec3(0.5f), vec3(1.0f), true)});
    s.spheres.push_back({vec3(0.0f), 1.0f, 0});
    s.camera.position = vec3(0.0f);
    s.camera.look_at = vec3(0.0f, 0.0f, -1.0f);
    s.camera.vfov_deg = 90.0f;
    return s;
  };
  Scene plastic = furnace();
  Material coat;
  coat.type = MaterialType::kCoatedDiffuse;
  coat.albedo = vec3(1.0f);
  plastic.materials.push_back({"plastic", coat});
  plastic.spheres.push_back({vec3(0.0f, 0.0f, -0.5f), 0.35f, 1});
  Scene sheets = furnace();
  Material sheet;
  sheet.type = MaterialType::kDiffuseTransmission;
  sheet.albedo = vec3(0.3f, 0.6f, 0.9f);
  sheet.transmittance = vec3(0.7f, 0.4f, 0.1f);
  sheets.materials.push_back({"sheet", sheet});
  add_quad(sheets.mesh, vec3(-0.3f, -0.3f, -0.6f), vec3(0.6f, 0.0f, 0.0f), vec3(0.0f, 0.6f, 0.15f),
           1);
  Scene gold = furnace();
  Material au;
  au.type = MaterialType::kConductor;
  au.flags = kMaterialConductorIor;
  au.albedo = vec3(1.0f);
  au.eta = vec3(0.1757f, 0.3985f, 1.5856f);
  au.k = vec3(4.8935f, 2.3672f, 1.7183f);
  au.roughness = 0.2f;
  au.roughness_v = 0.6f;
  gold.materials.push_back({"gold", au});
  gold.spheres.push_back({vec3(0.0f, 0.0f, -0.5f), 0.35f, 1});
  RenderSettings rs;
  rs.width = rs.height = 32;
  rs.max_depth = 96;
  rs.sampler = kSamplerRandom;
  for (KernelMode mode : {KernelMode::kWavefront, KernelMode::kMegakernel}) {
    GpuOptions o;
    o.kernel = mode;
    for (const Scene* s : {&plastic, &sheets}) {
      const ImageRGB img = render_gpu(*gpu, *s, rs, 1024, o);
      double mean = 0.0, worst = 0.0;
      for (float v : img.pixels) {
        mean += v / img.pixels.size();
        worst = std::max(worst, std::abs(double(v) - 2.0));
      }
      std::printf("%s furnace, %s: mean %.4f, worst pixel off by %.4f\n",
                  s == &plastic ? "plastic" : "sheets",
                  mode == KernelMode::kWavefront ? "wavefront" : "megakernel", mean, worst);
      EXPECT_NEAR(mean, 2.0, 0.01);
      EXPECT_LT(worst, 0.2);
    }
    const ImageRGB img = render_gpu(*gpu, gold, rs, 256, o);
    const size_t centre = (size_t(rs.height / 2) * rs.width + rs.width / 2) * 3;
    EXPECT_LT(img.pixels[centre + 2], 1.0f) << "gold reflects little blue";
    EXPECT_GT(img.pixels[centre], img.pixels[centre + 2]);
  }
}

TEST(Gpu, KernelAutoChoosesAndSaysWhich) {
  REQUIRE_GPU(gpu);
  const Scene s = builtin_default_scene();
  RenderSettings rs = s.settings;
  rs.width = 256;
  rs.height = 256;
  const CompiledScene cs(s, rs.width, rs.height);
  gpu->set_gpu_options(GpuOptions{});
  gpu->set_scene(cs, make_integrator_settings(rs));
  const FrameStats st = gpu->render(8);
  EXPECT_NE(st.note.find("kernel auto chose"), std::string::npos) << st.note;
  std::printf("%s\n", st.note.c_str());
  // Auto kept the design its own timing found faster (ties go to the wavefront).
  const AutoKernelTimes t = gpu->auto_kernel_times();
  ASSERT_GT(t.wavefront_ms, 0.0);
  ASSERT_GT(t.megakernel_ms, 0.0);
  EXPECT_EQ(gpu->chosen_kernel(), t.wavefront_ms <= t.megakernel_ms ? "wavefront" : "megakernel")
      << t.wavefront_ms << " ms wavefront, " << t.megakernel_ms << " ms megakernel per sample";
}

// Path guiding on the GPU (integrator/guide.h): the wavefront trains the guide in its stages
// (8 builds, the cells the CPU's guide learns), and guided renders keep the CPU's mean (batches of
// independent seeds, each through training and beyond, against the CPU's unguided statistics)
// with less noise where the light shines through glass (assets/scenes/glass_lamp.json: light
// sampling reaches no light there). Every megakernel request runs the wavefront.
// Path guiding's calibration measures a block's noise on the device (film.cu) as the CPU does
// (guide_block_noise): the same sum for the same films.
TEST(Gpu, CalibrationNoiseMatchesTheHost) {
  REQUIRE_GPU(gpu);
  const uint32_t n = 10000;
  std::vector<float4> a(n), b(n), then(n), base(n);
  std::vector<double> now_h(3 * size_t(n)), then_h(3 * size_t(n)), base_h(3 * size_t(n));
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 4.0f);
  for (uint32_t i = 0; i < n; ++i) {
    float fa[3], fb[3], ft[3], fm[3];
    for (int c = 0; c < 3; ++c) {
      const bool black = c == 2 && i % 7 == 0;  // some black channels
      fm[c] = black ? 0.0f : 64.0f * u(rng);
      ft[c] = fm[c] + (black ? 0.0f : 2.0f * u(rng));
      fa[c] = 0.5f * ft[c] + u(rng);
      fb[c] = 0.5f * ft[c] + (i % 5 == 0 ? 8.0f : u(rng));
      now_h[3 * i + c] = double(fa[c]) + double(fb[c]);
      then_h[3 * i + c] = ft[c];
      base_h[3 * i + c] = fm[c];
    }
    a[i] = make_float4(fa[0], fa[1], fa[2], 0.0f);
    b[i] = make_float4(fb[0], fb[1], fb[2], 0.0f);
    then[i] = make_float4(ft[0], ft[1], ft[2], 0.0f);
    base[i] = make_float4(fm[0], fm[1], fm[2], 0.0f);
  }
  DeviceBuffer<float4> d_a, d_b, d_then, d_base, d_sum(n);
  d_a.upload(a);
  d_b.upload(b);
  d_then.upload(then);
  d_base.upload(base);
  DeviceBuffer<double> d_noise(1);
  launch_block_noise(d_a.get(), d_b.get(), d_then.get(), d_base.get(), 1.0f / 8.0f, 1.0f / 64.0f,
                     n, d_noise.get(), nullptr);
  std::vector<double> noise;
  d_noise.download(noise);
  const double host = guide_block_noise(now_h.data(), then_h.data(), base_h.data(), 1.0 / 8.0,
                                        1.0 / 64.0, now_h.size());
  EXPECT_NEAR(noise[0], host, 1e-4 * host);
  // The films' sum that the blocks start from.
  launch_sum_films(d_a.get(), d_b.get(), d_sum.get(), n, nullptr);
  std::vector<float4> sum;
  d_sum.download(sum);
  EXPECT_NEAR(sum[5].y, a[5].y + b[5].y, 1e-5f * (a[5].y + b[5].y));
}

TEST(Gpu, GuidingTrainsKeepsTheMeanAndLowersNoise) {
  REQUIRE_GPU(gpu);
  const Scene s = load_scene(source_dir() + "/assets/scenes/glass_lamp.json");
  RenderSettings rs = s.settings;
  rs.width = 64;
  rs.height = 64;
  rs.seed = 5;
  const PixelStats cpu = render_pixel_stats(s, rs, 2048);
  // The CPU's own guide, for the learned cells.
  RenderSettings guided_rs = rs;
  guided_rs.guiding = true;
  const CompiledScene cs(s, rs.width, rs.height);
  CpuRenderer cpu_r;
  cpu_r.set_scene(cs, make_integrator_settings(guided_rs));
  cpu_r.render(kGuideTrainSamples);
  const GuideStatus cpu_guide = cpu_r.guide_status();
  GpuOptions o;
  o.kernel = KernelMode::kMegakernel;  // overridden: guiding runs the wavefront
  for (int guided = 0; guided < 2; ++guided) {
    std::vector<ImageRGB> batches;
    FrameStats st;
    for (uint32_t b = 0; b < 16; ++b) {
      RenderSettings other = guided ? guided_rs : rs;
      other.seed = 100 + b;
      batches.push_back(render_gpu(*gpu, s, other, 384, GpuOptions(), &st));
      if (guided && b == 0) {
        const GuideStatus g = gpu->guide_status();
        std::printf("GPU guide: %s; CPU guide: %s\n", g.describe().c_str(),
                    cpu_guide.describe().c_str());
        EXPECT_EQ(g.builds, 8u);
        EXPECT_TRUE(g.frozen());
        EXPECT_EQ(g.cells, cpu_guide.cells);
        EXPECT_NEAR(double(g.learned_cells), double(cpu_guide.learned_cells),
                    0.05 * cpu_guide.learned_cells + 5);
        // The shares are chosen from noisy estimates: the same cells guide within a margin.
        EXPECT_NEAR(double(g.guiding_cells), double(cpu_guide.guiding_cells),
                    0.2 * cpu_guide.guiding_cells + 10);
        EXPECT_NE(st.specialization.find("path guiding"), std::string::npos) << st.specialization;
        // Calibrated after training (guide_host.h): 8 unguided and 8 guided samples measured.
        ASSERT_TRUE(g.calibration.done()) << g.describe();
        EXPECT_EQ(g.calibration.samples[0], kGuideCalibrationSamples / 2);
        EXPECT_GT(g.calibration.time_ratio(), 0.0);
        EXPECT_GT(g.calibration.variance_ratio(), 0.0);
        if (!g.retired()) EXPECT_EQ(st.kernel, "wavefront");
      }
    }
    if (guided) {  // a megakernel request renders guided in the wavefront too
      FrameStats mst;
      render_gpu(*gpu, s, guided_rs, 4, o, &mst);
      EXPECT_EQ(mst.kernel, "wavefront");
      ASSERT_TRUE(mst.gpu.has_value());
      EXPECT_NE(mst.gpu->find("kernel"), nullptr);
    }
    const BlockZ z = block_z(batches, cpu);
    std::printf("%s: independent chi2/dof %.3f (limit %.3f)\n", guided ? "guided" : "unguided",
                z.chi2_per_dof, z.limit);
    EXPECT_LT(z.chi2_per_dof, z.limit) << (guided ? "guided" : "unguided");
  }
  // Noise at 256 x 256 (enough pixels to fill the guide's 10 x 10 x 10 grid): the spread of 8
  // batches' pixel values, guided against unguided, at 384 spp each.
  double noise[2] = {0, 0};
  for (int guided = 0; guided < 2; ++guided) {
    RenderSettings big = guided ? guided_rs : rs;
    big.width = big.height = 256;
    std::vector<ImageRGB> batches;
    for (uint32_t b = 0; b < 8; ++b) {
      big.seed = 200 + b;
      batches.push_back(render_gpu(*gpu, s, big, 384, GpuOptions()));
    }
    noise[guided] += batch_variance(batches);
  }
  std::printf("variance, guided / unguided at 384 spp, 256 x 256: %.3f\n", noise[1] / noise[0]);
  EXPECT_LT(noise[1], 0.85 * noise[0]);
}

// Manifold NEE (render.mnee) in the wavefront's mnee stage, 16 GPU batches of 256 spp at 64x64:
// their means against the CPU's (block z-test of the batches against 2,048 CPU samples of the
// plain estimator, or of manifold NEE's own where plain's rare caustic paths are too heavy a tail
// for the test at this size), and their variance against the plain GPU batches' (summed, or
// relative to the pixel's mean as relMSE weighs it). A megakernel request runs the wavefront.
void expect_gpu_mnee(const std::string& scene, bool cpu_mnee, bool relative, double limit,
                     const std::function<void(Scene&)>& edit = nullptr) {
  REQUIRE_GPU(gpu);
  RenderSettings rs;
  const Scene s = caustic_asset(scene, edit, &rs);
  RenderSettings mnee_rs = rs;
  mnee_rs.mnee = true;
  const PixelStats cpu = render_pixel_stats(s, cpu_mnee ? mnee_rs : rs, 2048);
  GpuOptions mega;
  mega.kernel = KernelMode::kMegakernel;
  FrameStats st;
  render_gpu(*gpu, s, mnee_rs, 4, mega, &st);
  EXPECT_EQ(st.kernel, "wavefront");
  EXPECT_NE(st.specialization.find("manifold NEE"), std::string::npos) << st.specialization;
  // The mnee stage ran: nearly every camera vertex (diffuse or seeing the lamp's light through
  // glass or in a ball) queued a request.
  ASSERT_FALSE(st.mnee_per_bounce.empty());
  EXPECT_GT(st.mnee_per_bounce[0], uint32_t(rs.width * rs.height / 2));
  double noise[2] = {0, 0};
  for (int on = 0; on < 2; ++on) {
    std::vector<ImageRGB> batches;
    for (uint32_t b = 0; b < 16; ++b) {
      RenderSettings r = on ? mnee_rs : rs;
      r.seed = 300 + b;
      batches.push_back(render_gpu(*gpu, s, r, 256, GpuOptions()));
    }
    if (on == int(cpu_mnee)) {
      const BlockZ z = block_z(batches, cpu);
      std::printf("%s %s: independent chi2/dof %.3f (limit %.3f)\n", scene.c_str(),
                  on ? "mnee" : "plain", z.chi2_per_dof, z.limit);
      EXPECT_LT(z.chi2_per_dof, z.limit) << scene << (on ? " mnee" : " plain");
    }
    noise[on] += batch_variance(batches, relative ? &cpu : nullptr);
  }
  std::printf("%s: %svariance, mnee / plain at 256 spp, 64 x 64: %.3f\n", scene.c_str(),
              relative ? "relative " : "", noise[1] / noise[0]);
  EXPECT_LT(noise[1], limit * noise[0]) << scene;
}

// The lamp behind glass (chains through flat glass): the plain CPU's mean, 0.35x the variance.
TEST(Gpu, ManifoldNeeKeepsTheMeanAndLowersNoise) {
  expect_gpu_mnee("glass_lamp.json", false, false, 0.5);
}

// The glass and mirror balls (every chain through and off the spheres, found exactly): the CPU's
// manifold NEE mean, 0.39x the relative variance on the CPU at this size.
TEST(Gpu, ManifoldNeeThroughBallsAgreesWithTheCpu) {
  expect_gpu_mnee("cornell_spheres.json", true, true, 0.6);
}

// A scene of mirrors alone (the lamp's glass box made a mirror: the room lit by the lamp's
// reflection off its top, on the ceiling) runs the caustic kernels too (reflections off the
// box's flat faces): the CPU's manifold NEE mean, less variance than plain (0.71x on an H100: most
// of the image is lit by the ceiling, whose light manifold NEE connects only at the ceiling
// itself; the plain kernels' would be 1x).
TEST(Gpu, ManifoldNeeOffMirrorsAloneAgreesWithTheCpu) {
  expect_gpu_mnee("glass_lamp.json", true, false, 0.85, [](Scene& scene) {
    test::retype_material(scene, "glass", MaterialType::kMirror);
  });
}

// The pool (a wavy water surface of 2,048 triangles with interpolated normals over the floor):
// chains through one refraction, walked on the mesh by the mnee stage's own rays; the CPU's
// manifold NEE mean, less relative variance than plain (0.11x on the CPU at 24x24).
TEST(Gpu, ManifoldNeeUnderAWavySurfaceAgreesWithTheCpu) {
  expect_gpu_mnee("pool.json", true, true, 0.5);
}

// Light tracing (render.light_tracing): the light kernel after each sample's camera paths, in
// the megakernel (even batches) and the wavefront (odd ones); 16 batches of 256 spp at 64x64
// against the CPU's plain path tracing (block z-test of the batches against 2,048 CPU samples)
// and their relative variance against the plain GPU batches'.
void expect_gpu_light_tracing(const std::string& scene, double limit,
                              const std::function<void(Scene&)>& edit = nullptr) {
  REQUIRE_GPU(gpu);
  RenderSettings rs;
  const Scene s = caustic_asset(scene, edit, &rs);
  RenderSettings lt_rs = rs;
  lt_rs.light_tracing = true;
  const PixelStats cpu = render_pixel_stats(s, rs, 2048);
  double noise[2] = {0, 0};
  for (int on = 0; on < 2; ++on) {
    std::vector<ImageRGB> batches;
    for (uint32_t b = 0; b < 16; ++b) {
      RenderSettings r = on ? lt_rs : rs;
      r.seed = 300 + b;
      GpuOptions o;
      o.kernel = b % 2 ? KernelMode::kWavefront : KernelMode::kMegakernel;
      FrameStats st;
      batches.push_back(render_gpu(*gpu, s, r, 256, o, &st));
      if (on) EXPECT_GT(st.stages.light, 0.0) << "the light kernel ran";
      else EXPECT_EQ(st.stages.light, 0.0);
    }
    const BlockZ z = block_z(batches, cpu);
    std::printf("%s %s: chi2/dof against the CPU's plain %.3f (limit %.3f)\n", scene.c_str(),
                on ? "light tracing" : "plain", z.chi2_per_dof, z.limit);
    if (on) EXPECT_LT(z.chi2_per_dof, z.limit) << scene;
    noise[on] += batch_variance(batches, &cpu);
  }
  std::printf("%s: relative variance, light tracing / plain at 256 spp, 64 x 64: %.3f\n",
              scene.c_str(), noise[1] / noise[0]);
  EXPECT_LT(noise[1], limit * noise[0]) << scene;
}

// The lamp behind glass: its room is lit through the slab, all of it light-traced.
TEST(Gpu, LightTracingKeepsTheMeanAndLowersNoise) {
  expect_gpu_light_tracing("glass_lamp.json", 0.2);
}

// The glass and mirror balls: their caustics light-traced.
TEST(Gpu, LightTracingOfTheBallsAgreesWithTheCpu) {
  expect_gpu_light_tracing("cornell_spheres.json", 0.8);
}

// The rough materials (gold balls of roughness 0.05 and 0.25, a frosted glass ball): light paths
// from their glossy casters, aimed at the balls (SceneView::light_targets), a quarter as many
// as pixels.
TEST(Gpu, LightTracingOfGlossyCastersAgreesWithTheCpu) {
  expect_gpu_light_tracing("rough_materials.json", 0.6);
}

// The same beside a point light, a spot, a sun and a sky (test::add_other_lights): at a glossy
// caster the path tracer samples those with MIS and leaves the area light to the light tracer
// (the wavefront keeps that mark as a negative prev_pdf between bounces). The mean; the variance
// bounded only from above (the lamp's share of the light choices is small here).
TEST(Gpu, LightTracingOfGlossyCastersBesideOtherLightsAgreesWithTheCpu) {
  expect_gpu_light_tracing("rough_materials.json", 2.0,
                           [](Scene& s) { test::add_other_lights(s); });
}

// The water tank seen through its front (tank.json): light paths joined to the camera through
// the window's refraction (window_path, rays traced in the light kernel).
TEST(Gpu, LightTracingThroughAWindowAgreesWithTheCpu) {
  expect_gpu_light_tracing("tank.json", 0.6);
}

// The balls through a thin lens and a tent filter of radius 1.5 (the light kernel's general
// variant: lens points, splats over several pixels).
TEST(Gpu, LightTracingThroughALensAgreesWithTheCpu) {
  expect_gpu_light_tracing("cornell_spheres.json", 0.9, [](Scene& s) {
    s.camera.aperture_radius = 20.0f;
    s.settings.filter = PixelFilter::kTent;
    s.settings.filter_radius = 1.5f;
  });
}

// Glass balls placed as instances (the light kernel's variant with the BVH's second level).
TEST(Gpu, LightTracingThroughInstancesAgreesWithTheCpu) {
  expect_gpu_light_tracing("cornell_box.json", 0.9,
                           [](Scene& s) { s = test::instanced_scene(true); });
}

}  // namespace
