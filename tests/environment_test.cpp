// The environment light's pieces: the equal-area octahedral map (both directions, equal area by
// a chi-square of uniform square points), the layout of both mappings, the map's sampling
// distribution (chi-square of its samples against its pdf, the pdf integrating to 1, samples and
// evaluation agreeing), and the readers of .pfm, .hdr and .exr (DWA included) on good and
// broken files, each error naming the file.
#include "scene/environment.h"

#include <ImfRgbaFile.h>
#include <gtest/gtest.h>
#include <stb_image_write.h>
#include <sys/stat.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include "chi_square.h"
#include "scene/loader.h"
#include "scene/scene.h"
#include "test_util.h"
#include "ui/workbench.h"

namespace {
using namespace tracer;
namespace fs = std::filesystem;

constexpr int kChi2Tests = 8;  // the chi-square tests in this file, for the Sidak correction

std::string temp_path(const std::string& name) {
  return testing::TempDir() + "/env_" + name;
}

// A PFM file: `rows` top to bottom, `channels` 1 or 3 floats per texel, written bottom to top.
void write_pfm(const std::string& path, int w, int h, int channels, const std::vector<float>& rows,
               bool little, float scale = 1.0f) {
  std::ofstream f(path, std::ios::binary);
  f << (channels == 3 ? "PF" : "Pf") << "\n"
    << w << " " << h << "\n"
    << (little ? -scale : scale) << "\n";
  for (int y = h - 1; y >= 0; --y)
    for (int i = 0; i < w * channels; ++i) {
      float v = rows[size_t(y) * size_t(w) * size_t(channels) + size_t(i)];
      unsigned char b[4];
      std::memcpy(b, &v, 4);  // the machine is little-endian
      if (!little) std::swap(b[0], b[3]), std::swap(b[1], b[2]);
      f.write(reinterpret_cast<const char*>(b), 4);
    }
}

// A synthetic sky: a gradient, a dark band, a bright 2x2 sun and a black region, so that the
// distribution has structure, zeros and a peak.
std::shared_ptr<EnvironmentImage> synthetic_map(int w, int h) {
  auto img = std::make_shared<EnvironmentImage>();
  img->path = "synthetic";
  img->width = w;
  img->height = h;
  img->rgba.assign(size_t(w) * size_t(h) * 4, 0.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* t = &img->rgba[4 * (size_t(y) * size_t(w) + size_t(x))];
      vec3 c = vec3(0.2f, 0.4f, 0.9f) * (1.0f + float(x) / float(w));
      if (y > h * 3 / 4) c = vec3(0.0f);  // black ground
      if (x >= w / 3 && x < w / 3 + 2 && y >= h / 4 && y < h / 4 + 2) c = vec3(80.0f, 70.0f, 60.0f);
      if (y == h / 2) c *= 0.05f;
      t[0] = c.x;
      t[1] = c.y;
      t[2] = c.z;
    }
  return img;
}

InfiniteLightsData lights_for(std::shared_ptr<const EnvironmentImage> img, EnvMapping m,
                              float rotation = 0.0f) {
  EnvironmentDesc d;
  d.file = img->path;
  d.mapping = m;
  d.rotation_deg = rotation;
  InfiniteLightsData out;
  build_infinite_lights(d, img, {}, &out);
  return out;
}

std::string read_error(const std::string& path) {
  try {
    read_environment_image(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

glm::dvec3 dv(vec3 v) {
  return glm::dvec3(v);
}

TEST(EqualArea, RoundTripsBothWays) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  float worst_dir = 0.0f, worst_square = 0.0f;
  for (int i = 0; i < 200000; ++i) {
    const vec2 p(u01(rng), u01(rng));
    const vec3 d = equal_area_square_to_sphere(p);
    ASSERT_NEAR(glm::length(d), 1.0f, 1e-5f);
    const vec2 q = equal_area_sphere_to_square(d);
    worst_square = std::max(worst_square, glm::length(q - p));
    const vec3 e = equal_area_square_to_sphere(q);
    worst_dir = std::max(worst_dir, glm::length(e - d));
  }
  // Float rounding near the poles (z = 1 - r^2 keeps r^2 to 6e-8 absolute): a sixth of a texel
  // of a 4096-texel map.
  EXPECT_LT(worst_square, 1e-4f);
  EXPECT_LT(worst_dir, 3e-4f);
  // pbrt-v4's layout: the centre is +z, the corners -z, the edges' midpoints the equator.
  EXPECT_LT(glm::length(equal_area_square_to_sphere(vec2(0.5f)) - vec3(0, 0, 1)), 1e-6f);
  for (vec2 c : {vec2(0, 0), vec2(1, 0), vec2(0, 1), vec2(1, 1)})
    EXPECT_LT(glm::length(equal_area_square_to_sphere(c) - vec3(0, 0, -1)), 1e-6f);
  EXPECT_LT(glm::length(equal_area_square_to_sphere(vec2(1.0f, 0.5f)) - vec3(1, 0, 0)), 1e-6f);
  EXPECT_LT(glm::length(equal_area_square_to_sphere(vec2(0.5f, 1.0f)) - vec3(0, 1, 0)), 1e-6f);
}

TEST(EqualArea, UniformSquarePointsAreUniformDirections) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  auto sample = [&](glm::dvec3& w) {
    w = dv(equal_area_square_to_sphere(vec2(u01(rng), u01(rng))));
    return true;
  };
  auto pdf = [](const glm::dvec3&) { return 1.0 / (4.0 * chi2::kPi); };
  chi2::SphereBins bins;
  const chi2::Result r = chi2::sphere_chi_square(sample, pdf, 1000000, bins, 0.01, kChi2Tests);
  EXPECT_TRUE(r.passed) << r.message;
}

TEST(EqualArea, MirroredWrapFindsTheSphereNeighbour) {
  // A texel just outside an edge is the sphere's neighbour of the texel just inside it.
  const int n = 64;
  for (int k = 0; k < n; ++k) {
    for (auto [x, y] : {std::pair{-1, k}, std::pair{n, k}, std::pair{k, -1}, std::pair{k, n}}) {
      int wx = x, wy = y;
      equal_area_wrap(wx, wy, n);
      ASSERT_TRUE(wx >= 0 && wx < n && wy >= 0 && wy < n);
      // The outside texel's centre, mapped with the unfolded formula, lands next to the wrapped
      // one.
      const vec2 outside((float(x) + 0.5f) / n, (float(y) + 0.5f) / n);
      const vec2 inside((float(wx) + 0.5f) / n, (float(wy) + 0.5f) / n);
      const vec2 edge = glm::clamp(outside, vec2(0.0f), vec2(1.0f));
      const float gap =
          glm::length(equal_area_square_to_sphere(inside) - equal_area_square_to_sphere(edge));
      EXPECT_LT(gap, 4.0f / n) << x << "," << y << " -> " << wx << "," << wy;
    }
  }
}

TEST(EnvMap, LayoutOfBothMappings) {
  // Equirectangular: the centre looks along +x, three quarters along +z, the top row up.
  EXPECT_LT(glm::length(env_map_dir(kEnvEquirect, vec2(0.5f, 0.5f)) - vec3(1, 0, 0)), 1e-6f);
  EXPECT_LT(glm::length(env_map_dir(kEnvEquirect, vec2(0.75f, 0.5f)) - vec3(0, 0, 1)), 1e-6f);
  EXPECT_LT(glm::length(env_map_dir(kEnvEquirect, vec2(0.3f, 0.0f)) - vec3(0, 1, 0)), 1e-6f);
  EXPECT_LT(glm::length(env_map_dir(kEnvEquirect, vec2(0.3f, 1.0f)) - vec3(0, -1, 0)), 1e-6f);
  // Octahedral: the centre up, the map's x our x, its y our -z.
  EXPECT_LT(glm::length(env_map_dir(kEnvOctahedral, vec2(0.5f)) - vec3(0, 1, 0)), 1e-6f);
  EXPECT_LT(glm::length(env_map_dir(kEnvOctahedral, vec2(1.0f, 0.5f)) - vec3(1, 0, 0)), 1e-6f);
  EXPECT_LT(glm::length(env_map_dir(kEnvOctahedral, vec2(0.5f, 1.0f)) - vec3(0, 0, -1)), 1e-6f);
  // Both directions of each mapping agree.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.01f, 0.99f);
  for (uint32_t kind : {uint32_t(kEnvEquirect), uint32_t(kEnvOctahedral)})
    for (int i = 0; i < 1000; ++i) {
      const vec2 p(u(rng), u(rng));
      EXPECT_LT(glm::length(env_map_uv(kind, env_map_dir(kind, p)) - p), 1e-4f);
    }
  // Rotation: +90 degrees turns the map's +x to the world's -z (counter-clockwise from above).
  const auto img = synthetic_map(16, 8);
  const InfiniteLightsData d = lights_for(img, EnvMapping::kEquirect, 90.0f);
  EXPECT_LT(glm::length(env_map_to_world(d.view, vec3(1, 0, 0)) - vec3(0, 0, -1)), 1e-6f);
  EXPECT_LT(glm::length(env_world_to_map(d.view, vec3(0, 0, -1)) - vec3(1, 0, 0)), 1e-6f);
}

TEST(EnvMap, BilinearLookupHitsTexelCentresAndWraps) {
  const auto img = synthetic_map(16, 8);
  const InfiniteLightsData d = lights_for(img, EnvMapping::kEquirect);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x) {
      const vec3 c = env_lookup(d.view, vec2((x + 0.5f) / 16.0f, (y + 0.5f) / 8.0f));
      const float* t = &img->rgba[4 * (size_t(y) * 16 + size_t(x))];
      EXPECT_NEAR(c.x, t[0], 1e-4f * (1.0f + t[0]));
    }
  // Across the seam at u = 0 the lookup blends the first and the last column.
  const vec3 seam = env_lookup(d.view, vec2(0.0f, 0.5f / 8.0f));
  const float* first = &img->rgba[0];
  const float* last = &img->rgba[4 * 15];
  EXPECT_NEAR(seam.x, 0.5f * (first[0] + last[0]), 1e-5f);
}

// The map's samples against its pdf, and the pdf's integral over the sphere.
void expect_sampling_matches_pdf(const InfiniteLights& v, const std::string& what,
                                 size_t n = 1000000) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  auto sample = [&](glm::dvec3& w) {
    float pdf;
    w = dv(env_sample(v, vec2(u01(rng), u01(rng)), &pdf));
    return pdf > 0.0f;
  };
  auto pdf = [&](const glm::dvec3& w) { return double(env_pdf(v, vec3(w))); };
  chi2::SphereBins bins;
  bins.basis = chi2::Basis(glm::dvec3(0, 1, 0));  // rows of latitude, as the maps are laid out
  // The pdf jumps at every texel edge (by 200x at the sun's), which the cells do not follow: a
  // fine midpoint rule keeps the expected counts exact to well below the noise.
  bins.integration_res = 40;
  const chi2::Result r = chi2::sphere_chi_square(sample, pdf, n, bins, 0.01, kChi2Tests);
  EXPECT_TRUE(r.passed) << what << ": " << r.message;
  EXPECT_NEAR(r.pdf_integral, 1.0, 2e-3) << what;
}

