// Distributed rendering's parts that need no MPI (integrator/distributed.h): sample ranges on a
// renderer, the accumulators ranks add, the batch scheduler with ranks of different speeds, and
// frame patterns. tests/mpi_test.cpp runs the real thing under mpirun.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "cpu/cpu_backend.h"
#include "integrator/distributed.h"
#include "scene/loader.h"
#include "test_util.h"

namespace {
using namespace tracer;

RenderSettings tiny(const Scene& s) {
  RenderSettings rs = s.settings;
  rs.width = 24;
  rs.height = 18;
  return rs;
}

void expect_close(const ImageRGB& a, const ImageRGB& b, float rel, const char* what) {
  ASSERT_EQ(a.pixels.size(), b.pixels.size()) << what;
  size_t bad = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i)
    if (std::abs(a.pixels[i] - b.pixels[i]) > rel * (1e-3f + std::abs(b.pixels[i]))) ++bad;
  EXPECT_EQ(bad, 0u) << what << ": values differ by more than float rounding";
}

TEST(Distributed, SampleRangesInAnyOrderAddUpToOneRender) {
  const Scene s = builtin_default_scene();
  const RenderSettings rs = tiny(s);
  const CompiledScene cs(s, rs.width, rs.height);
  CpuRenderer whole(2);
  whole.set_scene(cs, make_integrator_settings(rs));
  whole.render(9);
  EXPECT_EQ(whole.half_samples(0), 5u);
  EXPECT_EQ(whole.half_samples(1), 4u);
  EXPECT_EQ(whole.next_sample(), 9u);

  // One renderer, the same samples out of order: the same sums in another order.
  CpuRenderer shuffled(2);
  shuffled.set_scene(cs, make_integrator_settings(rs));
  for (SampleRange r : {SampleRange{5, 4}, SampleRange{0, 3}, SampleRange{3, 2}}) {
    shuffled.set_next_sample(r.first);
    shuffled.render(r.count);
  }
  EXPECT_EQ(shuffled.samples_done(), 9u);
  EXPECT_EQ(shuffled.half_samples(0), 5u);
  expect_close(shuffled.image(), whole.image(), 1e-5f, "shuffled ranges");
  ImageRGB we, wo, se, so;
  whole.half_images(&we, &wo);
  shuffled.half_images(&se, &so);
  expect_close(se, we, 1e-5f, "even half");
  expect_close(so, wo, 1e-5f, "odd half");

  // Two "ranks", each with some ranges: their accumulations add up to the whole.
  CpuRenderer a(1), b(1);
  for (CpuRenderer* r : {&a, &b}) {
    r->set_scene(cs, make_integrator_settings(rs));
    r->set_aovs(true);
  }
  whole.set_aovs(true);
  whole.reset();
  whole.render(9);
  b.set_next_sample(0);
  b.render(1);  // sample 0 on the second rank: its ids are the image's
  a.set_next_sample(1);
  a.render(4);
  b.set_next_sample(5);
  b.render(4);
  Accumulation sum = accumulation_of(a, rs.width, rs.height);
  sum.add(accumulation_of(b, rs.width, rs.height));
  EXPECT_EQ(sum.samples(), 9u);
  EXPECT_EQ(sum.count[0], 5u);
  expect_close(sum.image(), whole.image(), 1e-5f, "two ranks");
  const AovImages aw = whole.aov_images(), as = sum.aov_images();
  ASSERT_FALSE(as.empty());
  expect_close(as.albedo, aw.albedo, 1e-5f, "albedo");
  EXPECT_EQ(sum.aov_count, 9u);
  EXPECT_NEAR(sum.half_relmse(), half_buffer_relmse(whole), 1e-6);
  // A range that is not the next one is refused when guiding (it trains in sample order).
  RenderSettings guided = rs;
  guided.guiding = true;
  CpuRenderer g(1);
  g.set_scene(cs, make_integrator_settings(guided));
  EXPECT_NO_THROW(g.set_next_sample(0));
  EXPECT_THROW(g.set_next_sample(4), std::logic_error);
}

