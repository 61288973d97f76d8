// Tests for tracer/image: the sRGB transfer functions and tone maps, PNG/EXR round trips, atomic
// writes, loaders on broken files, and the error metrics against hand-computed values.
#include "image/image.h"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <tinyexr.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/diagnostics.h"

namespace tracer {
namespace {

namespace fs = std::filesystem;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// A fresh directory per test, removed afterwards.
class ImageFileTest : public testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = testing::TempDir() + "image_test_XXXXXX";
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  // Every entry directly in `d`, so a leftover temporary file shows up.
  static std::vector<std::string> list(const fs::path& d) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(d)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }
  static void write_bytes(const std::string& p, const std::string& bytes) {
    std::ofstream(p, std::ios::binary) << bytes;
  }
  static std::string read_bytes(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  fs::path dir_;
};

// Expects `fn` to throw InputError whose message contains `needle` (the file's path).
template <typename Fn>
void expect_input_error(Fn fn, const std::string& needle) {
  try {
    fn();
    ADD_FAILURE() << "no InputError thrown; expected one mentioning " << needle;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

ImageRGB random_image(int w, int h, float scale, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, scale);
  ImageRGB img = make_image(w, h);
  for (float& v : img.pixels) v = u(rng);
  return img;
}

// ---- sRGB and tone mapping --------------------------------------------------------------------

TEST(Srgb, KnownValues) {
  EXPECT_EQ(to_srgb8(0.0f), 0);
  EXPECT_EQ(to_srgb8(1.0f), 255);
  // 1.055 * 0.5^(1/2.4) - 0.055 = 0.73536 -> 187.5 -> 188.
  EXPECT_EQ(to_srgb8(0.5f), 188);
  // 0.214 encodes to 0.49996, half way between codes 127 and 128.
  EXPECT_NEAR(to_srgb8(0.214f), 128, 1);
  EXPECT_NEAR(srgb_to_linear(128.0f / 255.0f), 0.2158605f, 1e-6f);
  // Out-of-range and bad values clamp rather than wrap.
  EXPECT_EQ(to_srgb8(2.0f), 255);
  EXPECT_EQ(to_srgb8(-1.0f), 0);
  EXPECT_EQ(to_srgb8(kNaN), 0);
}

TEST(Srgb, PiecewiseBoundaryIsContinuous) {
  // Both branches of IEC 61966-2-1 meet at linear 0.0031308 / encoded 0.04045.
  const float below = std::nextafter(0.0031308f, 0.0f);
  const float above = std::nextafter(0.0031308f, 1.0f);
  EXPECT_NEAR(linear_to_srgb(0.0031308f), 0.04045f, 1e-6f);
  EXPECT_NEAR(linear_to_srgb(below), 12.92f * below, 1e-7f);
  EXPECT_NEAR(linear_to_srgb(above), linear_to_srgb(below), 1e-6f);
  EXPECT_NEAR(srgb_to_linear(0.04045f), 0.0031308f, 1e-7f);
  EXPECT_FLOAT_EQ(srgb_to_linear(0.02f), 0.02f / 12.92f);
}

TEST(Srgb, RoundTrips) {
  for (int code = 0; code < 256; ++code) {
    EXPECT_EQ(to_srgb8(srgb_to_linear(code / 255.0f)), code);
  }
  for (int i = 0; i <= 1000; ++i) {
    const float x = i / 1000.0f;
    EXPECT_NEAR(srgb_to_linear(linear_to_srgb(x)), x, 1e-5f + 1e-5f * x);
  }
}

TEST(ToneMap, Operators) {
  EXPECT_EQ(tone_map(vec3(0.25f, 2.0f, -1.0f), ToneMap::kNone), vec3(0.25f, 1.0f, 0.0f));
  EXPECT_EQ(tone_map(vec3(1.0f, 3.0f, 0.0f), ToneMap::kReinhard), vec3(0.5f, 0.75f, 0.0f));
  // Narkowicz: f(0) = 0, f(1) = 2.54 / 3.16, and the curve saturates at 1.
  const vec3 aces = tone_map(vec3(0.0f, 1.0f, 1e6f), ToneMap::kAces);
  EXPECT_FLOAT_EQ(aces.x, 0.0f);
  EXPECT_NEAR(aces.y, 2.54f / 3.16f, 1e-6f);
  EXPECT_FLOAT_EQ(aces.z, 1.0f);
  float previous = 0.0f;
  for (int i = 1; i <= 100; ++i) {
    const float v = tone_map(vec3(i * 0.1f), ToneMap::kAces).x;
    EXPECT_GE(v, previous);
    previous = v;
  }
  for (ToneMap op : {ToneMap::kNone, ToneMap::kReinhard, ToneMap::kAces}) {
    EXPECT_EQ(tone_map(vec3(kNaN, kInf, -kInf), op), vec3(0.0f)) << tone_map_name(op);
  }
}

TEST(ToneMap, Names) {
  for (ToneMap op : {ToneMap::kNone, ToneMap::kReinhard, ToneMap::kAces}) {
    ToneMap parsed = ToneMap::kNone;
    EXPECT_TRUE(parse_tone_map(tone_map_name(op), &parsed));
    EXPECT_EQ(parsed, op);
  }
  ToneMap op = ToneMap::kReinhard;
  EXPECT_TRUE(parse_tone_map("ACES", &op));
  EXPECT_EQ(op, ToneMap::kAces);
  EXPECT_FALSE(parse_tone_map("filmic", &op));
  EXPECT_EQ(op, ToneMap::kAces);
}

// ---- Round trips ------------------------------------------------------------------------------

TEST_F(ImageFileTest, PngRoundTripWithinOneCode) {
  const ImageRGB img = random_image(7, 5, 1.0f, 1);
  write_image(path("a.png"), img);
  const ImageRGB back = read_image(path("a.png"));
  ASSERT_EQ(back.width, 7);
  ASSERT_EQ(back.height, 5);
  for (size_t i = 0; i < img.pixels.size(); ++i) {
    // Compared in the encoded domain, where the quantisation step is uniform.
    EXPECT_NEAR(linear_to_srgb(back.pixels[i]), linear_to_srgb(img.pixels[i]), 1.0f / 255.0f);
    EXPECT_EQ(to_srgb8(back.pixels[i]), to_srgb8(img.pixels[i]));
  }
}

TEST_F(ImageFileTest, PngAppliesExposureAndWritesBadValuesAsBlack) {
  ImageRGB img = make_image(2, 2, vec3(0.25f));
  img.set(1, 0, vec3(kNaN, kInf, -kInf));
  img.set(0, 1, vec3(7.0f, -3.0f, 0.0f));
  write_image(path("UPPER.PNG"), img, 1.0f);  // +1 stop: 0.25 -> 0.5; extension case ignored
  const ImageRGB back = read_image(path("UPPER.PNG"));
  EXPECT_EQ(to_srgb8(back.at(0, 0).x), 188);
  EXPECT_EQ(back.at(1, 0), vec3(0.0f));
  EXPECT_EQ(back.at(0, 1), vec3(1.0f, 0.0f, 0.0f));
}

TEST_F(ImageFileTest, ExrRoundTripIsExact) {
  // 20x17 is stored ZIP-compressed, 3x2 uncompressed; both must be bit exact incl. values > 1.
  for (auto [w, h] : {std::pair{20, 17}, std::pair{3, 2}}) {
    ImageRGB img = random_image(w, h, 50.0f, 2);
    img.set(0, 0, vec3(1e-30f, 65504.0f * 4.0f, 0.1f));  // outside half's range: float is kept
    img.set(1, 0, vec3(-2.5f, 0.0f, 1.0f));
    img.set(2, 1, vec3(kNaN, 3.0f, 1e7f));
    const std::string p = path("img_" + std::to_string(w) + ".exr");
    write_image(p, img, 3.0f, ToneMap::kAces);  // display settings must not touch EXR data
    const ImageRGB back = read_image(p);
    ASSERT_EQ(back.width, w);
    ASSERT_EQ(back.height, h);
    for (size_t i = 0; i < img.pixels.size(); ++i) {
      if (std::isnan(img.pixels[i])) {
        EXPECT_TRUE(std::isnan(back.pixels[i]));
      } else {
        EXPECT_EQ(back.pixels[i], img.pixels[i]) << "value " << i << " of " << w << "x" << h;
      }
    }
  }
}

TEST_F(ImageFileTest, ReadsTiledExr) {
  // Other tools write tiled files; build one with tinyexr directly: 20x13 in 8x8 tiles, so the
  // right and bottom tiles are partial. Tile buffers are tile_size_x wide whatever their width.
  constexpr int kW = 20, kH = 13, kT = 8, kTilesX = 3, kTilesY = 2;
  auto value = [](int x, int y, int c) { return 100.0f * c + 10.0f * y + 0.5f * x; };
  std::vector<std::vector<float>> planes(kTilesX * kTilesY * 3, std::vector<float>(kT * kT));
  std::vector<std::vector<unsigned char*>> tile_channels(kTilesX * kTilesY);
  std::vector<EXRTile> tiles(kTilesX * kTilesY);
  for (int ty = 0; ty < kTilesY; ++ty) {
    for (int tx = 0; tx < kTilesX; ++tx) {
      const int t = ty * kTilesX + tx;
      EXRTile& tile = tiles[t];
      tile = EXRTile{};
      tile.offset_x = tx;
      tile.offset_y = ty;
      tile.width = std::min(kT, kW - tx * kT);
      tile.height = std::min(kT, kH - ty * kT);
      for (int c = 0; c < 3; ++c) {  // channels stored B, G, R
        std::vector<float>& plane = planes[3 * t + c];
        for (int j = 0; j < tile.height; ++j) {
          for (int i = 0; i < tile.width; ++i) {
            plane[j * kT + i] = value(tx * kT + i, ty * kT + j, 2 - c);
          }
        }
        tile_channels[t].push_back(reinterpret_cast<unsigned char*>(plane.data()));
      }
      tile.images = tile_channels[t].data();
    }
  }
  EXRImage image;
  InitEXRImage(&image);
  image.tiles = tiles.data();
  image.num_tiles = kTilesX * kTilesY;
  image.num_channels = 3;
  image.width = kW;
  image.height = kH;
  EXRChannelInfo channels[3] = {};
  int types[3] = {TINYEXR_PIXELTYPE_FLOAT, TINYEXR_PIXELTYPE_FLOAT, TINYEXR_PIXELTYPE_FLOAT};
  int requested[3] = {TINYEXR_PIXELTYPE_HALF, TINYEXR_PIXELTYPE_HALF, TINYEXR_PIXELTYPE_HALF};
  for (int c = 0; c < 3; ++c) channels[c].name[0] = "BGR"[c];
  EXRHeader header;
  InitEXRHeader(&header);
  header.num_channels = 3;
  header.channels = channels;
  header.pixel_types = types;
  header.requested_pixel_types = requested;  // stored as half: exercises half -> float too
  header.compression_type = TINYEXR_COMPRESSIONTYPE_ZIP;
  header.tiled = 1;
  header.tile_size_x = kT;
  header.tile_size_y = kT;
  header.tile_level_mode = TINYEXR_TILE_ONE_LEVEL;
  header.data_window = {0, 0, kW - 1, kH - 1};  // tinyexr counts tiles from the header
  header.display_window = header.data_window;
  const char* err = nullptr;
  ASSERT_EQ(SaveEXRImageToFile(&image, &header, path("tiled.exr").c_str(), &err), TINYEXR_SUCCESS)
      << (err ? err : "");

  const ImageRGB back = read_image(path("tiled.exr"));
  ASSERT_EQ(back.width, kW);
  ASSERT_EQ(back.height, kH);
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      for (int c = 0; c < 3; ++c) {
        // All values are multiples of 0.5 below 256: exact in half precision.
        ASSERT_EQ(back.at(x, y)[c], value(x, y, c)) << x << "," << y << " channel " << c;
      }
    }
  }
}