TEST(EnvMap, SamplingMatchesPdfEquirect) {
  const InfiniteLightsData d = lights_for(synthetic_map(64, 32), EnvMapping::kEquirect, 30.0f);
  expect_sampling_matches_pdf(d.view, "equirect 64x32, rotated 30 degrees");
}

TEST(EnvMap, SamplingMatchesPdfOctahedral) {
  const InfiniteLightsData d = lights_for(synthetic_map(48, 48), EnvMapping::kOctahedral);
  EXPECT_EQ(d.view.env, kEnvOctahedral);
  expect_sampling_matches_pdf(d.view, "octahedral 48x48");
}

// A large map's one-texel sun is far below the sphere test's cells: its samples are tested in
// the image instead, in blocks of texels whose probability is the exact sum of their cells',
// and the pdf evaluated at every cell's centre times its solid angle must sum to 1.
void expect_image_sampling_matches(const InfiniteLightsData& d, const std::string& what) {
  const InfiniteLights& v = d.view;
  const uint32_t bx = std::max(1u, v.width / 64), by = std::max(1u, v.height / 32);
  const uint32_t nx = v.width / bx, ny = v.height / by;
  std::vector<double> observed(size_t(nx) * ny, 0.0), expected(size_t(nx) * ny, 0.0);
  const size_t n = 2000000;
  for (uint32_t y = 0; y < v.height; ++y)
    for (uint32_t x = 0; x < v.width; ++x)
      expected[size_t(std::min(y / by, ny - 1)) * nx + std::min(x / bx, nx - 1)] +=
          double(d.func[size_t(y) * v.width + x]) / double(v.func_sum) * double(n);
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  for (size_t i = 0; i < n; ++i) {
    float pdf;
    const vec3 w = env_sample(v, vec2(u01(rng), u01(rng)), &pdf);
    if (pdf <= 0.0f) continue;
    const vec2 uv = env_map_uv(v.env, env_world_to_map(v, w));
    const uint32_t x = env_cell(uv.x, v.width), y = env_cell(uv.y, v.height);
    observed[size_t(std::min(y / by, ny - 1)) * nx + std::min(x / bx, nx - 1)] += 1.0;
  }
  const chi2::Result r = chi2::chi_square_test(observed, expected, 0.01, kChi2Tests);
  EXPECT_TRUE(r.passed) << what << ": " << r.message;
  double integral = 0.0;
  for (uint32_t y = 0; y < v.height; ++y)
    for (uint32_t x = 0; x < v.width; ++x) {
      const vec2 uv((x + 0.5f) / v.width, (y + 0.5f) / v.height);
      const vec3 w = env_map_to_world(v, env_map_dir(v.env, uv));
      integral += double(env_pdf(v, w)) * double(env_cell_solid_angle(v.env, y, v.width, v.height));
    }
  EXPECT_NEAR(integral, 1.0, 1e-3) << what;
}

