// Every user setting, declared once in one table (settings_table()): the scene format's "camera",
// "render", "gpu" and "display" sections, the command-line flags, the --set keys of every
// command, the workbench's panels and tooltips, the sidecar, Save scene and the bench's
// configuration names all derive from it, so they cannot disagree on a name, a range or a default.
#pragma once

#include <functional>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "core/math.h"
#include "image/image.h"
#include "materials/material.h"

namespace tracer {

// The GPU backend's user-facing switches (what a user of the workbench compares; none of them
// changes the expected image). Which of them a scene or another switch overrides is decided in
// one place, resolve_gpu_options() (integrator/gpu_options.h).
enum class KernelMode { kAuto, kWavefront, kMegakernel };

// Compaction of the live paths' indices after each wavefront bounce. kShade: the shade kernel
// appends each path that goes on to the next bounce's queue (one atomic per block on the count
// it keeps anyway), and queues the shadow rays, stored at their queue slots, for the shadow
// stage. kCub: a CUB select over the alive flags after each bounce. kAuto: kShade except on
// textured scenes, whose long shading makes the block's barrier cost more than CUB's pass
// (PERFORMANCE.md). kOff: every stage passes over every path.
enum class Compaction { kOff, kAuto, kShade, kCub };

struct GpuOptions {
  KernelMode kernel = KernelMode::kAuto;
  Compaction compaction = Compaction::kAuto;
  bool sort_materials = false;     // bucket paths by material type before shading
  bool first_bounce_cache = true;  // reuse camera-ray hits (only without jitter and DoF)
  bool flat_list = true;           // small scenes: every lane tests every primitive, no BVH
  // The wavefront's tail (with compaction): once a bounce's queue is estimated (from the last
  // timed sample) to hold fewer paths than this fraction of the pixels, one megakernel launch
  // runs all their remaining bounces. 0: the stages run every bounce.
  float tail_fraction = 0.25f;
};
inline bool operator==(const GpuOptions& a, const GpuOptions& b) {
  return a.kernel == b.kernel && a.compaction == b.compaction &&
         a.sort_materials == b.sort_materials && a.first_bounce_cache == b.first_bounce_cache &&
         a.flat_list == b.flat_list && a.tail_fraction == b.tail_fraction;
}
inline bool operator!=(const GpuOptions& a, const GpuOptions& b) {
  return !(a == b);
}

// Which renderer runs: the GPU when there is one (kAuto), or the one named.
enum class BackendChoice { kAuto, kCpu, kCuda };

// The denoiser (image/denoise.h) on what is shown and exported: kOn shows and exports the
// denoised image, kBoth shows it and exports the raw image and the denoised one beside it.
enum class DenoiseMode { kOff, kOn, kBoth };

// What the workbench's viewport shows: the image, or one of the AOVs (integrator/aov.h).
enum class ViewMode { kImage, kAlbedo, kNormal, kDepth, kId };

// How the image is shown and exported as PNG (the accumulator is linear radiance).
struct DisplaySettings {
  float exposure = 0.0f;  // stops
  ToneMap tone_map = ToneMap::kNone;
  DenoiseMode denoise = DenoiseMode::kOff;
  ViewMode view = ViewMode::kImage;
  float scale() const { return std::exp2(exposure); }
};

struct Scene;

enum class SettingType { kBool, kInt, kFloat, kChoice, kVec3, kString };

// What an edit of a setting touches in the workbench: kImage, kCamera and kResize change the
// expected image (the accumulator restarts); kDisplay only how it is shown; kGpu only speed;
// kStop when rendering stops; kBackend which renderer runs.
enum class SettingEffect { kDisplay, kCamera, kImage, kResize, kGpu, kStop, kBackend };

struct Setting {
  std::string key;   // "render.max_depth": the JSON section and key, and the --set key
  std::string flag;  // "--max-depth", or "" when the command line has none (use --set)
  SettingType type = SettingType::kFloat;
  double lo = 0.0, hi = 0.0;         // inclusive range of a number or of each vector component
  std::vector<std::string> choices;  // kChoice: the names; kBool: {"off", "on"}
  std::string unit;                  // for the docs and tooltips ("px", "s", "stops", ...)
  std::string help;
  SettingEffect effect = SettingEffect::kImage;
  bool bare_flag = false;  // kBool: the command-line flag takes no value and means "on"
  // kString: the value names a file; a scene file's relative name is taken relative to the
  // scene file's folder (the command line's to the working directory).
  bool path = false;
  std::function<nlohmann::json(const Scene&)> get;
  std::function<void(Scene&, const nlohmann::json&)> put;  // the value is already checked
  // Optional, run by set_setting after put: reads what the value names (a file) into the scene.
  // "" or the problem, in which case set_setting restores the previous value.
  std::function<std::string(Scene&)> load;