// ---- Atomic writes ----------------------------------------------------------------------------

TEST_F(ImageFileTest, CreatesMissingParentDirectories) {
  const std::string p = path("a/b/c/out.exr");
  write_image(p, make_image(2, 1, vec3(1.0f)));
  EXPECT_EQ(read_image(p).at(1, 0), vec3(1.0f));
  EXPECT_EQ(list(dir_ / "a/b/c"), std::vector<std::string>{"out.exr"});
}

TEST_F(ImageFileTest, OverwritesAndLeavesNoTemporaryFiles) {
  write_image(path("out.png"), make_image(2, 2, vec3(0.0f)));
  write_image(path("out.png"), make_image(3, 1, vec3(1.0f)));
  const ImageRGB back = read_image(path("out.png"));
  EXPECT_EQ(back.width, 3);
  EXPECT_EQ(back.at(2, 0), vec3(1.0f));
  write_text_atomic(path("scene.json"), "{\"a\": 1}\n");
  write_text_atomic(path("scene.json"), "{}\n");
  EXPECT_EQ(read_bytes(path("scene.json")), "{}\n");
  EXPECT_EQ(list(dir_), (std::vector<std::string>{"out.png", "scene.json"}));
}

TEST_F(ImageFileTest, ParentIsARegularFileThrows) {
  write_bytes(path("file.txt"), "not a directory");
  const std::string p = path("file.txt/out.png");
  expect_input_error([&] { write_image(p, make_image(1, 1)); }, p);
  expect_input_error([&] { write_text_atomic(path("file.txt/sub/x.json"), "{}"); }, "file.txt");
  EXPECT_EQ(list(dir_), std::vector<std::string>{"file.txt"});
  EXPECT_EQ(read_bytes(path("file.txt")), "not a directory");
}