TEST(EnvMap, SamplingMatchesPdfOnTheSharedMaps) {
  int tested = 0;
  const std::string sunrise = std::string(test::kBlenderWorlds) + "/sunrise.exr";
  if (fs::exists(sunrise)) {
    const InfiniteLightsData d =
        lights_for(read_environment_image(sunrise), EnvMapping::kAuto, 140.0f);
    EXPECT_EQ(d.view.env, kEnvEquirect);
    expect_image_sampling_matches(d, "sunrise.exr");
    ++tested;
  } else {
    std::printf("sunrise.exr skipped: %s is absent (Debian package blender-data)\n",
                test::kBlenderWorlds);
  }
  const std::string sky =
      test::source_dir() + "/../shared/scenes/bitterli/classroom/textures/Skydome.pfm";
  if (fs::exists(sky)) {
    const InfiniteLightsData d = lights_for(read_environment_image(sky), EnvMapping::kAuto);
    EXPECT_EQ(d.view.env, kEnvOctahedral);  // square: auto reads it as octahedral
    expect_image_sampling_matches(d, "Skydome.pfm");
    expect_sampling_matches_pdf(d.view, "Skydome.pfm (smooth: on the sphere too)");
    ++tested;
  } else {
    std::printf("Skydome.pfm skipped: the shared Bitterli scenes are absent\n");
  }
  if (tested == 0)
    GTEST_SKIP() << "neither blender-data's sunrise.exr nor the classroom's Skydome.pfm";
}

