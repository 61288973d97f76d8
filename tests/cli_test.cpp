// End-to-end tests of the `pathtracer` executable: renders write an image and a reproducible JSON
// sidecar, bad input and bad flags exit non-zero with a message, info and compare report figures.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "image/image.h"
#include "test_util.h"

namespace {

std::string tmpdir() {
  static std::string dir = [] {
    char tmpl[] = "/tmp/pathtracer_cli_XXXXXX";
    return std::string(mkdtemp(tmpl));
  }();
  return dir;
}

std::string exe() { return test::pathtracer_exe(); }

TEST(Cli, RenderWritesPngAndReproducibleSidecar) {
  const std::string out = tmpdir() + "/a.png";
  std::string log;
  ASSERT_EQ(test::run_command(exe() + " render --spp 4 --width 24 --height 16 --seed 3 --backend cpu --out " + out, &log), 0) << log;
  const tracer::ImageRGB img = tracer::read_image(out);
  EXPECT_EQ(img.width, 24);
  EXPECT_EQ(img.height, 16);
  std::ifstream f(out + ".json");
  ASSERT_TRUE(f.good());
  const auto j = nlohmann::json::parse(f);
  EXPECT_EQ(j["spp"], 4);
  EXPECT_EQ(j["render"]["width"], 24);
  EXPECT_EQ(j["render"]["seed"], 3);
  EXPECT_EQ(j["render"]["sampler"], "sobol");  // the default
  EXPECT_EQ(j["backend"], "cpu");
  EXPECT_TRUE(j.contains("device"));
  EXPECT_TRUE(j.contains("version"));
  EXPECT_TRUE(j.contains("wall_time_s"));
  EXPECT_EQ(j["scene"], "<built-in>");
  EXPECT_NE(log.find("wrote"), std::string::npos);
}

TEST(Cli, SamplerOptionIsRecordedAndChecked) {
  const std::string out = tmpdir() + "/sampler.png";
  std::string log;
  ASSERT_EQ(test::run_command(exe() + " render -q --spp 2 --width 8 --height 8 --backend cpu "
                                      "--sampler random --out " + out, &log), 0) << log;
  std::ifstream f(out + ".json");
  ASSERT_TRUE(f.good());
  EXPECT_EQ(nlohmann::json::parse(f)["render"]["sampler"], "random");
  EXPECT_NE(test::run_command(exe() + " render -q --spp 2 --sampler halton --out " + out, &log),
            0);
}

TEST(Cli, ExrIsLinearAndMatchesPng) {
  const std::string exr = tmpdir() + "/b.exr", png = tmpdir() + "/b.png";
  ASSERT_EQ(test::run_command(exe() + " render -q --spp 2 --width 8 --height 8 --out " + exr), 0);
  ASSERT_EQ(test::run_command(exe() + " render -q --spp 2 --width 8 --height 8 --out " + png), 0);
  const tracer::ImageRGB a = tracer::read_image(exr), b = tracer::read_image(png);
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  for (size_t i = 0; i < a.pixels.size(); ++i)
    EXPECT_NEAR(std::min(a.pixels[i], 1.0f), b.pixels[i], 0.01f + 0.02f * b.pixels[i]);
}

TEST(Cli, TimeBudgetRenders) {
  const std::string out = tmpdir() + "/t.png";
  ASSERT_EQ(test::run_command(exe() + " render -q --time 0.5 --width 16 --height 16 --out " + out), 0);
  std::ifstream f(out + ".json");
  const auto j = nlohmann::json::parse(f);
  // Behaviour, not speed (a loaded machine may be slow): the sidecar records the budget, and the
  // render stopped because the budget was spent, after at least one sample.
  EXPECT_DOUBLE_EQ(j["render"]["time_limit_s"].get<double>(), 0.5);
  EXPECT_GE(j["spp"].get<int>(), 1);
  EXPECT_GE(j["wall_time_s"].get<double>(), 0.5);
}

TEST(Cli, BadFlagsAndInputsFail) {
  std::string log;
  EXPECT_NE(test::run_command(exe() + " render --spp 0", &log), 0);
  EXPECT_NE(test::run_command(exe() + " render --width -5", &log), 0);
  EXPECT_NE(test::run_command(exe() + " render --backend metal", &log), 0);
  EXPECT_NE(test::run_command(exe() + " render --spp 4 --time 2", &log), 0);
  EXPECT_NE(test::run_command(exe() + " render --bogus", &log), 0);
  EXPECT_NE(test::run_command(exe() + " render --compaction thrust", &log), 0);
  EXPECT_NE(log.find("cub"), std::string::npos) << log;  // the choices are named
  EXPECT_NE(test::run_command(exe() + " render /nonexistent/scene.json", &log), 0);
  EXPECT_NE(test::run_command(exe() + " render -q --spp 1 --width 8 --height 8 --out " + tmpdir() +
                                  "/x.bmp", &log), 0);
  EXPECT_NE(log.find("x.bmp"), std::string::npos) << log;
  EXPECT_NE(test::run_command(exe() + " info " + test::data_dir() + "/bad/unknown_key.json", &log),
            0);
  EXPECT_NE(log.find("did you mean"), std::string::npos) << log;
}

// An output that cannot be created is found before the render, not after it.
TEST(Cli, UnwritableOutputFailsBeforeRendering) {
  std::string log;
  // /proc takes no new files, even for root; the render would take minutes at this size.
  EXPECT_EQ(test::run_command(exe() + " render --spp 100000 --width 2048 --height 2048 --out "
                                      "/proc/pathtracer_test/x.png",
                              &log),
            1)
      << log;
  EXPECT_NE(log.find("/proc/pathtracer_test/x.png"), std::string::npos) << log;
  EXPECT_NE(log.find("nothing was rendered"), std::string::npos) << log;
  EXPECT_EQ(log.find("render:"), std::string::npos) << "no progress: nothing rendered\n" << log;
  // A missing folder is made, as the writer would.
  const std::string out = tmpdir() + "/new/folder/y.png";
  ASSERT_EQ(test::run_command(exe() + " render -q --spp 1 --width 8 --height 8 --out " + out, &log),
            0)
      << log;
  std::ifstream f(out);
  EXPECT_TRUE(f.good());
}

// Numeric options outside the settings table refuse NaN and infinities too (the table's own are
// checked in settings_test).
TEST(Cli, NonFiniteNumbersAreRefused) {
  std::string log;
  const std::string files = " " + exe() + " " + exe();  // they exist: only the number is wrong
  for (const std::string& args : std::vector<std::string>{"compare --ppd nan" + files, "compare --flip-exposure inf" + files,
                                 "bench --error --backend cpu --time-limit nan",
                                 "render --exposure nan", "render --clamp inf", "render --time nan",
                                 "render --tail nan", "render --set display.exposure=-inf"}) {
    EXPECT_EQ(test::run_command(exe() + " " + args, &log), 2) << args << "\n" << log;
    EXPECT_NE(log.find("finite"), std::string::npos) << args << "\n" << log;
  }
}

TEST(Cli, HelpOnEverySubcommand) {
  for (const char* sub : {"", "render", "info", "compare"}) {
    std::string log;
    EXPECT_EQ(test::run_command(exe() + " " + sub + " --help", &log), 0) << sub;
    EXPECT_NE(log.find("--help"), std::string::npos) << sub;
  }
}

TEST(Cli, InfoReportsCountsBvhAndFeatures) {
  std::string log;
  ASSERT_EQ(test::run_command(exe() + " info --json " + test::source_dir() +
                                  "/assets/scenes/cornell_spheres.json", &log), 0) << log;
  const auto j = nlohmann::json::parse(log.substr(log.find('{')));
  EXPECT_GT(j["triangles"].get<int>(), 10);
  EXPECT_EQ(j["spheres"].get<int>(), 2);
  EXPECT_GE(j["lights"].get<int>(), 1);
  EXPECT_GT(j["bvh"]["nodes"].get<int>(), 1);
  EXPECT_NE(j["features"].get<std::string>().find("dielectrics"), std::string::npos);
  // Five walls and the light are six quads; with the two spheres the GPU uses the flat list.
  EXPECT_TRUE(j["flat_list"]["enabled"].get<bool>());
  EXPECT_EQ(j["flat_list"]["quads"].get<int>(), 6);
  EXPECT_EQ(j["flat_list"]["box_faces"].get<int>(), 5);
  EXPECT_EQ(j["flat_list"]["solid_boxes"].get<int>(), 0);
  EXPECT_EQ(j["gpu_specialization"].get<std::string>(), "spheres+triangles, pinhole, specular");
  EXPECT_EQ(j["reflector_planes"].get<int>(), 0);  // a mirror ball and a glass ball: no planes
  EXPECT_TRUE(j["mnee_casters"].get<bool>());
  EXPECT_TRUE(j["light_paths"].get<bool>());
  // Rough metals and frosted glass: manifold NEE has nothing to connect through, and says so.
  ASSERT_EQ(test::run_command(exe() + " info " + test::source_dir() +
                                  "/assets/scenes/rough_materials.json --mnee on", &log), 0) << log;
  EXPECT_NE(log.find("nothing here to connect through"), std::string::npos) << log;
  // The diffuse box: light tracing has no light path to find, and says so.
  ASSERT_EQ(test::run_command(exe() + " info " + test::source_dir() +
                                  "/assets/scenes/cornell_box.json --light-tracing on", &log),
            0) << log;
  EXPECT_NE(log.find("no light path to find here"), std::string::npos) << log;
  // smallpt: its light paths almost never reach the camera (its lamp mostly outside the room).
  ASSERT_EQ(test::run_command(exe() + " info " + test::source_dir() +
                                  "/assets/scenes/smallpt.json --light-tracing on", &log), 0)
      << log;
  EXPECT_NE(log.find("the path tracer renders alone"), std::string::npos) << log;
  ASSERT_EQ(test::run_command(exe() + " info --json " + test::source_dir() +
                                  "/assets/scenes/rough_materials.json", &log), 0) << log;
  EXPECT_FALSE(nlohmann::json::parse(log.substr(log.find('{')))["mnee_casters"].get<bool>());
  // Its narrow gold balls and frosted ball are light tracing's glossy casters, aimed at.
  EXPECT_TRUE(nlohmann::json::parse(log.substr(log.find('{')))["light_paths"].get<bool>());
  EXPECT_EQ(nlohmann::json::parse(log.substr(log.find('{')))["light_targets"].get<int>(), 3);
  // The lamp's glass box: six planes of flat reflectors (its faces) for manifold NEE.
  ASSERT_EQ(test::run_command(exe() + " info --json " + test::source_dir() +
                                  "/assets/scenes/glass_lamp.json", &log), 0) << log;
  EXPECT_EQ(nlohmann::json::parse(log.substr(log.find('{')))["reflector_planes"].get<int>(), 6);
  // The Cornell box's two blocks are solid boxes (one slab test each on the GPU).
  ASSERT_EQ(test::run_command(exe() + " info --json " + test::source_dir() +
                                  "/assets/scenes/cornell_box.json", &log), 0) << log;
  const auto b = nlohmann::json::parse(log.substr(log.find('{')));
  EXPECT_EQ(b["flat_list"]["solid_boxes"].get<int>(), 2);
  EXPECT_EQ(b["flat_list"]["quads"].get<int>(), 18);
  // The GPU design the settings resolve to, with a reason for each override: the cache is off
  // while the camera jitters, and on (no override) when it does not.
  auto override_of = [](const nlohmann::json& info, const std::string& name) {
    for (const auto& o : info["gpu_design"]["overrides"])
      if (o["name"] == name) return o;
    return nlohmann::json();
  };
  const auto cache = override_of(b, "first_bounce_cache");
  ASSERT_FALSE(cache.is_null()) << b["gpu_design"].dump();
  EXPECT_NE(cache["reason"].get<std::string>().find("jitter"), std::string::npos);
  EXPECT_EQ(b["gpu_design"]["effective"]["cache"], false);
  ASSERT_EQ(test::run_command(exe() + " info --json --jitter off --compaction cub " +
                                  test::source_dir() + "/assets/scenes/cornell_box.json", &log), 0)
      << log;
  const auto c = nlohmann::json::parse(log.substr(log.find('{')));
  EXPECT_TRUE(override_of(c, "first_bounce_cache").is_null()) << c["gpu_design"].dump();
  EXPECT_EQ(c["gpu_design"]["effective"]["compaction"], "cub");
  EXPECT_EQ(c["gpu_design"]["wavefront_paths"]["rays_at_slots"], false);
  EXPECT_FALSE(override_of(c, "rays_at_slots")["reason"].get<std::string>().empty());
}

TEST(Cli, CompareReportsMetricsAndDiff) {
  const std::string a = tmpdir() + "/c1.exr", b = tmpdir() + "/c2.exr", d = tmpdir() + "/d.png";
  ASSERT_EQ(test::run_command(exe() + " render -q --spp 2 --width 8 --height 8 --seed 1 --out " + a), 0);
  ASSERT_EQ(test::run_command(exe() + " render -q --spp 2 --width 8 --height 8 --seed 2 --out " + b), 0);
  std::string log;
  ASSERT_EQ(test::run_command(exe() + " compare --json " + a + " " + a, &log), 0) << log;
  auto j = nlohmann::json::parse(log.substr(log.find('{')));
  EXPECT_EQ(j["relmse"].get<double>(), 0.0);
  ASSERT_EQ(test::run_command(exe() + " compare --json --diff " + d + " " + a + " " + b, &log), 0);
  j = nlohmann::json::parse(log.substr(log.find('{')));
  EXPECT_GT(j["relmse"].get<double>(), 0.0);
  struct stat st;
  EXPECT_EQ(stat(d.c_str(), &st), 0);
  EXPECT_NE(test::run_command(exe() + " compare " + a + " /nonexistent.exr", &log), 0);
}

}  // namespace