TEST_F(ImageFileTest, FailedReplaceKeepsTargetAndRemovesTemporary) {
  // The target is a non-empty directory, so the final rename() fails after the temporary file
  // has been written: the failure mode that matters, and one that also fails when run as root.
  fs::create_directory(path("out.png"));
  write_bytes(path("out.png/keep"), "precious");
  expect_input_error([&] { write_image(path("out.png"), make_image(4, 4, vec3(0.5f))); },
                     path("out.png"));
  EXPECT_EQ(list(dir_), std::vector<std::string>{"out.png"});
  EXPECT_EQ(read_bytes(path("out.png/keep")), "precious");
}

TEST_F(ImageFileTest, UnwritableDirectoryKeepsExistingFile) {
  if (geteuid() == 0) GTEST_SKIP() << "running as root: directory permissions are not enforced";
  write_image(path("ro/out.png"), make_image(1, 1, vec3(1.0f)));
  const std::string before = read_bytes(path("ro/out.png"));
  fs::permissions(path("ro"), fs::perms::owner_read | fs::perms::owner_exec);
  expect_input_error([&] { write_image(path("ro/out.png"), make_image(1, 1)); }, "ro/out.png");
  fs::permissions(path("ro"), fs::perms::owner_all);
  EXPECT_EQ(read_bytes(path("ro/out.png")), before);
  EXPECT_EQ(list(dir_ / "ro"), std::vector<std::string>{"out.png"});
}