TEST(EnvMap, SampledPdfIsTheEvaluatedPdfAndCoversTheRadiance) {
  for (EnvMapping m : {EnvMapping::kEquirect, EnvMapping::kOctahedral}) {
    const InfiniteLightsData d =
        lights_for(synthetic_map(32, m == EnvMapping::kOctahedral ? 32 : 16), m, 45.0f);
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    int mismatches = 0;
    for (int i = 0; i < 100000; ++i) {
      float pdf;
      const vec3 w = env_sample(d.view, vec2(u01(rng), u01(rng)), &pdf);
      if (pdf <= 0.0f) continue;
      const float again = env_pdf(d.view, w);
      // Only at a cell boundary can rounding move the direction into the neighbour cell.
      if (std::abs(again - pdf) > 1e-3f * pdf) ++mismatches;
    }
    EXPECT_LT(mismatches, 50) << env_mapping_name(m);
    // Wherever the bilinear lookup gives radiance the pdf is positive (MIS needs both).
    for (int i = 0; i < 100000; ++i) {
      const vec3 w = sample_uniform_sphere(vec2(u01(rng), u01(rng)));
      if (max_component(env_radiance(d.view, w)) > 0.0f)
        ASSERT_GT(env_pdf(d.view, w), 0.0f) << env_mapping_name(m);
    }
  }
}

TEST(EnvMap, ConstantColourAndStrength) {
  EnvironmentDesc desc;
  desc.color = vec3(0.5f, 1.0f, 2.0f);
  desc.strength = 2.0f;
  InfiniteLightsData d;
  build_infinite_lights(desc, nullptr, {}, &d);
  EXPECT_EQ(d.view.env, kEnvConstant);
  EXPECT_EQ(env_radiance(d.view, vec3(0, 1, 0)), vec3(1.0f, 2.0f, 4.0f));
  EXPECT_NEAR(d.env_luminance_integral, 4.0 * M_PI * luminance(vec3(1, 2, 4)), 1e-4);
  desc.strength = 0.0f;  // nothing to light with
  build_infinite_lights(desc, nullptr, {}, &d);
  EXPECT_FALSE(d.any());
}

TEST(EnvReaders, PfmByteOrdersColourGreyAndScale) {
  // 3 x 2 texels, top row first: the file stores the bottom row first.
  const std::vector<float> rgb = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18};
  const std::vector<float> grey = {1, 2, 3, 4, 5, 6};
  for (bool little : {true, false}) {
    const std::string p = temp_path(little ? "le.pfm" : "be.pfm");
    write_pfm(p, 3, 2, 3, rgb, little);
    const auto img = read_environment_image(p);
    ASSERT_EQ(img->width, 3);
    ASSERT_EQ(img->height, 2);
    for (size_t t = 0; t < 6; ++t)
      for (size_t c = 0; c < 3; ++c) EXPECT_EQ(img->rgba[4 * t + c], rgb[3 * t + c]) << little;
    const std::string g = temp_path(little ? "le_grey.pfm" : "be_grey.pfm");
    write_pfm(g, 3, 2, 1, grey, little, 2.0f);  // |scale| multiplies, as pbrt-v4 reads it
    const auto gi = read_environment_image(g);
    for (size_t t = 0; t < 6; ++t)
      for (size_t c = 0; c < 3; ++c) EXPECT_EQ(gi->rgba[4 * t + c], 2.0f * grey[t]) << little;
  }
}

