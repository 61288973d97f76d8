// The resolution of the GPU switches (integrator/gpu_options.h), without a GPU: every combination
// of the user's switches on every kind of scene that a rule looks at, checked against the rules
// that the CUDA backend's code relies on, with one reason for every value the resolution changes.
#include "integrator/gpu_options.h"
#include "bvh/bvh8.h"
#include "scene/scene.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <map>

#include "core/features.h"

namespace {
using namespace tracer;

const char* on_off(bool b) {
  return b ? "on" : "off";
}

std::string fraction_text(float f) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", double(f));
  return buf;
}

// Every request: kernel x compaction x sorting x cache x flat list x tail (0 or the default).
std::vector<GpuOptions> all_requests() {
  std::vector<GpuOptions> out;
  for (KernelMode k : {KernelMode::kAuto, KernelMode::kWavefront, KernelMode::kMegakernel})
    for (Compaction c : {Compaction::kOff, Compaction::kAuto, Compaction::kShade, Compaction::kCub})
      for (bool sort : {false, true})
        for (bool cache : {false, true})
          for (bool flat : {false, true})
            for (float tail : {0.0f, GpuOptions().tail_fraction}) {
              GpuOptions o;
              o.kernel = k;
              o.compaction = c;
              o.sort_materials = sort;
              o.first_bounce_cache = cache;
              o.flat_list = flat;
              o.tail_fraction = tail;
              out.push_back(o);
            }
  return out;
}

// Every scene a rule distinguishes: the features the rules and the specialisation read
// (textures, random walks, spheres, depth of field, specular materials, lights beyond emitters,
// instances, glass),
// with and without a flat list, a jittered camera and a lens, guiding and manifold NEE (with and
// without something to connect through).
std::vector<GpuSceneTraits> all_scenes() {
  const uint32_t bits[] = {kFeatureTextures, kFeatureSubsurface, kFeatureSpheres,
                           kFeatureDepthOfField, kFeatureMirror, kFeaturePointLights,
                           kFeatureInstances, kFeatureDielectric};
  std::vector<GpuSceneTraits> out;
  for (uint32_t mask = 0; mask < 256; ++mask)
    for (int other = 0; other < 128; ++other) {
      GpuSceneTraits t;
      for (int i = 0; i < 8; ++i)
        if (mask & (1u << i)) t.features |= bits[i];
      // Scenes with instances have no flat list (CompiledScene).
      if ((t.features & kFeatureInstances) && (other & 1)) continue;
      t.flat_available = other & 1;
      t.jitter = other & 2;
      t.depth_of_field = other & 4;
      t.bvh8_available = other & 8;
      t.guiding = other & 16;
      t.mnee = other & 32;
      t.mnee_casters = other & 64;
      out.push_back(t);
    }
  return out;
}

std::string describe_case(const GpuOptions& o, const GpuSceneTraits& t) {
  return std::string("request kernel ") + kernel_mode_name(o.kernel) + ", compaction " +
         compaction_name(o.compaction) + ", sort " + on_off(o.sort_materials) + ", cache " +
         on_off(o.first_bounce_cache) + ", flat " + on_off(o.flat_list) + ", tail " +
         fraction_text(o.tail_fraction) + "; scene features 0x" + std::to_string(t.features) +
         ", flat list " + on_off(t.flat_available) + ", jitter " + on_off(t.jitter) + ", lens " +
         on_off(t.depth_of_field) + ", 8-wide tree " + on_off(t.bvh8_available) + ", guiding " +
         on_off(t.guiding) + ", mnee " + on_off(t.mnee) + ", casters " + on_off(t.mnee_casters);
}

// The user's switches, by the names the overrides use, as text.
std::map<std::string, std::string> switch_values(const GpuOptions& o) {
  return {{"kernel", kernel_mode_name(o.kernel)},
          {"compaction", compaction_name(o.compaction)},
          {"sort_materials", on_off(o.sort_materials)},
          {"first_bounce_cache", on_off(o.first_bounce_cache)},
          {"flat_list", on_off(o.flat_list)},
          {"tail_fraction", fraction_text(o.tail_fraction)}};
}

