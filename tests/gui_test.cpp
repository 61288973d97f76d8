// The real workbench window under Xvfb (Mesa, CPU backend): the screenshot shows both the panels
// and a rendered image; a scripted edit resets the accumulator and the image re-converges; a
// display edit does not reset; bad scripts and edits fail with a message. Skips, saying why, when
// xvfb-run is not installed.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "image/image.h"
#include "test_util.h"

namespace {

std::string tmpdir() {
  static std::string dir = [] {
    char tmpl[] = "/tmp/pathtracer_gui_XXXXXX";
    return std::string(mkdtemp(tmpl));
  }();
  return dir;
}

bool have_xvfb() { return test::run_command("command -v xvfb-run >/dev/null") == 0; }

int run_gui(const std::string& args, std::string* log) {
  return test::run_command("xvfb-run -a -s '-screen 0 1200x800x24' " + test::pathtracer_exe() +
                               " gui --backend cpu --window 1200 --window-height 800 " + args,
                           log);
}

std::vector<nlohmann::json> read_stats(const std::string& path) {
  std::vector<nlohmann::json> rows;
  std::ifstream f(path);
  for (std::string line; std::getline(f, line);) rows.push_back(nlohmann::json::parse(line));
  return rows;
}

TEST(Gui, ScreenshotShowsPanelsAndImage) {
  if (!have_xvfb()) GTEST_SKIP() << "xvfb-run is not installed (scripts/setup.sh installs xvfb)";
  const std::string shot = tmpdir() + "/shot.png";
  std::string log;
  ASSERT_EQ(run_gui("--frames 40 --set render.width=160 --set render.height=160 --screenshot " +
                        shot, &log), 0) << log;
  const tracer::ImageRGB img = tracer::read_image(shot);
  ASSERT_EQ(img.width, 1200);
  ASSERT_EQ(img.height, 800);
  // The viewport (left) holds the Cornell box: red and green walls.
  int reddish = 0, greenish = 0;
  for (int y = 100; y < 700; ++y)
    for (int x = 0; x < 800; ++x) {
      const tracer::vec3 c = img.at(x, y);
      if (c.x > 0.08f && c.x > 3.0f * c.y && c.x > 3.0f * c.z) ++reddish;
      if (c.y > 0.04f && c.y > 1.8f * c.x && c.y > 1.8f * c.z) ++greenish;
    }
  EXPECT_GT(reddish, 2000) << "no red wall in the viewport";
  EXPECT_GT(greenish, 2000) << "no green wall in the viewport";
  // The panel column (right 400 px) holds ImGui's blue headers and light text.
  int header = 0, text = 0;
  for (int y = 0; y < 800; ++y)
    for (int x = 810; x < 1200; ++x) {
      const tracer::vec3 c = img.at(x, y);
      if (c.z > 0.1f && c.z > 1.5f * c.x && c.x < 0.2f) ++header;
      if (c.x > 0.6f && c.y > 0.6f && c.z > 0.6f) ++text;
    }
  EXPECT_GT(header, 2000) << "no panel headers";
  EXPECT_GT(text, 500) << "no panel text";
}

TEST(Gui, ScriptedEditResetsAndReconvergesDisplayEditDoesNot) {
  if (!have_xvfb()) GTEST_SKIP() << "xvfb-run is not installed (scripts/setup.sh installs xvfb)";
  const std::string dir = tmpdir();
  {
    std::ofstream s(dir + "/edit.script");
    s << "# converge, recolour the red wall blue, converge again, then only change exposure\n"
      << "converged: export " << dir << "/a.exr\n"
      << "converged: set materials.red.albedo=0.05,0.05,0.65\n"
      << "converged: export " << dir << "/b.exr\n"
      << "converged: set display.exposure=1\n"
      << "converged: screenshot " << dir << "/edited.png\n"
      << "converged: quit\n";
  }
  std::string log;
  ASSERT_EQ(run_gui("--frames 100000 --set render.width=64 --set render.height=64 "
                    "--set render.spp=64 --script " + dir + "/edit.script --stats-json " + dir +
                        "/stats.jsonl", &log), 0) << log;
  const auto rows = read_stats(dir + "/stats.jsonl");
  ASSERT_GT(rows.size(), 3u);
  // Find the reset: resets goes up by one and spp drops to 0 in that same frame.
  size_t reset_frame = 0;
  for (size_t i = 1; i < rows.size(); ++i)
    if (rows[i]["resets"] != rows[i - 1]["resets"]) {
      EXPECT_EQ(reset_frame, 0u) << "exactly one reset expected";
      reset_frame = i;
      EXPECT_EQ(rows[i - 1]["spp"], 64);
      EXPECT_LT(rows[i]["spp"].get<int>(), 64);
    }
  ASSERT_GT(reset_frame, 0u) << "the material edit did not reset the accumulator";
  // The exposure change (after the reset) never drops spp.
  for (size_t i = reset_frame + 1; i < rows.size(); ++i)
    EXPECT_GE(rows[i]["spp"].get<int>(), rows[i - 1]["spp"].get<int>()) << "frame " << i;
  EXPECT_EQ(rows.back()["exposure"], 1.0);
  EXPECT_EQ(rows.back()["spp"], 64);
  // The left wall turned from red to blue.
  const tracer::ImageRGB a = tracer::read_image(dir + "/a.exr");
  const tracer::ImageRGB b = tracer::read_image(dir + "/b.exr");
  tracer::vec3 wall_a(0.0f), wall_b(0.0f);
  for (int y = 20; y < 44; ++y)
    for (int x = 1; x < 7; ++x) {
      wall_a += a.at(x, y);
      wall_b += b.at(x, y);
    }
  EXPECT_GT(wall_a.x, 3.0f * wall_a.z);
  EXPECT_GT(wall_b.z, 1.5f * wall_b.x);
}

TEST(Gui, BadInputFailsWithMessages) {
  if (!have_xvfb()) GTEST_SKIP() << "xvfb-run is not installed (scripts/setup.sh installs xvfb)";
  std::string log;
  EXPECT_NE(run_gui("--frames 2 --set camera.fov=40", &log), 0);
  EXPECT_NE(log.find("did you mean"), std::string::npos) << log;
  const std::string bad = tmpdir() + "/bad.script";
  std::ofstream(bad) << "1: set camera.vfov=40\n2: fly away\n";
  EXPECT_NE(run_gui("--frames 5 --script " + bad, &log), 0);
  EXPECT_NE(log.find("bad.script:2"), std::string::npos) << log;
  EXPECT_NE(run_gui("--frames 2 " + test::data_dir() + "/bad/unknown_key.json", &log), 0);
  EXPECT_NE(log.find("unknown_key.json"), std::string::npos) << log;
}

}  // namespace