TEST(EnvReaders, HdrAndExrReadBack) {
  const int w = 8, h = 4;
  std::vector<float> rgb(size_t(w) * h * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = 0.25f + 0.5f * float(i % 7) + float(i / 3 % 5);
  const std::string hdr = temp_path("map.hdr");
  ASSERT_TRUE(stbi_write_hdr(hdr.c_str(), w, h, 3, rgb.data()));
  const auto a = read_environment_image(hdr);
  ASSERT_EQ(a->width, w);
  for (size_t t = 0; t < size_t(w) * h; ++t)
    for (size_t c = 0; c < 3; ++c)
      EXPECT_NEAR(a->rgba[4 * t + c], rgb[3 * t + c], 0.01f * rgb[3 * t + c]);
  // OpenEXR, losslessly (ZIP: half precision) and with DWAA (lossy, as the world maps are).
  for (Imf::Compression comp : {Imf::ZIP_COMPRESSION, Imf::DWAA_COMPRESSION}) {
    const int ew = 64, eh = 32;  // DWA works in 8x8 blocks
    std::vector<Imf::Rgba> px(size_t(ew) * eh);
    for (int y = 0; y < eh; ++y)
      for (int x = 0; x < ew; ++x)
        px[size_t(y) * ew + x] = Imf::Rgba(0.5f + 0.01f * x, 0.25f + 0.02f * y, 2.0f, 1.0f);
    const std::string exr = temp_path(comp == Imf::ZIP_COMPRESSION ? "zip.exr" : "dwaa.exr");
    {
      Imf::RgbaOutputFile out(exr.c_str(), ew, eh, Imf::WRITE_RGBA, 1.0f, Imath::V2f(0, 0), 1.0f,
                              Imf::INCREASING_Y, comp);
      out.setFrameBuffer(px.data(), 1, size_t(ew));
      out.writePixels(eh);
    }
    const auto e = read_environment_image(exr);
    ASSERT_EQ(e->width, ew);
    ASSERT_EQ(e->height, eh);
    const float tol = comp == Imf::ZIP_COMPRESSION ? 1e-3f : 0.03f;
    for (int y = 0; y < eh; ++y)
      for (int x = 0; x < ew; ++x) {
        const float* t = &e->rgba[4 * (size_t(y) * ew + size_t(x))];
        EXPECT_NEAR(t[0], 0.5f + 0.01f * x, tol * 2.0f);
        EXPECT_NEAR(t[1], 0.25f + 0.02f * y, tol * 2.0f);
        EXPECT_NEAR(t[2], 2.0f, tol * 2.0f);
      }
  }
}

TEST(EnvReaders, BadFilesNameTheFile) {
  const std::string missing = temp_path("missing.hdr");
  EXPECT_NE(read_error(missing).find(missing + ": no such file"), std::string::npos)
      << read_error(missing);
  // A pipe (or a device) could be read for ever: refused before reading.
  const std::string fifo = temp_path("fifo.pfm");
  fs::remove(fifo);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_NE(read_error(fifo).find(fifo + ": is not a regular file"), std::string::npos)
      << read_error(fifo);
  const std::string png = temp_path("map.png");
  std::ofstream(png) << "x";
  EXPECT_NE(read_error(png).find(png + ": environment maps must be .hdr, .pfm or .exr files"),
            std::string::npos)
      << read_error(png);
  struct Case {
    const char* name;
    std::string text;
    const char* expected;
  };
  const std::vector<Case> pfm = {
      {"p6.pfm", "P6\n2 2\n255\n", ":1: not a PFM file"},
      {"width.pfm", "PF\nw 2\n-1\n", ":2: the PFM width \"w\" is not a whole number"},
      {"negative.pfm", "PF\n-2 2\n-1\n", ":2: the PFM width \"-2\""},
      {"zero.pfm", "PF\n0 2\n-1\n", ":2: map size 0x2 is empty or too large"},
      {"scale.pfm", "PF\n2 2\n0\n", ":3: the PFM scale \"0\" is not a non-zero number"},
      {"header.pfm", "PF\n2", ":2: the header ends before its height"},
      {"short.pfm", std::string("PF\n2 2\n-1\n") + std::string(40, '\0'),
       ": truncated: 2x2 RGB texels need 48 bytes of data, the file has 40 after its header"},
      {"empty.pfm", "", ": the file is empty"},
  };
  for (const Case& c : pfm) {
    const std::string p = temp_path(c.name);
    std::ofstream(p, std::ios::binary) << c.text;
    const std::string e = read_error(p);
    EXPECT_NE(e.find(p + c.expected), std::string::npos) << c.name << ": " << e;
    EXPECT_NE(e.find("the environment map was not loaded"), std::string::npos) << e;
  }
  // NaN and infinite texels are errors naming the texel.
  for (float bad : {std::nanf(""), INFINITY}) {
    const std::string p = temp_path(std::isnan(bad) ? "nan.pfm" : "inf.pfm");
    write_pfm(p, 2, 2, 3, {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, bad, 1}, true);
    const std::string e = read_error(p);
    EXPECT_NE(e.find(p + ": texel (1, 1) is " + (std::isnan(bad) ? "NaN" : "infinite")),
              std::string::npos)
        << e;
  }
  // Truncated Radiance and OpenEXR files (a good file cut short) and garbage with their names.
  const int w = 64, h = 32;
  std::vector<float> rgb(size_t(w) * h * 3, 1.5f);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] += float(i % 13);
  const std::string hdr = temp_path("cut.hdr");
  ASSERT_TRUE(stbi_write_hdr(hdr.c_str(), w, h, 3, rgb.data()));
  fs::resize_file(hdr, fs::file_size(hdr) / 2);
  EXPECT_NE(read_error(hdr).find(hdr + ": "), std::string::npos) << read_error(hdr);
  const std::string exr = temp_path("cut.exr");
  {
    std::vector<Imf::Rgba> px(size_t(w) * h, Imf::Rgba(1.0f, 2.0f, 3.0f, 1.0f));
    Imf::RgbaOutputFile out(exr.c_str(), w, h, Imf::WRITE_RGBA, 1.0f, Imath::V2f(0, 0), 1.0f,
                            Imf::INCREASING_Y, Imf::DWAA_COMPRESSION);
    out.setFrameBuffer(px.data(), 1, size_t(w));
    out.writePixels(h);
  }
  fs::resize_file(exr, fs::file_size(exr) * 2 / 3);
  EXPECT_NE(read_error(exr).find(exr + ": cannot read the OpenEXR file"), std::string::npos)
      << read_error(exr);
  const std::string garbage = temp_path("garbage.exr");
  std::ofstream(garbage) << "not an exr file at all";
  EXPECT_NE(read_error(garbage).find(garbage + ": cannot read the OpenEXR file"), std::string::npos)
      << read_error(garbage);
  const std::string text_hdr = temp_path("text.hdr");
  std::ofstream(text_hdr) << "hello";
  EXPECT_NE(read_error(text_hdr).find(text_hdr + ":1: not a Radiance HDR file"), std::string::npos)
      << read_error(text_hdr);
}