// Simulates ranks of the given speeds (ms per sample) asking the scheduler when they are free;
// returns each rank's finishing time.
std::vector<double> simulate(BatchScheduler& s, const std::vector<double>& ms_per_spp,
                             std::vector<SampleRange>* handed) {
  const size_t n = ms_per_spp.size();
  std::vector<double> free_at(n, 0.0), measured(n, 0.0);
  std::vector<bool> done(n, false);
  for (;;) {
    size_t r = n;
    for (size_t i = 0; i < n; ++i)
      if (!done[i] && (r == n || free_at[i] < free_at[r])) r = i;
    if (r == n) break;
    const SampleRange b = s.next(int(r), measured[r], free_at[r] / 1000.0);
    if (b.count == 0) {
      done[r] = true;
      continue;
    }
    handed->push_back(b);
    free_at[r] += b.count * ms_per_spp[r] + 2.0;  // 2 ms to ask and answer
    measured[r] = ms_per_spp[r];
  }
  return free_at;
}

TEST(Distributed, BatchesCoverEverySampleOnceAndBalanceUnequalRanks) {
  // Three fast ranks and one four times slower (a CPU rank beside GPUs), 4096 samples.
  const std::vector<double> speeds = {10.0, 10.0, 10.0, 40.0};
  BatchScheduler s(4096, 0.0, 4);
  std::vector<SampleRange> handed;
  const std::vector<double> end = simulate(s, speeds, &handed);
  uint32_t next = 0;
  for (const SampleRange& b : handed) {
    EXPECT_EQ(b.first, next) << "the batches are in order and disjoint";
    next += b.count;
  }
  EXPECT_EQ(next, 4096u);
  EXPECT_EQ(s.handed_out(), 4096u);
  uint32_t total = 0;
  for (int r = 0; r < 4; ++r) total += s.samples(r);
  EXPECT_EQ(total, 4096u);
  // The slow rank did about a quarter of a fast one's work, and all finished together: the
  // ideal (every rank busy to the end) is 4096 / (3/10 + 1/40) ms.
  EXPECT_NEAR(double(s.samples(3)) / s.samples(0), 0.25, 0.05);
  const double ideal = 4096.0 / (3.0 / 10.0 + 1.0 / 40.0);
  const double last = *std::max_element(end.begin(), end.end());
  const double first = *std::min_element(end.begin(), end.end());
  EXPECT_LT(last, 1.03 * ideal);
  EXPECT_LT(last - first, 0.03 * ideal) << "ranks ended far apart";
  // Batches stay about half a second long at each rank's speed, never more.
  for (int r = 0; r < 4; ++r) EXPECT_GT(s.batches(r), 3u);
}

TEST(Distributed, TimedBatchesStopAtTheLimitAndStopEndsAll) {
  BatchScheduler s(0, 3.0, 2);
  std::vector<SampleRange> handed;
  const std::vector<double> end = simulate(s, {20.0, 50.0}, &handed);
  for (double t : end) {
    EXPECT_GT(t, 2900.0);
    EXPECT_LT(t, 3100.0) << "a rank ran far past the time limit";
  }
  EXPECT_GT(s.handed_out(), 100u);
  BatchScheduler stopped(100, 0.0, 2);
  EXPECT_EQ(stopped.next(0, 0.0, 0.0).count, 1u);
  stopped.stop();
  EXPECT_EQ(stopped.next(1, 0.0, 0.0).count, 0u);
}

