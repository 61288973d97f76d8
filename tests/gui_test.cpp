// The real workbench window under Xvfb (Mesa, CPU backend): the screenshot shows both the panels
// and a rendered image; a scripted edit resets the accumulator and the image re-converges; a
// display edit does not reset; bad scripts and edits fail with a message; warnings reach stderr
// once and the status line counts them; the panels fit at 1280x720 and 1600x900; the Material
// panel follows the selection; --until-spp and a script's quit write the screenshot of the image
// they stop at. Skips, saying why, when xvfb-run is not installed.
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

// The workbench under xvfb-run; its own exit status, which the shell that xvfb-run starts writes
// to a file: xvfb-run's may instead be that of its cleanup, which now and then fails to remove
// its temporary directory under a parallel ctest (an error of its own, about nothing the
// workbench did, whose message is dropped from the log as well).
int run_gui(const std::string& args, std::string* log, int width = 1200, int height = 800) {
  static int calls = 0;
  const std::string w = std::to_string(width), h = std::to_string(height);
  const std::string code = tmpdir() + "/exit_code_" + std::to_string(calls++);
  std::string out;
  const int rc = test::run_command("xvfb-run -a -s '-screen 0 " + w + "x" + h + "x24' sh -c '" +
                                       test::pathtracer_exe() + " gui --backend cpu --window " +
                                       w + " --window-height " + h + " " + args + "; echo $? > " +
                                       code + "'",
                                   &out);
  const std::string cleanup = "xvfb-run: error: problem while cleaning up temporary directory\n";
  for (size_t at; (at = out.find(cleanup)) != std::string::npos;) out.erase(at, cleanup.size());
  if (log) *log = out;
  std::ifstream f(code);
  int status = rc;
  return f >> status ? status : rc;
}