  std::string section() const { return key.substr(0, key.find('.')); }
  std::string name() const { return key.substr(key.find('.') + 1); }
};

const std::vector<Setting>& settings_table();
const Setting* find_setting(const std::string& key);
// Every key of the table, in table order.
std::vector<std::string> setting_keys();
// "unknown setting "x" (did you mean "y"?); settings: a, b, ..." for any entry point.
std::string unknown_setting_message(const std::string& key, const std::string& section = "");

// The one check of a value, whatever it came from: "" when `value` (typed as in the scene
// format) is valid for `s`, else the problem, e.g. "\"render.max_depth\" is 0, outside 1..1024".
std::string check_setting(const Setting& s, const nlohmann::json& value);
// Reads a value as the command line and --set spell it (on/off, numbers, "x,y,z", a choice's
// name) into the scene format's type; "" or the problem (the same texts as check_setting's).
std::string parse_setting_text(const Setting& s, const std::string& text, nlohmann::json* value);
// check_setting, put, then the setting's load hook: "" or the problem; the scene's value is
// unchanged on a problem.
std::string set_setting(Scene& scene, const Setting& s, const nlohmann::json& value);
// "KEY=VALUE" (the --set language) for table keys: "" or the problem.
std::string set_setting_assignment(Scene& scene, const std::string& assignment);

// "materials.NAME.FIELD=VALUE": an edit of a named material (type, albedo, emission,
// emission_strength, ior, fresnel, absorption, two_sided, roughness, scattering, g), as --set
// spells it on every command. "" or the problem.
std::string set_material_assignment(Scene& scene, const std::string& assignment);
extern const std::vector<std::string> kMaterialSetKeys;  // "materials.NAME.albedo", ...
// The values of such edits: exactly n finite numbers separated by commas ("1,2,3").
bool parse_floats(const std::string& s, float* out, int n);
// A material in the scene format (what the scene reader reads back).
nlohmann::json material_to_json(const Material& m);

// The value as text in the --set language ("on", "1.5", "0,1,2", "wavefront").
std::string setting_text(const Scene& scene, const Setting& s);
std::string setting_default_text(const Setting& s);
// What a value may be, for help texts: "1..1024", "[0, 1]", ">= 0", "on|off", "auto|cpu|cuda".
std::string setting_values_text(const Setting& s);
// {"camera": {...}, "render": {...}, "gpu": {...}, "display": {...}}: every setting, in the
// scene format (the sidecar and Save scene write this; the scene reader reads it back).
// Indented JSON text ending in a newline, as every file and --json output is written. Bytes that
// are not UTF-8 (names from mesh files: regr01.obj's are Latin-1) become U+FFFD instead of
// failing the write.
std::string json_text(const nlohmann::json& j);
nlohmann::json settings_to_json(const Scene& scene);
// The check that needs several camera settings together: "" or the problem.
std::string check_camera(const Scene& scene);

// Every setting of the scene against the table, then check_camera(): "" or the first problem.
std::string check_settings(const Scene& scene);

// The docs' tables (docs/CLI.md, docs/SCENE_FORMAT.md), one Markdown table per section.
std::string settings_markdown();

}  // namespace tracer
