// Images on the host: a linear float RGB buffer, the display transform (exposure, tone map, sRGB),
// atomic PNG/EXR export, image loading, and the error metrics used to compare renders.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/hd.h"
#include "image/display.h"

namespace tracer {

// Linear float RGB, row-major, top row first. Plain data so that the film can fill `pixels`
// directly; `at`/`set` are conveniences for tests and tools, not for inner loops.
struct ImageRGB {
  int width = 0, height = 0;
  std::vector<float> pixels;  // 3 * width * height

  vec3 at(int x, int y) const;
  void set(int x, int y, vec3 c);
};

// A width x height image filled with `fill`.
ImageRGB make_image(int width, int height, vec3 fill = vec3(0.0f));

// ---- Display transform ------------------------------------------------------------------------

const char* tone_map_name(ToneMap op);  // "none", "reinhard", "aces"
// Accepts the names above (case-insensitive); returns false and leaves *op alone otherwise.
bool parse_tone_map(const std::string& name, ToneMap* op);

// Maps linear radiance to [0, 1] per channel. NaN, Inf and negative values map to 0 so that one
// bad sample never poisons a PNG. Reinhard is the simple global operator c / (1 + c) (Reinhard et
// al. 2002, eq. 3) applied per channel; ACES is Narkowicz's fit, applied without pre-scaling.
vec3 tone_map(vec3 linear, ToneMap op);
// The sRGB OETF (IEC 61966-2-1) of a value clamped to [0, 1], rounded to 8 bits; NaN gives 0.
uint8_t to_srgb8(float linear01);
// The sRGB OETF without quantisation, and its inverse, the EOTF.
float linear_to_srgb(float linear01);
float srgb_to_linear(float encoded01);

// ---- Files ------------------------------------------------------------------------------------

// Writes by extension (case-insensitive):
//   .png: 8-bit sRGB of the display transform: multiply by 2^exposure_stops, tone map, OETF.
//   .exr: linear float32 RGB exactly as stored (exposure and tone map are display settings and are
//         not applied), ZIP-compressed (uncompressed below 16x16, as tinyexr's SaveEXR does).
// Atomic: the bytes go to a temporary file in the same directory which is then rename()d over the
// target, so a crash never leaves a half-written file and an existing file is never lost. Creates
// the parent directory if missing. Throws InputError naming the path on an unknown extension, an
// empty image or any I/O failure, after removing the temporary file.
void write_image(const std::string& path, const ImageRGB& img, float exposure_stops = 0.0f,
                 ToneMap op = ToneMap::kNone);
// One float32 channel of a layered EXR: its full name ("albedo.R", "depth.Z") and width x height
// values, rows top first.
struct ExrChannel {
  std::string name;
  std::vector<float> values;
};
// Writes `img` as the R, G, B channels of an EXR and `layers` beside them (channels sorted by
// name, as OpenEXR wants), atomically as write_image does. Throws InputError naming the path.
void write_exr_layers(const std::string& path, const ImageRGB& img, std::vector<ExrChannel> layers);
// Writes 8-bit RGBA pixels (e.g. a window screenshot) as PNG, atomically. bottom_up: the first
// row in memory is the bottom of the image (OpenGL's glReadPixels order).
void write_png_rgba8(const std::string& path, int width, int height, const uint8_t* rgba,
                     bool bottom_up);
// Writes any text file atomically the same way (the JSON sidecar, saved scenes).
void write_text_atomic(const std::string& path, const std::string& text);
// Before a long render: creates the missing directories of `path` and checks that a file can be
// created beside it (as the atomic writers will); throws std::runtime_error with the reason.
void check_writable(const std::string& path);

// Reads PNG/JPEG/BMP/TGA (stb_image; 8- or 16-bit sRGB decoded to linear), Radiance .hdr (already
// linear) or OpenEXR (tinyexr: R, G, B channels of float, half or uint, or one grey channel). The
// format is recognised by content, not extension; alpha is ignored. Throws InputError naming the
// file when it is missing, unreadable, corrupt, unsupported or of absurd size.
ImageRGB read_image(const std::string& path);

// ---- Metrics ----------------------------------------------------------------------------------

struct CompareResult {
  int width = 0, height = 0;
  double rmse = 0.0;    // sqrt(mean over pixels and channels of (t - r)^2)
  double relmse = 0.0;  // pbrt-v4's MRSE: mean over pixels and channels of (t - r)^2 / (r + 0.01)^2
  vec3 mean_test{0.0f}, mean_ref{0.0f};  // per-channel means of the finite values
  long nonfinite_test = 0;               // NaN/Inf values (not pixels) in the test image
  long nonfinite_ref = 0;                // ... and in the reference
};

// Values where either image is NaN/Inf are counted and left out of every sum and every
// denominator, so rmse/relmse are means over the remaining values (NaN when none remain).
// `keep` (width * height, row-major), when given, leaves out every pixel where it is 0 before
// anything is counted. Throws InputError if the sizes differ (the message names both sizes).
CompareResult compare_images(const ImageRGB& test, const ImageRGB& ref,
                             const std::vector<uint8_t>* keep = nullptr);

// A false-colour image of the per-pixel relative squared error (mean over channels of
// (t - r)^2 / (r + 0.01)^2) through the viridis ramp on a log scale: 1e-4 or less is the dark end
// (#440154), 1 or more the bright end (#FDE725). Pixels with a NaN/Inf value in either image are
// magenta. Colours are stored linear, so a PNG of the result shows exactly the ramp's sRGB values.
ImageRGB false_color_difference(const ImageRGB& test, const ImageRGB& ref);
// A colour map from `count` even, sRGB-encoded 0xRRGGBB stops, interpolated in the encoded values
// at t in [0, 1] (clamped; NaN gives the first stop), returned as linear RGB.
vec3 color_ramp(const unsigned* stops, int count, float t);
// Viridis (van der Walt & Smith 2015) at t in [0, 1], clamped, as linear RGB.
vec3 viridis(float t);

// {"width":..,"height":..,"rmse":..,"relmse":..,"mean_test":[r,g,b],"mean_ref":[r,g,b],
//  "nonfinite_test":..,"nonfinite_ref":..}; a non-finite metric is written as null.
std::string compare_to_json(const CompareResult& r);

}  // namespace tracer