// The design paths, by the names the overrides use.
std::map<std::string, bool> path_values(const EffectiveGpuOptions& e) {
  std::map<std::string, bool> m = {{"rays_at_slots", e.rays_at_slots},
                                    {"fused_trace", e.fused_trace},
                                    {"fused_tail", e.fused_tail},
                                    {"dynamic_fetch", e.dynamic_fetch},
                                    {"specialize", e.specialize}};
  if (tracer::kBvh8Build) m["bvh8"] = e.bvh8;  // a path of bvh8 builds only
  return m;
}

// Checks one resolution; returns false after the first failed expectation (so that a broken
// rule reports a few cases, not thousands).
bool check(const GpuOptions& r, const GpuSceneTraits& t, const EffectiveGpuOptions& e) {
  const std::string what = describe_case(r, t);
  const GpuOptions& o = e.options;
  const bool textured = (t.features & kFeatureTextures) != 0;
  const bool walks = (t.features & kFeatureSubsurface) != 0;
  const bool variant = gpu_build_variant() != "default";
  bool ok = true;
  auto expect = [&](bool cond, const std::string& rule) {
    if (!cond && ok) ADD_FAILURE() << rule << "\n  " << what << "\n  -> " << e.describe();
    ok = ok && cond;
  };

  // The user's switches.
  // Manifold NEE runs where the scene has glass or smooth reflectors (elsewhere it has nothing to
  // connect through or off).
  const bool mnee = t.mnee && t.mnee_casters;
  expect(o.kernel == (t.guiding || mnee ? KernelMode::kWavefront : r.kernel),
         "the kernel is as requested (auto is decided by timing); guiding or manifold NEE: the "
         "wavefront");
  expect(o.sort_materials == r.sort_materials, "sorting is as requested");
  expect(o.compaction != Compaction::kAuto, "compaction auto is resolved");
  if (r.compaction == Compaction::kAuto)
    expect(o.compaction == (textured ? Compaction::kCub : Compaction::kShade),
           "auto: CUB on textured scenes, the shade kernel's queues elsewhere");
  else
    expect(o.compaction == r.compaction, "an explicit compaction is kept");
  expect(o.tail_fraction ==
             (o.compaction == Compaction::kOff || t.guiding || mnee ? 0.0f : r.tail_fraction),
         "a tail only with compaction (it takes its paths from a queue), never with guiding or "
         "manifold NEE");
  expect(o.first_bounce_cache == (r.first_bounce_cache && !t.jitter && !t.depth_of_field),
         "the cache never with jitter or depth of field, else as requested");
  expect(o.flat_list == (r.flat_list && t.flat_available),
         "the flat list only where the scene has one, else as requested");

  // The design paths: each only where the code that runs it can.
  expect(!e.rays_at_slots || (e.queues_in_shade() && !o.sort_materials && !walks),
         "rays at slots only over the shade kernel's queues, without sorting or random walks");
  expect(!e.fused_trace || (e.rays_at_slots && o.flat_list),
         "the fused trace stage only with rays at slots and the flat list");
  expect(!e.fused_tail || (e.fused_trace && o.tail_fraction > 0.0f),
         "the tail's fusion only with the fused trace stage and a tail");
  expect(!e.dynamic_fetch || !o.flat_list, "dynamic fetch only through the BVH");
  expect(e.spec == (e.specialize                            ? spec_for_features(t.features)
                    : (t.features & kFeatureInstances) ? kInstancesSpec
                                                       : kGeneralSpec),
         "the kernels compiled for the scene's features, or the general ones (with instances "
         "where the scene has some)");
  expect((spec_for_features(t.features) & ~e.spec) == 0, "the kernels cover the scene's features");
  expect(e.shade_spec == (mnee        ? caustic_shade_spec(e.spec)
                          : t.guiding ? guided_shade_spec(e.spec)
                                      : e.spec),
         "the caustic shade kernel with manifold NEE, the guided one with guiding, else the "
         "other stages' variant");
  expect((spec_for_features(t.features) & ~kSpecDepthOfField & ~e.shade_spec) == 0,
         "the shade kernel covers the scene's features (but the lens, which it does not read)");
  expect(!(e.spec & kSpecLights) || (e.spec & kSpecSpecular),
         "the lights' kernels are among the specular ones (no diffuse-with-lights variant)");
  expect(*spec_label(e.spec) != '\0', "the kernels have a name");
  // A variant build turns its path off everywhere.
  const std::string variants = "+" + gpu_build_variant() + "+";
  auto built = [&](const char* name) {
    return variants.find(std::string("+") + name + "+") != std::string::npos;
  };
  expect(e.bvh8 == (built("bvh8") && !o.flat_list && t.bvh8_available),
         "the 8-wide BVH in a bvh8 build wherever the BVH is walked and the scene has one");
  if (built("no-fetch")) expect(!e.dynamic_fetch, "no-fetch build: no dynamic fetch");
  if (built("general-spec")) expect(!e.specialize, "general-spec build: the general kernels");
  if (built("rays-at-ids")) expect(!e.rays_at_slots, "rays-at-ids build: no rays at slots");
  if (built("unfused")) expect(!e.fused_trace, "unfused build: no fused trace stage");
  if (built("unfused-tail")) expect(!e.fused_tail, "unfused-tail build: no tail fusion");
  if (!variant) {  // the default build runs every path wherever it can
    expect(e.rays_at_slots == (e.queues_in_shade() && !o.sort_materials && !walks),
           "default build: rays at slots wherever they can be");
    expect(e.fused_trace == (e.rays_at_slots && o.flat_list),
           "default build: the fused trace stage wherever it can run");
    expect(e.fused_tail == (e.fused_trace && o.tail_fraction > 0.0f),
           "default build: the tail's fusion wherever it can run");
    expect(e.dynamic_fetch == !o.flat_list, "default build: dynamic fetch through the BVH");
    expect(e.specialize, "default build: specialised kernels");
  }

  // Overrides: exactly one, with a reason, for each switch that differs from the request and for
  // each path that is off; none for anything else.
  std::map<std::string, int> seen;
  for (const GpuOverride& v : e.overrides) {
    ++seen[v.name];
    expect(!v.reason.empty(), "every override has a reason (" + v.name + ")");
    expect(v.requested != v.effective, "an override changes its value (" + v.name + ")");
  }
  const auto want = switch_values(r), got = switch_values(o);
  for (const auto& [name, requested] : want) {
    const GpuOverride* v = e.find(name);
    if (requested == got.at(name)) {
      expect(!v, "no override of an unchanged switch (" + name + ")");
      continue;
    }
    expect(v && seen[name] == 1, "exactly one override for the changed switch " + name);
    if (!v) continue;
    expect(!v->path && v->requested == requested && v->effective == got.at(name),
           "the override of " + name + " names the requested and the effective value");
  }
  for (const auto& [name, on] : path_values(e)) {
    const GpuOverride* v = e.find(name);
    if (on) {
      expect(!v, "no override of a path that runs (" + name + ")");
      continue;
    }
    expect(v && seen[name] == 1, "exactly one override for the path that is off: " + name);
    if (v) expect(v->path && v->requested == "on" && v->effective == "off", "path " + name);
  }
  for (const auto& [name, count] : seen)
    expect(want.count(name) || path_values(e).count(name), "an override of a known name: " + name);
  const std::string text = e.describe();
  for (const GpuOverride& v : e.overrides)
    expect(text.find(v.reason) != std::string::npos, "describe() gives every reason");

  // Idempotent: the effective options resolve to themselves, with no switch overridden.
  const EffectiveGpuOptions again = resolve_gpu_options(o, t);
  expect(again.options == o, "resolving the effective options changes no switch");
  expect(path_values(again) == path_values(e) && again.spec == e.spec,
         "resolving the effective options changes no path");
  bool switch_overridden = false;
  for (const GpuOverride& v : again.overrides) switch_overridden |= !v.path;
  expect(!switch_overridden, "the effective options need no override");
  expect(
      again.overrides.size() == size_t(std::count_if(e.overrides.begin(), e.overrides.end(),
                                                     [](const GpuOverride& v) { return v.path; })),
      "the same paths are off, each once");
  return ok;
}