size_t occurrences(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Pixels of the message colours (ui/panels.cpp: warnings 255,200,60, errors 255,90,90, decoded
// to linear) in the status line and Messages list at the top of the panel column.
struct StatusColours {
  int warning = 0, error = 0;
};
StatusColours status_colours(const tracer::ImageRGB& img) {
  StatusColours n;
  for (int y = 20; y < 100; ++y)
    for (int x = img.width - 460; x < img.width; ++x) {
      const tracer::vec3 c = img.at(x, y);
      if (c.x < 0.4f || c.z > 0.25f * c.x) continue;
      if (c.y > 0.35f * c.x && c.y < 0.8f * c.x) ++n.warning;
      if (c.y < 0.25f * c.x) ++n.error;
    }
  return n;
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
  // The built-in box has no warnings: nothing in the status line's colours.
  EXPECT_LT(status_colours(img).warning, 5);
  EXPECT_LT(status_colours(img).error, 5);
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
  std::ofstream(bad) << "1: select red wal\n";
  EXPECT_NE(run_gui("--frames 3 --script " + bad, &log), 0);
  EXPECT_NE(log.find("bad.script:1: no object named \"red wal\" (did you mean \"red wall\"?)"),
            std::string::npos) << log;
}

TEST(Gui, WarningsGoToStderrOnceAndTheStatusLineShowsThem) {
  if (!have_xvfb()) GTEST_SKIP() << "xvfb-run is not installed (scripts/setup.sh installs xvfb)";
  const std::string dir = tmpdir(), file = test::data_dir() + "/bad/missing_mtl.obj";
  const std::string small = " --set render.width=64 --set render.height=64 ";
  // The file's warning and notes, each once on stderr, however many frames run; the status line at
  // the top of the column counts them in the warning colour.
  std::string log;
  ASSERT_EQ(run_gui("--frames 12" + small + "--screenshot " + dir + "/warned.png " + file, &log,
                    1280, 720), 0) << log;
  EXPECT_EQ(occurrences(log, "warning: "), 1u) << log;
  EXPECT_EQ(occurrences(log, "\"nowhere.mtl\" not found"), 1u) << log;
  EXPECT_EQ(occurrences(log, "note: "), 2u) << log;  // the framing camera and the default light
  EXPECT_EQ(occurrences(log, "no light in the file"), 1u) << log;
  StatusColours c = status_colours(tracer::read_image(dir + "/warned.png"));
  EXPECT_GT(c.warning, 20) << "no warning count at the top of the panels";
  EXPECT_LT(c.error, 5);
  // Reloading logs the file's warnings again (once for this load); a failed export is an error
  // on stderr (once) and in red at the top of the column, and the exit status says so.
  {
    std::ofstream s(dir + "/reload.script");
    s << "2: load " << file << "\n4: export /proc/forbidden/x.png\n";
  }
  EXPECT_EQ(run_gui("--frames 12" + small + "--script " + dir + "/reload.script --screenshot " +
                        dir + "/failed.png " + file, &log, 1280, 720), 1) << log;
  EXPECT_EQ(occurrences(log, "\"nowhere.mtl\" not found"), 2u) << log;
  EXPECT_EQ(occurrences(log, "error: "), 1u) << log;
  EXPECT_EQ(occurrences(log, "reload.script:2: /proc/forbidden/x.png"), 1u) << log;
  c = status_colours(tracer::read_image(dir + "/failed.png"));
  EXPECT_GT(c.error, 20) << "the error is not shown at the top of the panels";
}

TEST(Gui, PanelsFitAt1280x720And1600x900WithEveryPanelOpen) {
  if (!have_xvfb()) GTEST_SKIP() << "xvfb-run is not installed (scripts/setup.sh installs xvfb)";
  const std::string dir = tmpdir();
  std::ofstream(dir + "/expand.script") << "1: expand\n";
  for (const auto& [w, h] : {std::pair{1280, 720}, std::pair{1600, 900}}) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    const std::string stats = dir + "/fit" + std::to_string(w) + ".jsonl";
    std::string log;
    ASSERT_EQ(run_gui("--frames 8 --set render.width=64 --set render.height=64 --script " + dir +
                          "/expand.script --stats-json " + stats,
                      &log, w, h), 0) << log;
    const auto rows = read_stats(stats);
    ASSERT_EQ(rows.size(), 8u);
    for (size_t i = 3; i < rows.size(); ++i)  // the panels open at frame 1
      EXPECT_TRUE(rows[i]["layout_problems"].empty()) << rows[i]["layout_problems"].dump(1);
  }
}

TEST(Gui, TheMaterialPanelShowsTheSelectedObjectsMaterial) {
  if (!have_xvfb()) GTEST_SKIP() << "xvfb-run is not installed (scripts/setup.sh installs xvfb)";
  const std::string dir = tmpdir();
  std::ofstream(dir + "/select.script") << "3: select red wall\n5: select light\n";
  std::string log;
  ASSERT_EQ(run_gui("--frames 7 --set render.width=32 --set render.height=32 --script " + dir +
                        "/select.script --stats-json " + dir + "/select.jsonl",
                    &log), 0) << log;
  const auto rows = read_stats(dir + "/select.jsonl");
  ASSERT_EQ(rows.size(), 7u);
  EXPECT_EQ(rows[0]["selected_object"], "floor") << "the first object is selected on start";
  EXPECT_EQ(rows[0]["material"], "white");
  EXPECT_EQ(rows[3]["selected_object"], "red wall");
  EXPECT_EQ(rows[3]["material"], "red");
  EXPECT_EQ(rows[6]["material"], "light");
}

TEST(Gui, UntilSppStopsAtThatImageAndScreenshotsIt) {
  if (!have_xvfb()) GTEST_SKIP() << "xvfb-run is not installed (scripts/setup.sh installs xvfb)";
  const std::string dir = tmpdir();
  std::string log;
  ASSERT_EQ(run_gui("--until-spp 16 --set render.width=96 --set render.height=96 --screenshot " +
                        dir + "/until.png --export " + dir + "/until.exr --stats-json " + dir +
                        "/until.jsonl",
                    &log), 0) << log;
  const auto rows = read_stats(dir + "/until.jsonl");
  ASSERT_FALSE(rows.empty());
  EXPECT_EQ(rows.back()["spp"], 16);
  for (size_t i = 0; i + 1 < rows.size(); ++i) EXPECT_LT(rows[i]["spp"].get<int>(), 16);
  std::ifstream sidecar(dir + "/until.exr.json");
  ASSERT_TRUE(sidecar) << "no sidecar";
  EXPECT_EQ(nlohmann::json::parse(sidecar)["spp"], 16);
  const tracer::ImageRGB exported = tracer::read_image(dir + "/until.exr");
  double sum = 0.0;
  for (float v : exported.pixels) sum += v;
  EXPECT_GT(sum / double(exported.pixels.size()), 0.05) << "a black image";
  // The screenshot shows that image, not a black one: the red wall is in the viewport.
  const tracer::ImageRGB shot = tracer::read_image(dir + "/until.png");
  int reddish = 0;
  for (int y = 100; y < 700; ++y)
    for (int x = 0; x < 700; ++x) {
      const tracer::vec3 c = shot.at(x, y);
      reddish += c.x > 0.08f && c.x > 3.0f * c.y && c.x > 3.0f * c.z;
    }
  EXPECT_GT(reddish, 2000);
  // A time limit that stops the render first: it quits there and says so.
  ASSERT_EQ(run_gui("--until-spp 1000000 --set render.width=64 --set render.height=64 "
                    "--set render.time_limit_s=0.5",
                    &log), 0) << log;
  EXPECT_NE(log.find("before --until-spp 1000000"), std::string::npos) << log;
}

TEST(Gui, AScriptsQuitStillWritesTheScreenshotAndExport) {
  if (!have_xvfb()) GTEST_SKIP() << "xvfb-run is not installed (scripts/setup.sh installs xvfb)";
  const std::string dir = tmpdir();
  std::ofstream(dir + "/quit.script") << "converged: quit\n";
  std::string log;
  ASSERT_EQ(run_gui("--set render.spp=8 --set render.width=64 --set render.height=64 --script " +
                        dir + "/quit.script --screenshot " + dir + "/quit.png --export " + dir +
                        "/quit.exr",
                    &log), 0) << log;
  const tracer::ImageRGB shot = tracer::read_image(dir + "/quit.png");
  EXPECT_EQ(shot.width, 1200);
  EXPECT_EQ(shot.height, 800);
  std::ifstream sidecar(dir + "/quit.exr.json");
  ASSERT_TRUE(sidecar) << "no export at the script's quit";
  EXPECT_EQ(nlohmann::json::parse(sidecar)["spp"], 8);
}

}  // namespace