TEST_F(ImageFileTest, RejectsUnknownExtensionAndEmptyImage) {
  expect_input_error([&] { write_image(path("out.bmp"), make_image(1, 1)); }, "out.bmp");
  expect_input_error([&] { write_image(path("noext"), make_image(1, 1)); }, "noext");
  expect_input_error([&] { write_image(path("empty.png"), ImageRGB{}); }, "empty.png");
  EXPECT_TRUE(list(dir_).empty());
}

// ---- Loaders on broken input ------------------------------------------------------------------

TEST_F(ImageFileTest, ReadMissingFileNamesIt) {
  expect_input_error([&] { read_image(path("missing.png")); }, path("missing.png"));
  expect_input_error([&] { read_image(dir_.string()); }, dir_.string());
}

TEST_F(ImageFileTest, ReadCorruptFilesNamesThem) {
  std::mt19937 rng(3);
  std::string noise(4096, '\0');
  for (char& c : noise) c = static_cast<char>(rng());
  const std::string exr_magic("\x76\x2f\x31\x01", 4);
  const std::pair<std::string, std::string> cases[] = {
      {"noise.png", noise},
      {"noise.exr", noise},
      {"noise.jpg", noise},
      {"empty.png", ""},
      {"magic_then_noise.exr", exr_magic + noise},  // gets past the magic into tinyexr's parser
      {"png_signature_only.png", "\x89PNG\r\n\x1a\n"},
  };
  for (const auto& [name, bytes] : cases) {
    write_bytes(path(name), bytes);
    expect_input_error([&] { read_image(path(name)); }, path(name));
  }
}

TEST_F(ImageFileTest, ReadTruncatedExrThrows) {
  write_image(path("full.exr"), random_image(32, 32, 4.0f, 4));
  const std::string bytes = read_bytes(path("full.exr"));
  write_bytes(path("cut.exr"), bytes.substr(0, bytes.size() / 2));
  expect_input_error([&] { read_image(path("cut.exr")); }, path("cut.exr"));
}