TEST(GpuOptions, EveryCombinationObeysTheRules) {
  const std::vector<GpuOptions> requests = all_requests();
  const std::vector<GpuSceneTraits> scenes = all_scenes();
  ASSERT_EQ(requests.size(), 192u);
  // 128 x 128 without instances, 128 x 64 with (no flat list)
  ASSERT_EQ(scenes.size(), 24576u);
  size_t failed = 0, overridden = 0;
  for (const GpuSceneTraits& t : scenes)
    for (const GpuOptions& r : requests) {
      const EffectiveGpuOptions e = resolve_gpu_options(r, t);
      overridden += e.options != r;
      if (!check(r, t, e) && ++failed >= 5) FAIL() << "stopped after 5 failing cases";
    }
  // (The enumeration reaches the rules: most combinations change some switch.)
  EXPECT_GT(overridden, requests.size() * scenes.size() / 2);
}

TEST(GpuOptions, CornellBoxDefaults) {
  // The open Cornell box: small (a flat list), untextured, no lens, jittered.
  GpuSceneTraits t;
  t.features = kFeatureEmissiveMeshes;
  t.flat_available = true;
  t.jitter = true;
  const EffectiveGpuOptions e = resolve_gpu_options(GpuOptions(), t);
  EXPECT_EQ(e.options.compaction, Compaction::kShade);
  EXPECT_TRUE(e.options.flat_list);
  ASSERT_NE(e.find("first_bounce_cache"), nullptr);
  EXPECT_NE(e.find("first_bounce_cache")->reason.find("jitter"), std::string::npos);
  ASSERT_NE(e.find("compaction"), nullptr);
  EXPECT_EQ(e.find("compaction")->effective, "shade");
  if (gpu_build_variant() == "default") {
    EXPECT_TRUE(e.rays_at_slots && e.fused_trace && e.fused_tail && e.specialize);
    EXPECT_FALSE(e.dynamic_fetch) << "the flat list's loop has no lanes to refill";
    EXPECT_EQ(e.spec, 0u);
  }
  std::printf("%s\n", e.describe().c_str());
}

