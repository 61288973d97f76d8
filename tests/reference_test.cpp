// Accuracy against an independent renderer (label `reference`): the shared Bitterli scenes
// (../shared/scenes/bitterli, pbrt-v4 files with Tungsten's reference renders) rendered small on
// the CPU, their 4x4-region means against the reference averaged down to the same size. A region
// passes when its mean is within the noise of the render (z from the per-pixel sample variance,
// Sidak-corrected over every region and channel) plus the scene's documented model difference
// (docs/BENCHMARKS.md explains each; 0 where the renderers agree). Regions a known model
// difference dominates are left out by name with the reason. Skips with the reason when the
// shared scenes are absent, so a user's clone stays green.
#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <sstream>
#include <vector>

#include "image/image.h"
#include "scene/loader.h"
#include "scene/settings.h"
#include "scene_builders.h"
#include "test_util.h"

namespace {

using namespace tracer;

std::string bitterli_dir() { return test::source_dir() + "/../shared/scenes/bitterli"; }

struct ReferenceCase {
  const char* name;
  int max_depth;  // the original pbrt maxdepth - 1: the segments the reference holds
  int downscale;  // of the reference's resolution
  uint32_t spp;
  double tolerance;  // relative model difference allowed on top of the noise
  int cols, rows;    // the grid of regions
  std::set<std::pair<int, int>> excluded;  // grid cells (column, row) a model difference rules
  const char* why_excluded;
  // materials.NAME.FIELD=VALUE edits that restore what the pbrt-v4 conversion changed
  // (BENCHMARKS.md says which and why)
  std::vector<std::string> edits = {};
};

// Every cell of the rows first_row.. of a grid `cols` wide.
std::set<std::pair<int, int>> rows_from(int first_row, int cols, int rows) {
  std::set<std::pair<int, int>> cells;
  for (int r = first_row; r < rows; ++r)
    for (int q = 0; q < cols; ++q) cells.insert({q, r});
  return cells;
}

// The reference averaged over downscale x downscale blocks: what a box-filtered render at the
// lower resolution estimates (Tungsten's tent of one full-size pixel blurs only the block edges).
ImageRGB block_average(const ImageRGB& img, int k) {
  ImageRGB out = make_image(img.width / k, img.height / k);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      glm::dvec3 s(0.0);
      long n = 0;
      for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {
          const vec3 v = img.at(x * k + i, y * k + j);
          if (!is_finite(v)) continue;  // one NaN pixel in water-caustic's reference
          s += glm::dvec3(v);
          ++n;
        }
      out.set(x, y, vec3(s / double(std::max(n, 1L))));
    }
  return out;
}

bool have_scene(const char* name) {
  return std::filesystem::exists(bitterli_dir() + "/" + name + "/scene-v4.pbrt");
}

// The regions and channels that differ by more than the noise and the tolerance, one message
// each; empty when the render agrees with the reference.
std::vector<std::string> differing_regions(const ReferenceCase& c) {
  const std::string dir = bitterli_dir() + "/" + c.name;
  const ImageRGB ref_full = read_image(dir + "/TungstenRender.exr");
  const ImageRGB ref = block_average(ref_full, c.downscale);
  Scene scene = load_scene(dir + "/scene-v4.pbrt");
  for (const std::string& e : c.edits) {
    const std::string problem = set_material_assignment(scene, e);
    EXPECT_EQ(problem, "") << e;
  }
  RenderSettings rs = scene.settings;
  rs.width = ref.width;
  rs.height = ref.height;
  rs.max_depth = c.max_depth;
  rs.filter = PixelFilter::kBox;  // a low-resolution pixel is the block the reference averages
  rs.filter_radius = 0.0f;
  rs.seed = 17;
  const test::PixelStats ps = test::render_pixel_stats(scene, rs, c.spp);
  EXPECT_EQ(ps.nonfinite, 0u);
  std::vector<std::string> out;

  const int cols = c.cols, rows = c.rows;
  const double z_max = test::sidak_z(0.01, size_t(cols * rows * 3));
  int checked = 0;
  for (int r = 0; r < rows; ++r)
    for (int q = 0; q < cols; ++q) {
      if (c.excluded.count({q, r})) continue;
      const int x0 = q * ref.width / cols, x1 = (q + 1) * ref.width / cols;
      const int y0 = r * ref.height / rows, y1 = (r + 1) * ref.height / rows;
      glm::dvec3 mt(0.0), mr(0.0), var(0.0);
      const double n = double(x1 - x0) * (y1 - y0);
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
          const size_t p = size_t(y) * ref.width + x;
          mt += glm::dvec3(ps.mean[p]);
          var += glm::dvec3(ps.var[p]) / double(c.spp);
          mr += glm::dvec3(ref.at(x, y));
        }
      mt /= n;
      mr /= n;
      const glm::dvec3 sigma = glm::sqrt(var) / n;
      for (int ch = 0; ch < 3; ++ch) {
        const double bound = z_max * sigma[ch] + c.tolerance * mr[ch];
        if (std::fabs(mt[ch] - mr[ch]) <= bound) continue;
        std::ostringstream m;
        m << c.name << " region " << q << "," << r << " channel " << ch << ": ours " << mt[ch]
          << ", Tungsten " << mr[ch] << " (" << 100.0 * (mt[ch] / mr[ch] - 1.0)
          << "%), noise sigma " << sigma[ch] << ", model tolerance " << 100.0 * c.tolerance
          << "%";
        out.push_back(m.str());
      }
      ++checked;
    }
  EXPECT_GT(checked, 0);
  if (!c.excluded.empty())
    std::printf("%s: %zu of %d regions left out: %s\n", c.name, c.excluded.size(), cols * rows,
                c.why_excluded);
  return out;
}