TEST_F(ImageFileTest, ReadAbsurdSizeThrows) {
  // A PNG header claiming 20000 x 20000 grey pixels and no data: small enough to pass
  // stb_image's own 2^30-byte limit, so it is our size check that must refuse it.
  std::string png = "\x89PNG\r\n\x1a\n";
  png += std::string("\0\0\0\x0d", 4) + "IHDR";
  png += std::string("\0\0\x4e\x20\0\0\x4e\x20", 8);             // width, height = 20000
  png += std::string("\x08\0\0\0\0", 5) + std::string(4, '\0');  // 8-bit grey, (bad) CRC
  write_bytes(path("huge.png"), png);
  expect_input_error([&] { read_image(path("huge.png")); }, path("huge.png"));
  expect_input_error([&] { read_image(path("huge.png")); }, "20000x20000");
}

// ---- Metrics ----------------------------------------------------------------------------------

ImageRGB two_pixels(vec3 a, vec3 b) {
  ImageRGB img = make_image(2, 1);
  img.set(0, 0, a);
  img.set(1, 0, b);
  return img;
}

TEST(Metrics, HandComputedTwoPixelImages) {
  const ImageRGB test = two_pixels(vec3(1, 2, 3), vec3(0, 0, 0));
  const ImageRGB ref = two_pixels(vec3(1, 1, 1), vec3(0.5f, 0, 0));
  const CompareResult r = compare_images(test, ref);
  EXPECT_EQ(r.width, 2);
  EXPECT_EQ(r.height, 1);
  // Differences 0, 1, 2, -0.5, 0, 0: squared sum 5.25 over 6 values.
  EXPECT_DOUBLE_EQ(r.rmse, std::sqrt(5.25 / 6.0));
  // Relative: (1 + 4) / 1.01^2 + 0.25 / 0.51^2, over 6 values.
  EXPECT_NEAR(r.relmse, (5.0 / (1.01 * 1.01) + 0.25 / (0.51 * 0.51)) / 6.0, 1e-12);
  EXPECT_EQ(r.mean_test, vec3(0.5f, 1.0f, 1.5f));
  EXPECT_EQ(r.mean_ref, vec3(0.75f, 0.5f, 0.5f));
  EXPECT_EQ(r.nonfinite_test, 0);
  EXPECT_EQ(r.nonfinite_ref, 0);

  const CompareResult same = compare_images(ref, ref);
  EXPECT_EQ(same.rmse, 0.0);
  EXPECT_EQ(same.relmse, 0.0);
}

TEST(Metrics, RelMseUsesTheReferenceInTheDenominator) {
  // Swapping test and reference changes relMSE (it is relative to the reference), not RMSE.
  const ImageRGB a = two_pixels(vec3(0.0f), vec3(0.0f));
  const ImageRGB b = two_pixels(vec3(0.99f), vec3(0.99f));
  EXPECT_NEAR(compare_images(a, b).relmse, 0.99 * 0.99 / 1.0, 1e-6);
  EXPECT_NEAR(compare_images(b, a).relmse, 0.99 * 0.99 / 1e-4, 1e-2);
  EXPECT_DOUBLE_EQ(compare_images(a, b).rmse, compare_images(b, a).rmse);
}

TEST(Metrics, NonFiniteValuesAreCountedAndExcluded) {
  const ImageRGB test = two_pixels(vec3(kNaN, 2, 3), vec3(kInf, 0, 0));
  const ImageRGB ref = two_pixels(vec3(1, 1, 1), vec3(0.5f, 0, kNaN));
  const CompareResult r = compare_images(test, ref);
  EXPECT_EQ(r.nonfinite_test, 2);
  EXPECT_EQ(r.nonfinite_ref, 1);
  // Remaining pairs: (2,1), (3,1), (0,0): squared sum 1 + 4 + 0 over 3 values.
  EXPECT_DOUBLE_EQ(r.rmse, std::sqrt(5.0 / 3.0));
  EXPECT_NEAR(r.relmse, 5.0 / (1.01 * 1.01) / 3.0, 1e-12);
  EXPECT_TRUE(std::isnan(r.mean_test.x));  // no finite red value in the test image
  EXPECT_FLOAT_EQ(r.mean_test.y, 1.0f);
  EXPECT_FLOAT_EQ(r.mean_test.z, 1.5f);
  EXPECT_FLOAT_EQ(r.mean_ref.z, 1.0f);  // the NaN reference value is left out of the mean
}