// Every truncation (in steps) and random byte damage of a good file loads or fails with an
// InputError naming it: never a crash, a hang (stb_image's run-length loop) or a silent short read.
TEST(EnvReaders, EveryTruncationAndRandomDamageFailsCleanly) {
  const int w = 64, h = 32;
  std::vector<float> rgb(size_t(w) * h * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = 0.1f + float(i % 29) * 0.7f;
  const std::string hdr = temp_path("good.hdr"), pfm = temp_path("good.pfm"),
                    exr = temp_path("good.exr");
  ASSERT_TRUE(stbi_write_hdr(hdr.c_str(), w, h, 3, rgb.data()));
  write_pfm(pfm, w, h, 3, rgb, false);
  {
    std::vector<Imf::Rgba> px(size_t(w) * h);
    for (size_t i = 0; i < px.size(); ++i)
      px[i] = Imf::Rgba(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]);
    Imf::RgbaOutputFile out(exr.c_str(), w, h, Imf::WRITE_RGBA, 1.0f, Imath::V2f(0, 0), 1.0f,
                            Imf::INCREASING_Y, Imf::DWAA_COMPRESSION);
    out.setFrameBuffer(px.data(), 1, size_t(w));
    out.writePixels(h);
  }
  std::mt19937 rng(99);
  for (const std::string& good : {hdr, pfm, exr}) {
    std::ifstream f(good, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    const std::string ext = fs::path(good).extension().string();
    const std::string bad = temp_path("damaged" + ext);
    int loaded = 0, failed = 0;
    auto attempt = [&](const std::string& data) {
      std::ofstream(bad, std::ios::binary) << data;
      try {
        const auto img = read_environment_image(bad);
        EXPECT_GT(img->width, 0);
        ++loaded;
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
        ++failed;
      }
    };
    const size_t step = std::max<size_t>(1, bytes.size() / 300);
    for (size_t len = 0; len < bytes.size(); len += step) attempt(bytes.substr(0, len));
    for (int k = 0; k < 300; ++k) {
      std::string d = bytes;
      for (int n = 0; n < 1 + k % 4; ++n) d[rng() % d.size()] = char(rng() & 0xff);
      attempt(d);
    }
    std::printf("%s: %d damaged files loaded, %d refused\n", ext.c_str(), loaded, failed);
    EXPECT_GT(failed, 0);
  }
}

TEST(EnvReaders, NegativeTexelsAreClampedWithOneWarning) {
  const std::string p = temp_path("negative.pfm");
  write_pfm(p, 2, 2, 3, {1, -0.001f, 1, 1, 1, 1, -0.5f, 1, 1, 1, 1, -0.002f}, true);
  Scene s;
  s.environment.file = p;
  EXPECT_EQ(refresh_environment(s), "");
  ASSERT_TRUE(s.environment_image);
  EXPECT_EQ(s.environment_image->negative, 3u);
  EXPECT_EQ(s.environment_image->rgba[1], 0.0f);
  ASSERT_EQ(s.diagnostics.warnings.size(), 1u);
  EXPECT_NE(s.diagnostics.warnings[0].find(p + ": 3 negative texel values (as low as -0.5"),
            std::string::npos)
      << s.diagnostics.warnings[0];
  EXPECT_EQ(refresh_environment(s), "");  // the same file again: not read again, no new warning
  EXPECT_EQ(s.diagnostics.warnings.size(), 1u);
}

TEST(EnvReaders, BlenderWorldMaps) {
  if (!fs::exists(test::kBlenderWorlds))
    GTEST_SKIP() << test::kBlenderWorlds << " is absent (Debian package blender-data)";
  int count = 0;
  for (const char* name :
       {"city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"}) {
    const std::string p = std::string(test::kBlenderWorlds) + "/" + name + ".exr";
    const auto img = read_environment_image(p);  // DWA-compressed: tinyexr cannot read these
    EXPECT_EQ(img->width, 1024) << name;
    EXPECT_EQ(img->height, 512) << name;
    float peak = 0.0f;
    for (size_t i = 0; i < img->rgba.size(); ++i) peak = std::max(peak, img->rgba[i]);
    std::printf("%-10s peak %8.1f, %llu negative texel values clamped (lowest %.4f)\n", name,
                double(peak), (unsigned long long)img->negative, double(img->most_negative));
    ++count;
  }
  EXPECT_EQ(count, 8);
}

// ---- the scene format and the settings table ----------------------------------------------

const char* kObjects =
    R"("materials": {"m": {}}, "objects": [{"type": "sphere", "radius": 1, "material": "m"}])";

std::string load_error(const std::string& text, const std::string& path) {
  try {
    load_scene_from_json(text, path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(EnvScene, FileIsRelativeToTheSceneAndErrorsPointAtIt) {
  const std::string dir = temp_path("scene_dir");
  fs::create_directories(dir + "/maps");
  write_pfm(dir + "/maps/sky.pfm", 4, 2, 3, std::vector<float>(24, 1.0f), true);
  const std::string scene = dir + "/scene.json";
  std::ofstream(scene) << "{\"environment\": {\"file\": \"maps/sky.pfm\", \"strength\": 2},\n"
                       << kObjects << "}";
  const Scene s = load_scene(scene);
  EXPECT_EQ(s.environment.file, fs::absolute(dir + "/maps/sky.pfm").lexically_normal().string());
  ASSERT_TRUE(s.environment_image);
  EXPECT_EQ(s.environment_image->width, 4);
  EXPECT_EQ(s.environment.strength, 2.0f);
  // A missing map: the scene's line, then the map's own message.
  const std::string e = load_error(
      "{\"environment\": {\n\"file\": \"nope.hdr\"}, " + std::string(kObjects) + "}", scene);
  EXPECT_NE(e.find(scene + ":2: "), std::string::npos) << e;
  EXPECT_NE(e.find("nope.hdr: no such file"), std::string::npos) << e;
  EXPECT_NE(e.find("nothing was rendered"), std::string::npos) << e;
  // An octahedral map must be square.
  const std::string o = load_error(
      "{\"environment\": {\"file\": \"maps/sky.pfm\",\n\"mapping\": "
      "\"octahedral\"}, " +
          std::string(kObjects) + "}",
      scene);
  EXPECT_NE(o.find("an octahedral map must be square, not 4x2"), std::string::npos) << o;
}

TEST(EnvScene, EveryEntryPointReadsTheMapAndKeepsTheOldOneOnAProblem) {
  const std::string good = temp_path("good.pfm");
  write_pfm(good, 4, 2, 3, std::vector<float>(24, 1.0f), true);
  Scene s = builtin_default_scene();
  EXPECT_EQ(set_setting_assignment(s, "environment.file=" + good), "");
  ASSERT_TRUE(s.environment_image);
  const std::string bad = temp_path("bad.pfm");
  std::ofstream(bad) << "P6\n";
  const std::string m = set_setting_assignment(s, "environment.file=" + bad);
  EXPECT_NE(m.find(bad + ":1: not a PFM file"), std::string::npos) << m;
  EXPECT_EQ(s.environment.file, good);  // restored, with its image
  EXPECT_EQ(s.environment_image->path, good);
  EXPECT_EQ(set_setting_assignment(s, "environment.file="), "");
  EXPECT_FALSE(s.environment_image);
}

TEST(EnvScene, WorkbenchEditsRestartAndABadFileKeepsTheMap) {
  const std::string map = temp_path("wb.pfm");
  write_pfm(map, 8, 4, 3, std::vector<float>(96, 0.5f), true);
  Scene s = builtin_default_scene();
  s.settings.width = s.settings.height = 8;
  ui::Workbench wb(s, BackendChoice::kCpu, 1);
  std::string err;
  ASSERT_TRUE(wb.apply("environment.file=" + map, &err)) << err;
  ASSERT_TRUE(wb.scene().environment_image);
  std::vector<uint32_t> rgba;
  int w = 0, h = 0;
  EXPECT_TRUE(wb.environment_preview(rgba, w, h));
  EXPECT_EQ(w, 8);
  EXPECT_EQ(h, 4);
  EXPECT_FALSE(wb.environment_preview(rgba, w, h)) << "nothing new to draw";
  EXPECT_NE(wb.environment_summary().find("8x4 equirect (auto)"), std::string::npos)
      << wb.environment_summary();
  for (const char* edit :
       {"environment.strength=2", "environment.rotation=45", "environment.visible=off",
        "environment.background=0.1,0.2,0.3", "environment.mapping=equirect"}) {
    wb.update();
    const uint64_t before = wb.stats().resets;
    ASSERT_TRUE(wb.apply(edit, &err)) << err;
    wb.update();  // the frame that applies the edit resets
    EXPECT_EQ(wb.stats().resets, before + 1) << edit;
  }
  EXPECT_TRUE(wb.environment_preview(rgba, w, h)) << "the strength changed the preview";
  const std::string missing = temp_path("missing.exr");
  EXPECT_FALSE(wb.apply("environment.file=" + missing, &err));
  EXPECT_NE(err.find(missing + ": no such file"), std::string::npos) << err;
  EXPECT_EQ(wb.scene().environment.file, map);
  EXPECT_FALSE(wb.apply("environment.mapping=octahedral", &err));  // 8x4 is not square
  EXPECT_NE(err.find("must be square"), std::string::npos) << err;
}

TEST(EnvScene, DistantLights) {
  const Scene s = load_scene_from_json(
      R"({"lights": [{"type": "distant", "name": "sun", "direction": [0, 2, 0],
                      "irradiance": [3, 2, 1], "angular_diameter": 0.53}], )" +
          std::string(kObjects) + "}",
      "sun.json");
  ASSERT_EQ(s.distant_lights.size(), 1u);
  EXPECT_EQ(s.distant_lights[0].name, "sun");
  EXPECT_EQ(s.distant_lights[0].irradiance, vec3(3, 2, 1));
  EXPECT_FLOAT_EQ(s.distant_lights[0].angular_diameter_deg, 0.53f);
  InfiniteLightsData d;
  build_infinite_lights(s.environment, nullptr, s.distant_lights, &d);
  ASSERT_EQ(d.distant.size(), 1u);
  EXPECT_EQ(d.distant[0].dir, vec3(0, 1, 0));
  // The cone's radiance gives the irradiance back: E = L pi sin^2(half-angle).
  const double a = 0.5 * 0.53 * M_PI / 180.0;
  EXPECT_NEAR(d.distant[0].radiance.x * M_PI * std::sin(a) * std::sin(a), 3.0, 1e-4);
  EXPECT_NEAR(d.distant[0].one_minus_cos, 1.0 - std::cos(a), 1e-9);
  struct Bad {
    const char* light;
    const char* expected;
  };
  for (const Bad& b : {
           Bad{R"({"type": "sun", "direction": [0, 1, 0]})",
               "sun.json:2: unknown light type \"sun\""},
           Bad{R"({"type": "distant"})", "has no \"direction\""},
           Bad{R"({"type": "distant", "direction": [0, 0, 0]})", "must be a non-zero vector"},
           Bad{R"({"type": "distant", "direction": [0, 1, 0], "irradiance": [1, -1, 1]})",
               "\"irradiance\" of light 0 must be >= 0"},
           Bad{R"({"type": "distant", "direction": [0, 1, 0], "angular_diameter": 180})",
               "must be in [0, 180) degrees"},
           Bad{R"({"type": "distant", "direction": [0, 1, 0], "radiance": [1, 1, 1]})",
               "unknown key \"radiance\" in light 0"},
       }) {
    const std::string e =
        load_error(std::string("{\"lights\": [\n") + b.light + "], " + kObjects + "}", "sun.json");
    EXPECT_NE(e.find(b.expected), std::string::npos) << b.light << "\n" << e;
    EXPECT_EQ(e.rfind("sun.json:", 0), 0u) << e;
  }
}

}  // namespace