TEST(Distributed, FramePatternsAndRanges) {
  int a = -1, b = -1;
  std::string problem;
  EXPECT_TRUE(parse_frame_range("1..24", &a, &b, &problem));
  EXPECT_EQ(a, 1);
  EXPECT_EQ(b, 24);
  EXPECT_TRUE(parse_frame_range("7", &a, &b, &problem));
  EXPECT_EQ(a, 7);
  EXPECT_EQ(b, 7);
  for (const char* bad : {"", "3..1", "a..b", "-1..2", "1..", "1...3"}) {
    EXPECT_FALSE(parse_frame_range(bad, &a, &b, &problem)) << bad;
    EXPECT_NE(problem.find("--frames"), std::string::npos);
  }
  EXPECT_TRUE(has_frame_field("shot_####.json"));
  EXPECT_FALSE(has_frame_field("shot.json"));
  EXPECT_EQ(frame_path("shot_####.json", 7), "shot_0007.json");
  EXPECT_EQ(frame_path("out/f#.png", 123), "out/f123.png");
  EXPECT_EQ(frame_path("a##_b##.png", 3), "a03_b##.png");  // the first field only
}

}  // namespace

namespace {
using namespace tracer;

TEST(Distributed, RanksTakeOneGpuEachAndTheRestShareTheCores) {
  // 3 ranks on a host with 1 GPU and 16 cores, --backend auto: one GPU rank, two CPU ranks
  // of 8 threads.
  RankPlacement p = place_rank(BackendChoice::kAuto, 0, 0, 3, 1, 16);
  EXPECT_EQ(p.backend, BackendChoice::kAuto);
  EXPECT_EQ(p.device, 0);
  for (int r : {1, 2}) {
    p = place_rank(BackendChoice::kAuto, 0, r, 3, 1, 16);
    EXPECT_EQ(p.backend, BackendChoice::kCpu);
    EXPECT_EQ(p.threads, 8);
    EXPECT_NE(p.note.find("CPU rank"), std::string::npos);
  }
  // 8 ranks, 8 GPUs: rank i on device i.
  for (int r = 0; r < 8; ++r)
    EXPECT_EQ(place_rank(BackendChoice::kAuto, 0, r, 8, 8, 128).device, r);
  // No GPU: every rank on the CPU, the cores divided; an explicit thread count is kept.
  EXPECT_EQ(place_rank(BackendChoice::kAuto, 0, 1, 2, 0, 2).threads, 1);
  EXPECT_EQ(place_rank(BackendChoice::kAuto, 0, 1, 2, 0, 2).note, "");
  EXPECT_EQ(place_rank(BackendChoice::kAuto, 6, 1, 2, 0, 2).threads, 6);
  EXPECT_EQ(place_rank(BackendChoice::kCpu, 0, 0, 4, 8, 64).threads, 16);
  // --backend cuda: round robin, saying that GPUs are shared.
  p = place_rank(BackendChoice::kCuda, 0, 5, 6, 4, 64);
  EXPECT_EQ(p.device, 1);
  EXPECT_NE(p.note.find("share"), std::string::npos);
}

}  // namespace

namespace {
using namespace tracer;

TEST(Distributed, SceneFingerprintSeesWhatShapesTheImage) {
  const std::string path = test::source_dir() + "/assets/scenes/cornell_spheres.json";
  const Scene a = load_scene(path), b = load_scene(path);
  EXPECT_EQ(scene_fingerprint(a), scene_fingerprint(b));
  Scene c = b;
  c.settings.threads = 3;
  c.settings.spp = 7;
  c.display.exposure = 2.0f;
  c.gpu.kernel = KernelMode::kMegakernel;
  EXPECT_EQ(scene_fingerprint(c), scene_fingerprint(a)) << "these do not change the samples";
  for (int k = 0; k < 5; ++k) {
    Scene d = b;
    if (k == 0) d.settings.seed = 9;
    if (k == 1) d.settings.width += 1;
    if (k == 2) d.mesh.positions[0].x += 1e-3f;
    if (k == 3) d.spheres[0].radius *= 1.01f;
    if (k == 4) d.materials[0].material.albedo *= 0.5f;
    EXPECT_NE(scene_fingerprint(d), scene_fingerprint(a)) << "change " << k;
  }
}

}  // namespace