void expect_agreement(const ReferenceCase& c) {
  if (!have_scene(c.name))
    GTEST_SKIP() << bitterli_dir() << "/" << c.name
                 << " is absent (the shared scenes lie beside the checkout)";
  for (const std::string& m : differing_regions(c)) ADD_FAILURE() << m;
}

TEST(Reference, CornellBoxMatchesTungstenWithinTheNoise) {
  // Diffuse only: no model difference at all.
  expect_agreement({"cornell-box", 64, 8, 128, 0.0, 4, 4, {}, ""});
}

// The check can fail: the depth the file was lowered to (pbrt maxdepth 4: 4 segments) misses the
// light of the longer paths, and the regions say so.
TEST(Reference, ACornellBoxCutShortDiffers) {
  if (!have_scene("cornell-box")) GTEST_SKIP() << bitterli_dir() << "/cornell-box is absent";
  EXPECT_GE(differing_regions({"cornell-box", 4, 8, 128, 0.0, 4, 4, {}, ""}).size(), 8u);
}

TEST(Reference, VeachMisLightsAndWallsMatchTungsten) {
  // The lights and the diffuse wall match to the noise; the plates are Tungsten's rough
  // conductors, whose parameters the pbrt-v4 conversion does not carry (BENCHMARKS.md).
  // An 8x6 grid: its top two rows hold the lights and the wall above the plates.
  expect_agreement({"veach-mis", 2, 8, 64, 0.0, 8, 6, rows_from(2, 8, 6),
               "the four plates (Tungsten's conductors differ: docs/BENCHMARKS.md)"});
}

TEST(Reference, CoffeeMatchesTungstenWithTheOriginalMaterials) {
  // The conversion gave the plastics pbrt-v4's absorbing coat (thickness 0.01, albedo 0) and
  // turned Tungsten's white mirror into silver; undone here, the rest agrees. Two thin bands
  // where the carafe's glass touches the insert and the ring (regions 1,2 and 2,2) are dark in
  // the reference: Tungsten's 5e-4 ray epsilon steps over the near face. Under the carafe (regions
  // 1,3 and 2,3) ours is 1.0-1.7% brighter at 2 x 8192 spp on the GPU, not explained yet: 2%.
  expect_agreement({"coffee", 16, 8, 96, 0.02, 4, 4, {{1, 2}, {2, 2}},
                    "the carafe's contact bands (Tungsten's ray epsilon: docs/BENCHMARKS.md)",
                    {"materials.Floor.thickness=0", "materials.Plastic_Orange.thickness=0",
                     "materials.Plastic_Black.thickness=0", "materials.Metal.type=mirror",
                     "materials.Metal.albedo=1,1,1"}});
}

TEST(Reference, ClassroomWaitsForTheOriginalSun) {
  GTEST_SKIP() << "classroom: the converted delta sun carries about a fifth more light than "
                  "Tungsten's sun cap, whose size and power the pbrt-v4 file lost; the interior "
                  "is 10-33% brighter (docs/BENCHMARKS.md), so no agreement is claimed";
}

TEST(Reference, WaterCausticNeedsCausticSampling) {
  GTEST_SKIP() << "water-caustic: the tank is lit only through the water surface by a 5 x 4 mm "
                  "light; plain path tracing finds it by BSDF sampling alone, far beyond a test's "
                  "samples. Light tracing through the tank's front converges it (on an H100 the "
                  "regions under the water within -2% to +5% of Tungsten's, docs/BENCHMARKS.md), "
                  "but the water's surface seen from below converges with no technique here";
}

}  // namespace