TEST(GpuOptions, ReasonsNameTheScene) {
  GpuSceneTraits t;
  t.features = kFeatureTextures | kFeatureSubsurface;
  t.jitter = false;
  t.depth_of_field = true;
  GpuOptions r;
  r.compaction = Compaction::kOff;
  const EffectiveGpuOptions e = resolve_gpu_options(r, t);
  ASSERT_NE(e.find("first_bounce_cache"), nullptr);
  EXPECT_NE(e.find("first_bounce_cache")->reason.find("depth of field"), std::string::npos);
  ASSERT_NE(e.find("flat_list"), nullptr);
  EXPECT_NE(e.find("flat_list")->reason.find("too large"), std::string::npos);
  ASSERT_NE(e.find("tail_fraction"), nullptr);
  EXPECT_EQ(e.find("tail_fraction")->requested, "0.25");
  EXPECT_EQ(e.find("tail_fraction")->effective, "0");
  r.compaction = Compaction::kAuto;
  const EffectiveGpuOptions cub = resolve_gpu_options(r, t);
  EXPECT_EQ(cub.options.compaction, Compaction::kCub);
  EXPECT_NE(cub.find("compaction")->reason.find("textured"), std::string::npos);
}

// The names messages use are the settings table's (gpu.kernel, gpu.compaction).
TEST(GpuOptions, NamesAreTheSettingsTables) {
  for (Compaction k : {Compaction::kOff, Compaction::kAuto, Compaction::kShade, Compaction::kCub}) {
    tracer::Scene scene;
    ASSERT_EQ(tracer::set_setting_assignment(scene, std::string("gpu.compaction=") +
                                                        compaction_name(k)), "");
    EXPECT_EQ(scene.gpu.compaction, k);
  }
  for (KernelMode k : {KernelMode::kAuto, KernelMode::kWavefront, KernelMode::kMegakernel}) {
    tracer::Scene scene;
    ASSERT_EQ(tracer::set_setting_assignment(scene, std::string("gpu.kernel=") +
                                                        kernel_mode_name(k)), "");
    EXPECT_EQ(scene.gpu.kernel, k);
  }
  EXPECT_FALSE(gpu_build_variant().empty());
}

}  // namespace