TEST(Metrics, SizeMismatchThrowsNamingBothSizes) {
  const ImageRGB a = make_image(2, 1), b = make_image(1, 2);
  for (auto fn : {+[](const ImageRGB&x, const ImageRGB&y) { compare_images(x, y); },
                  +[](const ImageRGB&x, const ImageRGB&y) { false_color_difference(x, y); }}) {
    try {
      fn(a, b);
      ADD_FAILURE() << "no InputError";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("2x1"), std::string::npos) << msg;
      EXPECT_NE(msg.find("1x2"), std::string::npos) << msg;
    }
  }
}

TEST(Metrics, JsonIsValidAndComplete) {
  const CompareResult r = compare_images(two_pixels(vec3(1, 2, 3), vec3(0.1f, 0, 0)),
                                         two_pixels(vec3(1, 1, 1), vec3(kNaN, 0, 0)));
  const nlohmann::json j = nlohmann::json::parse(compare_to_json(r));
  EXPECT_EQ(j["width"], 2);
  EXPECT_EQ(j["height"], 1);
  EXPECT_DOUBLE_EQ(j["rmse"].get<double>(), r.rmse);
  EXPECT_DOUBLE_EQ(j["relmse"].get<double>(), r.relmse);
  EXPECT_EQ(j["mean_test"].size(), 3u);
  EXPECT_FLOAT_EQ(j["mean_test"][0].get<float>(), r.mean_test.x);
  EXPECT_TRUE(j["mean_ref"][0].is_number());
  EXPECT_EQ(j["nonfinite_test"], 0);
  EXPECT_EQ(j["nonfinite_ref"], 1);
  // Undefined metrics (nothing to compare) become null rather than invalid JSON.
  const CompareResult none = compare_images(make_image(1, 1, vec3(kNaN)), make_image(1, 1));
  const nlohmann::json k = nlohmann::json::parse(compare_to_json(none));
  EXPECT_TRUE(k["rmse"].is_null());
  EXPECT_TRUE(k["mean_test"][0].is_null());
}

// ---- False colour -----------------------------------------------------------------------------

uint32_t srgb_hex(vec3 linear) {
  return (uint32_t{to_srgb8(linear.x)} << 16) | (uint32_t{to_srgb8(linear.y)} << 8) |
         to_srgb8(linear.z);
}

TEST(FalseColor, RampEndsAndMidpoint) {
  EXPECT_EQ(srgb_hex(viridis(0.0f)), 0x440154u);
  EXPECT_EQ(srgb_hex(viridis(0.5f)), 0x21908Cu);
  EXPECT_EQ(srgb_hex(viridis(1.0f)), 0xFDE725u);
  EXPECT_EQ(viridis(-1.0f), viridis(0.0f));
  EXPECT_EQ(viridis(2.0f), viridis(1.0f));
  EXPECT_EQ(viridis(kNaN), viridis(0.0f));
}

TEST(FalseColor, IdenticalIsDarkLargeIsBrightNanIsMagenta) {
  const ImageRGB ref = random_image(4, 3, 2.0f, 5);
  const ImageRGB same = false_color_difference(ref, ref);
  ASSERT_EQ(same.width, 4);
  ASSERT_EQ(same.height, 3);
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) EXPECT_EQ(same.at(x, y), viridis(0.0f));
  }

  const ImageRGB zero = make_image(3, 1, vec3(0.0f));
  ImageRGB test = make_image(3, 1, vec3(0.0f));
  test.set(0, 0, vec3(10.0f));             // relative error 1e6: past the bright end
  test.set(1, 0, vec3(0.001f));            // (0.001 / 0.01)^2 = 1e-2: the ramp's middle
  test.set(2, 0, vec3(0.0f, kNaN, 0.0f));  // any NaN channel marks the pixel
  const ImageRGB diff = false_color_difference(test, zero);
  EXPECT_EQ(diff.at(0, 0), viridis(1.0f));
  EXPECT_EQ(srgb_hex(diff.at(1, 0)), 0x21908Cu);
  EXPECT_EQ(diff.at(2, 0), vec3(1.0f, 0.0f, 1.0f));
}

}  // namespace
}  // namespace tracer
