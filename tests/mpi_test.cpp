// Distributed rendering under mpirun on the CPU (app/mpi_render.cpp): the image of 2 ranks equals
// the image of one process with the same samples, the batches keep both ranks busy, and a rank
// that cannot start or a frame that fails is reported by rank 0 with no partial file. Skipped
// with the reason when Open MPI is not installed or pathtracer was built without it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

#include "image/image.h"
#include "test_util.h"

namespace {
namespace fs = std::filesystem;
using namespace test;

std::string mpirun(int ranks) {
  return std::string(TRACER_MPIEXEC) + " -np " + std::to_string(ranks) +
         " --allow-run-as-root --oversubscribe ";
}

#define REQUIRE_MPI()                                                                     \
  do {                                                                                    \
    if (!TRACER_PATHTRACER_MPI)                                                           \
      GTEST_SKIP() << "pathtracer was built without MPI (install libopenmpi-dev: "        \
                      "scripts/setup.sh does)";                                           \
    if (std::string(TRACER_MPIEXEC).empty() || !fs::exists(TRACER_MPIEXEC))               \
      GTEST_SKIP() << "no mpirun (Open MPI's openmpi-bin is not installed)";              \
  } while (0)

class Mpi : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("pathtracer_mpi_" + std::string(::testing::UnitTest::GetInstance()
                                                 ->current_test_info()
                                                 ->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static nlohmann::json sidecar(const std::string& image) {
    std::ifstream in(image + ".json");
    return nlohmann::json::parse(in);
  }
  fs::path dir_;
};

const std::string kScene = source_dir() + "/assets/scenes/cornell_box.json";
const std::string kSmall = " --width 40 --height 30 --backend cpu ";

TEST_F(Mpi, TwoRanksMakeTheImageOfOneProcess) {
  REQUIRE_MPI();
  std::string out;
  const std::string one = path("one.exr"), two = path("two.exr");
  ASSERT_EQ(run_command(pathtracer_exe() + " render " + kScene + kSmall +
                            "--spp 24 --aov all -q --out " + one, &out), 0) << out;
  ASSERT_EQ(run_command(mpirun(2) + pathtracer_exe() + " render " + kScene + kSmall +
                            "--spp 24 --aov all --out " + two, &out), 0) << out;
  EXPECT_NE(out.find("mpi: 2 ranks"), std::string::npos) << out;
  const tracer::ImageRGB a = tracer::read_image(one), b = tracer::read_image(two);
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  for (size_t i = 0; i < a.pixels.size(); ++i)
    ASSERT_NEAR(b.pixels[i], a.pixels[i], 2e-6f * (1.0f + std::abs(a.pixels[i])))
        << "value " << i << ": the ranks' sum is not the one process's image";
  // The same samples: the same rays, counted over both ranks; the same half buffers' noise.
  const nlohmann::json s1 = sidecar(one), s2 = sidecar(two);
  EXPECT_EQ(s2["spp"], 24);
  EXPECT_EQ(s2["rays"], s1["rays"]);
  EXPECT_NEAR(s2["relmse_halves"].get<double>(), s1["relmse_halves"].get<double>(),
              1e-4 * s1["relmse_halves"].get<double>());
  // One sidecar listing every rank, and the AOVs (ids of each pixel's sample 0) written.
  ASSERT_TRUE(s2.contains("mpi")) << s2.dump();
  const nlohmann::json& ranks = s2["mpi"]["ranks"];
  ASSERT_EQ(ranks.size(), 2u);
  uint32_t total = 0;
  for (const auto& r : ranks) {
    EXPECT_FALSE(r["host"].get<std::string>().empty());
    EXPECT_EQ(r["backend"], "cpu");
    total += r["samples"].get<uint32_t>();
  }
  EXPECT_EQ(total, 24u);
  EXPECT_EQ(s2["aovs"]["samples"], 24);
  EXPECT_GE(s2["mpi"]["reduce_s"].get<double>(), 0.0);
  // The AOVs too (3 ranks, PNGs beside a PNG): byte for byte, the ids of each pixel's sample 0.
  ASSERT_EQ(run_command(mpirun(3) + pathtracer_exe() + " render " + kScene + kSmall +
                            "--spp 24 --aov all -q --out " + path("three.png"), &out), 0) << out;
  ASSERT_EQ(run_command(pathtracer_exe() + " render " + kScene + kSmall +
                            "--spp 24 --aov all -q --out " + path("single.png"), &out), 0) << out;
  auto bytes = [](const std::string& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  for (const char* aov : {"albedo", "normal", "depth", "id"}) {
    const std::string a = bytes(path(std::string("single.") + aov + ".png"));
    EXPECT_FALSE(a.empty()) << aov;
    EXPECT_EQ(bytes(path(std::string("three.") + aov + ".png")), a) << aov << " differs";
  }
  // Rank 0 decides the AOVs: a rank asked for other ones (MPMD) renders rank 0's, and the sums
  // still add up, whichever way round.
  for (const char* aov0 : {"", " --aov all"}) {
    const std::string common = kScene + kSmall + "--spp 24 -q --out " + path("mixed.png");
    const std::string aov1 = std::string(aov0).empty() ? " --aov albedo" : "";
    ASSERT_EQ(run_command(std::string(TRACER_MPIEXEC) + " --allow-run-as-root --oversubscribe " +
                              "-np 1 " + pathtracer_exe() + " render " + common + aov0 +
                              " : -np 1 " + pathtracer_exe() + " render " + common + aov1,
                          &out), 0) << out;
    EXPECT_EQ(bytes(path("mixed.png")), bytes(path("single.png"))) << "rank 0's AOVs:" << aov0;
    EXPECT_EQ(fs::exists(path("mixed.albedo.png")), !std::string(aov0).empty());
    fs::remove(path("mixed.albedo.png"));
  }
}

TEST_F(Mpi, BatchesKeepEveryRankBusyUnderATimeBudget) {
  REQUIRE_MPI();
  std::string out;
  const std::string img = path("timed.png");
  ASSERT_EQ(run_command(mpirun(2) + pathtracer_exe() + " render " + kScene + kSmall +
                            "--time 3 -q --out " + img, &out), 0) << out;
  const nlohmann::json s = sidecar(img);
  uint32_t total = 0;
  for (const auto& r : s["mpi"]["ranks"]) {
    EXPECT_GT(r["samples"].get<uint32_t>(), 10u) << "a rank was left without work: " << s.dump();
    EXPECT_GT(r["batches"].get<uint32_t>(), 2u);
    // Every rank ends within about a batch (half a second) of the others.
    EXPECT_LT(r["idle_s"].get<double>(), 0.75) << s["mpi"].dump();
    total += r["samples"].get<uint32_t>();
  }
  EXPECT_EQ(s["spp"].get<uint32_t>(), total);
  EXPECT_GT(s["wall_time_s"].get<double>(), 2.9);
  EXPECT_LT(s["wall_time_s"].get<double>(), 4.0);
}

TEST_F(Mpi, ARankThatCannotStartFailsTheRunOnRankZero) {
  REQUIRE_MPI();
  std::string out;
  const std::string img = path("never.png");
  // MPMD: rank 1 is given a scene that does not exist on its "host".
  const std::string args = kSmall + "--spp 4 --out " + img;
  const int rc = run_command(std::string(TRACER_MPIEXEC) +
                                 " --allow-run-as-root --oversubscribe -np 1 " + pathtracer_exe() +
                                 " render " + kScene + args + " : -np 1 " + pathtracer_exe() +
                                 " render " + path("missing.json") + args,
                             &out);
  EXPECT_NE(rc, 0) << out;
  EXPECT_NE(out.find("rank 1 ("), std::string::npos) << out;
  EXPECT_NE(out.find("missing.json"), std::string::npos) << out;
  EXPECT_NE(out.find("nothing was rendered"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(img)) << "a partial image was written";
  // Path guiding trains on one renderer's samples in order: refused with more than one rank.
  EXPECT_EQ(run_command(mpirun(2) + pathtracer_exe() + " render " + kScene + kSmall +
                            "--spp 4 --guiding on --out " + img, &out), 2) << out;
  EXPECT_NE(out.find("render.guiding with 2 MPI ranks"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(img));
  // A rank whose scene or settings differ (here its seed) would add other samples: refused.
  const std::string mpmd = std::string(TRACER_MPIEXEC) + " --allow-run-as-root --oversubscribe " +
                           "-np 1 " + pathtracer_exe() + " render " + kScene + args +
                           " : -np 1 " + pathtracer_exe() + " render " + kScene + args;
  EXPECT_NE(run_command(mpmd + " --seed 9", &out), 0) << out;
  EXPECT_NE(out.find("rank 1 (") , std::string::npos) << out;
  EXPECT_NE(out.find("loaded a different scene than rank 0"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(img));
  // ... while settings that do not shape the image may differ.
  EXPECT_EQ(run_command(mpmd + " --threads 1 --exposure 2", &out), 0) << out;
  EXPECT_TRUE(fs::exists(img));
  fs::remove(img);
  // Only render distributes: another command under mpirun would run twice.
  EXPECT_EQ(run_command(mpirun(2) + pathtracer_exe() + " info " + kScene, &out), 2) << out;
  EXPECT_NE(out.find("only `pathtracer render` distributes"), std::string::npos) << out;
}

TEST_F(Mpi, FramesAreSpreadOverRanksAndAFailedFrameIsReported) {
  REQUIRE_MPI();
  for (int f = 1; f <= 4; ++f)
    fs::copy_file(kScene, path("shot_0" + std::to_string(f) + ".json"));
  {
    std::ofstream broken(path("shot_03.json"), std::ios::trunc);
    broken << "{ \"camera\": [1, 2\n";
  }
  std::string out;
  const int rc = run_command(mpirun(2) + pathtracer_exe() + " render " + path("shot_##.json") +
                                 kSmall + "--spp 4 --frames 1..4 --out " + path("f_###.png"),
                             &out);
  EXPECT_NE(rc, 0) << "a failed frame must fail the run: " << out;
  for (int f : {1, 2, 4}) EXPECT_TRUE(fs::exists(path("f_00" + std::to_string(f) + ".png"))) << out;
  EXPECT_FALSE(fs::exists(path("f_003.png")));
  EXPECT_NE(out.find("frame 3 ("), std::string::npos) << out;
  EXPECT_NE(out.find("shot_03.json:"), std::string::npos) << "the message names the file: " << out;
  EXPECT_NE(out.find("3 of 4 written"), std::string::npos) << out;
  // Without mpirun: the same frames one after another.
  EXPECT_EQ(run_command(pathtracer_exe() + " render " + path("shot_##.json") + kSmall +
                            "--spp 2 --frames 1..2 -q --out " + path("g_###.png"), &out), 0)
      << out;
  EXPECT_TRUE(fs::exists(path("g_002.png"))) << out;
}

}  // namespace
