// The settings table and the one place that checks, parses, prints and documents a setting.
#include "scene/settings.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>

#include "materials/metals.h"
#include "scene/scene.h"

namespace tracer {

namespace {

using nlohmann::json;
using T = SettingType;
using E = SettingEffect;

constexpr double kHuge = 3.0e38;  // the largest magnitude a 32-bit float setting accepts

// The shortest decimal that reads back as the same float, as a double: 0.1f is written 0.1,
// not 0.10000000149011612, and still round-trips through the scene format exactly.
double shortest(float f) {
  if (!std::isfinite(f)) return double(f);
  char buf[32];
  for (int digits = 1; digits <= 9; ++digits) {
    snprintf(buf, sizeof buf, "%.*g", digits, double(f));
    if (std::strtof(buf, nullptr) == f) return std::strtod(buf, nullptr);
  }
  return double(f);
}

std::string number_text(double d) {
  char buf[32];
  snprintf(buf, sizeof buf, "%.10g", d);
  return buf;
}

json to_value(bool b) {
  return b;
}
json to_value(int i) {
  return i;
}
json to_value(uint32_t u) {
  return u;
}
json to_value(float f) {
  return shortest(f);
}
json to_value(double d) {
  return d;
}
json to_value(const std::string& t) {
  return t;
}
json to_value(vec3 v) {
  return json::array({shortest(v.x), shortest(v.y), shortest(v.z)});
}

void from_value(const json& j, bool& b) {
  b = j.get<bool>();
}
void from_value(const json& j, int& i) {
  i = int(j.get<double>());
}
void from_value(const json& j, uint32_t& u) {
  u = uint32_t(j.get<double>());
}
void from_value(const json& j, float& f) {
  f = float(j.get<double>());
}
void from_value(const json& j, double& d) {
  d = j.get<double>();
}
void from_value(const json& j, std::string& t) {
  t = j.get<std::string>();
}
void from_value(const json& j, vec3& v) {
  for (int i = 0; i < 3; ++i) v[i] = float(j[size_t(i)].get<double>());
}

// A setting stored in a field of the scene; `field` maps a scene to a reference to it.
template <class Field>
Setting field(std::string key, std::string flag, SettingType type, double lo, double hi,
              std::string unit, std::string help, SettingEffect effect, Field f) {
  Setting s;
  s.key = std::move(key);
  s.flag = std::move(flag);
  s.type = type;
  s.lo = lo;
  s.hi = hi;
  if (type == T::kBool) s.choices = {"off", "on"};
  s.unit = std::move(unit);
  s.help = std::move(help);
  s.effect = effect;
  s.get = [f](const Scene& sc) { return to_value(f(const_cast<Scene&>(sc))); };
  s.put = [f](Scene& sc, const json& v) { from_value(v, f(sc)); };
  return s;
}

// A setting with named values, read and written through `index` (which name the scene holds)
// and `assign` (store the name of that index).
Setting named(std::string key, std::string flag, std::vector<std::string> names, std::string help,
              SettingEffect effect, std::function<size_t(const Scene&)> index,
              std::function<void(Scene&, size_t)> assign) {
  Setting s;
  s.key = std::move(key);
  s.flag = std::move(flag);
  s.type = T::kChoice;
  s.choices = names;
  s.help = std::move(help);
  s.effect = effect;
  s.get = [names, index](const Scene& sc) { return json(names[index(sc)]); };
  s.put = [names, assign](Scene& sc, const json& v) {
    for (size_t i = 0; i < names.size(); ++i)
      if (names[i] == v.get<std::string>()) assign(sc, i);
  };
  return s;
}

// A named setting stored in a field: `names[i]` is stored as `values[i]`.
template <class V, class Field>
Setting choice(std::string key, std::string flag, std::vector<std::string> names,
               std::vector<V> values, std::string help, SettingEffect effect, Field f) {
  return named(
      std::move(key), std::move(flag), std::move(names), std::move(help), effect,
      [f, values](const Scene& sc) {
        const V v = f(const_cast<Scene&>(sc));
        for (size_t i = 0; i < values.size(); ++i)
          if (values[i] == v) return i;
        return size_t(0);
      },
      [f, values](Scene& sc, size_t i) { f(sc) = values[i]; });
}

std::vector<Setting> make_table() {
  std::vector<Setting> t;
  // ---- camera ----
  t.push_back(field("camera.position", "", T::kVec3, -kHuge, kHuge, "world units",
                    "Where the camera is.", E::kCamera,
                    [](Scene& s) -> vec3& { return s.camera.position; }));
  t.push_back(field("camera.look_at", "", T::kVec3, -kHuge, kHuge, "world units",
                    "The point the camera looks at.", E::kCamera,
                    [](Scene& s) -> vec3& { return s.camera.look_at; }));
  t.push_back(field("camera.up", "", T::kVec3, -kHuge, kHuge, "",
                    "The direction that is up in the image (need not be unit length).", E::kCamera,
                    [](Scene& s) -> vec3& { return s.camera.up; }));
  t.push_back(field("camera.vfov", "", T::kFloat, 1.0, 179.0, "degrees", "Vertical field of view.",
                    E::kCamera, [](Scene& s) -> float& { return s.camera.vfov_deg; }));
  t.push_back(field("camera.aperture", "", T::kFloat, 0.0, kHuge, "world units",
                    "Lens radius for depth of field (0: a pinhole camera).", E::kCamera,
                    [](Scene& s) -> float& { return s.camera.aperture_radius; }));
  t.push_back(field("camera.focus_distance", "", T::kFloat, 0.0, kHuge, "world units",
                    "Distance to the plane in focus (0: the distance to look_at).", E::kCamera,
                    [](Scene& s) -> float& { return s.camera.focus_distance; }));
  // ---- render ----
  t.push_back(field("render.width", "--width", T::kInt, 1, 16384, "pixels", "Image width.",
                    E::kResize, [](Scene& s) -> int& { return s.settings.width; }));
  t.push_back(field("render.height", "--height", T::kInt, 1, 16384, "pixels", "Image height.",
                    E::kResize, [](Scene& s) -> int& { return s.settings.height; }));
  t.push_back(field("render.spp", "--spp", T::kInt, 0, double(1 << 30), "samples",
                    "Samples per pixel to render (0: no limit; render then needs a time limit).",
                    E::kStop, [](Scene& s) -> int& { return s.settings.spp; }));
  t.push_back(field("render.time_limit_s", "--time", T::kFloat, 0.0, 1e7, "seconds",
                    "Render for this long instead of to a sample count (0: no time limit).",
                    E::kStop, [](Scene& s) -> double& { return s.settings.time_limit_s; }));
  t.push_back(field("render.max_depth", "--max-depth", T::kInt, 1, 1024, "segments",
                    "Maximum path segments (the camera ray is the first).", E::kImage,
                    [](Scene& s) -> int& { return s.settings.max_depth; }));
  t.push_back(field("render.nee", "--nee", T::kBool, 0, 0, "",
                    "Next-event estimation (light sampling).", E::kImage,
                    [](Scene& s) -> bool& { return s.settings.nee; }));
  t.push_back(field("render.mis", "--mis", T::kBool, 0, 0, "",
                    "Multiple importance sampling of NEE and BSDF sampling (power heuristic).",
                    E::kImage, [](Scene& s) -> bool& { return s.settings.mis; }));
  t.push_back(field("render.russian_roulette", "--rr", T::kBool, 0, 0, "",
                    "Russian roulette (unbiased path termination).", E::kImage,
                    [](Scene& s) -> bool& { return s.settings.russian_roulette; }));
  t.push_back(field("render.rr_start_depth", "--rr-start", T::kInt, 1, 1024, "segments",
                    "Path depth from which Russian roulette applies.", E::kImage,
                    [](Scene& s) -> int& { return s.settings.rr_start_depth; }));
  t.push_back(field("render.seed", "--seed", T::kInt, 0, 4294967295.0, "",
                    "Random seed (the same seed renders the same image).", E::kImage,
                    [](Scene& s) -> uint32_t& { return s.settings.seed; }));
  t.push_back(field("render.jitter", "--jitter", T::kBool, 0, 0, "",
                    "Jitter samples inside each pixel (antialiasing).", E::kImage,
                    [](Scene& s) -> bool& { return s.settings.jitter; }));
  t.push_back(field("render.clamp", "--clamp", T::kFloat, 0.0, kHuge, "radiance",
                    "Clamp each sample's radiance per channel to this (0: off; biased, the "
                    "sidecar reports the luminance removed).",
                    E::kImage, [](Scene& s) -> float& { return s.settings.clamp; }));
  t.push_back(choice<uint32_t>(
      "render.sampler", "--sampler", {"sobol", "sobol-pairs", "random"},
      {kSamplerSobol, kSamplerSobolPairs, kSamplerRandom},
      "Sample points: sobol (Owen-scrambled Sobol, stratified), sobol-pairs (two independent "
      "Sobol halves: exact half-buffer noise) or random (PCG32).",
      E::kImage, [](Scene& s) -> uint32_t& { return s.settings.sampler; }));
  t.push_back(choice<uint32_t>(
      "render.light_sampler", "--light-sampler", {"uniform", "power", "bvh"},
      {kLightSamplerUniform, kLightSamplerPower, kLightSamplerBvh},
      "How next-event estimation chooses a light: uniform (every light alike), power (in "
      "proportion to its power) or bvh (a light tree: by power, distance and orientation as seen "
      "from the shading point; lights at infinity by power).",
      E::kImage, [](Scene& s) -> uint32_t& { return s.settings.light_sampler; }));
  t.push_back(field("render.guiding", "--guiding", T::kBool, 0, 0, "",
                    "Path guiding: learn where light comes from while rendering (a grid of "
                    "directional histograms, trained over the first 255 samples in passes of "
                    "doubling length, then frozen) and sample directions from it and the BSDF by "
                    "one-sample MIS. Unbiased; pays off where light sampling fails (caustics).",
                    E::kImage, [](Scene& s) -> bool& { return s.settings.guiding; }));
  t.push_back(field("render.mnee", "--mnee", T::kBool, 0, 0, "",
                    "Manifold next-event estimation: connect each light sample also through "
                    "smooth glass (two refractions: in and out of one piece, on flat faces or "
                    "spheres) and by one reflection (off mirror and metal spheres, flat mirrors "
                    "and glass faces), where a shadow ray is blocked or cannot turn. Unbiased; "
                    "caustics of lights behind glass or in mirrors converge without fireflies.",
                    E::kImage, [](Scene& s) -> bool& { return s.settings.mnee; }));
  t.push_back(field("render.light_tracing", "--light-tracing", T::kBool, 0, 0, "",
                    "Light tracing of caustics: paths from the lights through mirrors, glass and "
                    "glossy metals, joined to the camera at each diffuse or rough vertex and "
                    "splatted into the image; the path tracer leaves those paths to them (an "
                    "exact split: unbiased). Caustics seen directly, and the light they bounce "
                    "on, converge without fireflies; up to one more path per pixel and sample (a "
                    "quarter where they are aimed at the casters). Needs jitter.",
                    E::kImage, [](Scene& s) -> bool& { return s.settings.light_tracing; }));
  t.push_back(choice<PixelFilter>(
      "render.filter", "--filter", {"box", "tent", "gaussian", "blackman-harris"},
      {PixelFilter::kBox, PixelFilter::kTent, PixelFilter::kGaussian,
       PixelFilter::kBlackmanHarris},
      "Pixel reconstruction filter, by where samples land (no splatting, no bias): box (one "
      "pixel), tent (Tungsten's and pbrt's triangle), gaussian (pbrt-v4's) or blackman-harris "
      "(Cycles').",
      E::kImage, [](Scene& s) -> PixelFilter& { return s.settings.filter; }));
  t.push_back(field("render.filter_radius", "--filter-radius", T::kFloat, 0.0, 8.0, "pixels",
                    "Filter radius (0: the filter's default: box 0.5, tent 1, gaussian 1.5, "
                    "blackman-harris 1).",
                    E::kImage, [](Scene& s) -> float& { return s.settings.filter_radius; }));
  t.push_back(
      choice<BackendChoice>("render.backend", "--backend", {"auto", "cpu", "cuda"},
                            {BackendChoice::kAuto, BackendChoice::kCpu, BackendChoice::kCuda},
                            "auto: the GPU when there is one, else the CPU.", E::kBackend,
                            [](Scene& s) -> BackendChoice& { return s.settings.backend; }));
  t.push_back(field("render.threads", "--threads", T::kInt, 0, 1024, "threads",
                    "CPU backend threads (0: all cores).", E::kBackend,
                    [](Scene& s) -> int& { return s.settings.threads; }));
  t.push_back(field("render.samples_per_frame", "", T::kInt, 0, 1024, "samples",
                    "Workbench, GPU: samples added per window frame (0: adapted to the frame "
                    "rate).",
                    E::kStop, [](Scene& s) -> int& { return s.settings.samples_per_frame; }));
  t.push_back(field("render.strict", "--strict", T::kBool, 0, 0, "",
                    "Every warning about the input is an error (exit 1): missing or corrupt "
                    "textures, truncated meshes, dropped geometry, unsupported extensions. For "
                    "pipelines.",
                    E::kStop, [](Scene& s) -> bool& { return s.settings.strict; }));
  t.back().bare_flag = true;
  // ---- gpu ----
  t.push_back(choice<KernelMode>(
      "gpu.kernel", "--kernel", {"auto", "wavefront", "megakernel"},
      {KernelMode::kAuto, KernelMode::kWavefront, KernelMode::kMegakernel},
      "GPU design: wavefront (one kernel per stage), megakernel (one persistent kernel) or "
      "auto (time both on the first samples, keep the faster).",
      E::kGpu, [](Scene& s) -> KernelMode& { return s.gpu.kernel; }));
  t.push_back(choice<Compaction>(
      "gpu.compaction", "--compaction", {"auto", "shade", "cub", "off"},
      {Compaction::kAuto, Compaction::kShade, Compaction::kCub, Compaction::kOff},
      "Wavefront: compact the live paths after each bounce. shade: the shade kernel queues the "
      "paths that go on (and the shadow rays); cub: a CUB select over the alive flags; auto: "
      "shade, but cub on textured scenes; off: every stage runs over every pixel.",
      E::kGpu, [](Scene& s) -> Compaction& { return s.gpu.compaction; }));
  t.push_back(field("gpu.sort", "--sort", T::kBool, 0, 0, "",
                    "Wavefront: sort paths by material before shading.", E::kGpu,
                    [](Scene& s) -> bool& { return s.gpu.sort_materials; }));
  t.push_back(field("gpu.cache", "--cache", T::kBool, 0, 0, "",
                    "Reuse the camera rays' hits across samples (only without jitter and depth "
                    "of field).",
                    E::kGpu, [](Scene& s) -> bool& { return s.gpu.first_bounce_cache; }));
  t.push_back(field("gpu.flat", "--flat", T::kBool, 0, 0, "",
                    "Scenes of at most 64 primitives: every lane tests every primitive in one "
                    "uniform loop instead of walking the BVH.",
                    E::kGpu, [](Scene& s) -> bool& { return s.gpu.flat_list; }));
  t.push_back(field("gpu.tail", "--tail", T::kFloat, 0.0, 1.0, "fraction of pixels",
                    "Wavefront with compaction: once fewer paths than this fraction of the "
                    "pixels remain, one megakernel launch runs their remaining bounces (0: off).",
                    E::kGpu, [](Scene& s) -> float& { return s.gpu.tail_fraction; }));
  // ---- environment ----
  // A new file or mapping is read and checked by the load hook (refresh_environment), so every
  // entry point that sets them (scene file, flags, --set, the workbench) reads the map.
  {
    Setting file = field("environment.file", "--env", T::kString, 0, 0, "",
                         "Environment map lighting the scene from infinitely far: a .hdr, .pfm "
                         "or .exr file (\"\": none; then environment.color, when not black, is "
                         "a constant environment).",
                         E::kImage, [](Scene& s) -> std::string& { return s.environment.file; });
    file.path = true;
    file.load = refresh_environment;
    t.push_back(file);
  }
  {
    Setting mapping = choice<EnvMapping>(
        "environment.mapping", "--env-mapping", {"auto", "equirect", "octahedral"},
        {EnvMapping::kAuto, EnvMapping::kEquirect, EnvMapping::kOctahedral},
        "How the map's image covers the sphere: equirect (latitude-longitude, the top row "
        "straight up), octahedral (pbrt-v4's equal-area square) or auto (a square image is "
        "octahedral, any other equirect: a guess from the shape).",
        E::kImage, [](Scene& s) -> EnvMapping& { return s.environment.mapping; });
    mapping.load = refresh_environment;
    t.push_back(mapping);
  }
  t.push_back(field("environment.strength", "--env-strength", T::kFloat, 0.0, kHuge, "",
                    "Multiplies the environment's radiance (map or colour).", E::kImage,
                    [](Scene& s) -> float& { return s.environment.strength; }));
  t.push_back(field("environment.rotation", "--env-rotation", T::kFloat, -360.0, 360.0, "degrees",
                    "Turns the environment about the up axis (+y), counter-clockwise seen from "
                    "above.",
                    E::kImage, [](Scene& s) -> float& { return s.environment.rotation_deg; }));
  t.push_back(field("environment.visible", "--env-visible", T::kBool, 0, 0, "",
                    "Camera rays see the environment (off: they see environment.background; "
                    "the environment still lights the scene and shows in reflections).",
                    E::kImage, [](Scene& s) -> bool& { return s.environment.visible; }));
  t.push_back(field("environment.background", "", T::kVec3, 0.0, kHuge, "radiance",
                    "What camera rays see where environment.visible is off.", E::kImage,
                    [](Scene& s) -> vec3& { return s.environment.background; }));
  t.push_back(field("environment.color", "", T::kVec3, 0.0, kHuge, "radiance",
                    "A constant environment's radiance, used when there is no environment.file "
                    "(0,0,0: none).",
                    E::kImage, [](Scene& s) -> vec3& { return s.environment.color; }));
  // ---- display ----
  t.push_back(field("display.exposure", "--exposure", T::kFloat, -20.0, 20.0, "stops",
                    "Exposure of the display and of PNG exports (EXR stays linear).", E::kDisplay,
                    [](Scene& s) -> float& { return s.display.exposure; }));
  t.push_back(choice<ToneMap>("display.tonemap", "--tonemap", {"none", "reinhard", "aces"},
                              {ToneMap::kNone, ToneMap::kReinhard, ToneMap::kAces},
                              "Tone mapping of the display and of PNG exports.", E::kDisplay,
                              [](Scene& s) -> ToneMap& { return s.display.tone_map; }));
  t.push_back(choice<DenoiseMode>(
      "display.denoise", "--denoise", {"off", "on", "both"},
      {DenoiseMode::kOff, DenoiseMode::kOn, DenoiseMode::kBoth},
      "Open Image Denoise on what is shown and exported, guided by the albedo and normal AOVs "
      "(biased: it trades noise for blur). on: the viewport and the export show the denoised "
      "image; both: the export writes the raw image and the denoised one beside it "
      "(name.denoised.ext). The accumulator is never changed: toggling it does not restart.",
      E::kDisplay, [](Scene& s) -> DenoiseMode& { return s.display.denoise; }));
  t.push_back(choice<ViewMode>(
      "display.view", "", {"image", "albedo", "normal", "depth", "id"},
      {ViewMode::kImage, ViewMode::kAlbedo, ViewMode::kNormal, ViewMode::kDepth, ViewMode::kId},
      "What the workbench's viewport shows: the image, or an AOV of the first non-specular hit "
      "(albedo; normal as n x 0.5 + 0.5; depth, near is white; id, a colour per material). "
      "Showing an AOV turns the AOVs on from the next sample; the image goes on accumulating.",
      E::kDisplay, [](Scene& s) -> ViewMode& { return s.display.view; }));
  return t;
}

const char* type_words(const Setting& s) {
  switch (s.type) {
    case T::kBool:
      return "on or off";
    case T::kInt:
      return "a whole number";
    case T::kFloat:
      return "a number";
    case T::kVec3:
      return "three numbers x,y,z";
    case T::kChoice:
      return "a name";
    case T::kString:
      return "a file name";
  }
  return "";
}

std::string quoted(const std::string& s) {
  return "\"" + s + "\"";
}

std::string range_text(const Setting& s) {
  if (s.type == T::kInt) return number_text(s.lo) + ".." + number_text(s.hi);
  if (s.hi >= kHuge && s.lo <= -kHuge) return "any finite value";
  if (s.hi >= kHuge) return ">= " + number_text(s.lo);
  return "[" + number_text(s.lo) + ", " + number_text(s.hi) + "]";
}

std::string choice_list(const Setting& s) {
  std::string out;
  for (size_t i = 0; i < s.choices.size(); ++i)
    out += (i == 0 ? "" : i + 1 == s.choices.size() ? " or " : ", ") + s.choices[i];
  return out;
}

// `shown` is the value as the message names it: the number itself, printed the same way whether
// it came from a scene file or a command line, so that both get the same message.
std::string check_number(const Setting& s, double d) {
  const std::string shown = number_text(d);
  if (!std::isfinite(d)) return quoted(s.key) + " is " + shown + ", not a finite number";
  if (s.type == T::kInt && d != std::floor(d))
    return quoted(s.key) + " is " + shown + ", not a whole number";
  if (d < s.lo || d > s.hi) return quoted(s.key) + " is " + shown + ", outside " + range_text(s);
  return "";
}

}  // namespace

const std::vector<Setting>& settings_table() {
  static const std::vector<Setting> table = make_table();
  return table;
}

const Setting* find_setting(const std::string& key) {
  for (const Setting& s : settings_table())
    if (s.key == key) return &s;
  return nullptr;
}

std::vector<std::string> setting_keys() {
  std::vector<std::string> keys;
  for (const Setting& s : settings_table()) keys.push_back(s.key);
  return keys;
}

std::string unknown_setting_message(const std::string& key, const std::string& section) {
  std::vector<std::string> keys;
  for (const Setting& s : settings_table())
    if (section.empty() || s.section() == section)
      keys.push_back(section.empty() ? s.key : s.name());
  if (section.empty()) keys.insert(keys.end(), kMaterialSetKeys.begin(), kMaterialSetKeys.end());
  if (section.empty()) keys.insert(keys.end(), kLightSetKeys.begin(), kLightSetKeys.end());
  std::string msg = "unknown setting " + quoted(key);
  const std::string guess = did_you_mean(key, keys);
  if (!guess.empty()) msg += " (did you mean " + quoted(guess) + "?)";
  msg += "; valid" + (section.empty() ? std::string() : " in \"" + section + "\"") + ": ";
  for (size_t i = 0; i < keys.size(); ++i) msg += (i ? ", " : "") + keys[i];
  return msg;
}

std::string check_setting(const Setting& s, const json& v) {
  const std::string shown = v.dump();
  switch (s.type) {
    case T::kBool:
      if (!v.is_boolean()) return quoted(s.key) + " must be true or false, not " + shown;
      return "";
    case T::kInt:
    case T::kFloat:
      if (!v.is_number()) return quoted(s.key) + " must be " + type_words(s) + ", not " + shown;
      return check_number(s, v.get<double>());
    case T::kVec3: {
      if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() ||
          !v[2].is_number())
        return quoted(s.key) + " must be three numbers, not " + shown;
      for (int i = 0; i < 3; ++i) {
        const std::string p = check_number(s, v[size_t(i)].get<double>());
        if (!p.empty()) return p;
      }
      return "";
    }
    case T::kString:
      if (!v.is_string()) return quoted(s.key) + " must be a string, not " + shown;
      return "";
    case T::kChoice: {
      if (v.is_string())
        for (const std::string& c : s.choices)
          if (c == v.get<std::string>()) return "";
      std::string msg = quoted(s.key) + " must be " + choice_list(s) + ", not " + shown;
      if (v.is_string()) {
        const std::string guess = did_you_mean(v.get<std::string>(), s.choices);
        if (!guess.empty()) msg += " (did you mean " + quoted(guess) + "?)";
      }
      return msg;
    }
  }
  return "";
}

std::string parse_setting_text(const Setting& s, const std::string& text, json* value) {
  auto parse_number = [&](const std::string& t, double* d) {
    if (t.empty()) return false;
    char* end = nullptr;
    *d = std::strtod(t.c_str(), &end);
    return *end == '\0';
  };
  switch (s.type) {
    case T::kBool:
      if (text == "on" || text == "true" || text == "1")
        *value = true;
      else if (text == "off" || text == "false" || text == "0")
        *value = false;
      else
        return quoted(s.key) + " must be on or off, not " + quoted(text);
      return "";
    case T::kInt:
    case T::kFloat: {
      double d;
      if (!parse_number(text, &d))
        return quoted(s.key) + " must be " + type_words(s) + ", not " + quoted(text);
      const std::string p = check_number(s, d);
      if (!p.empty()) return p;
      *value = d;
      return "";
    }
    case T::kVec3: {
      json arr = json::array();
      size_t start = 0;
      for (int i = 0; i < 3; ++i) {
        const size_t comma = text.find(',', start);
        if ((i < 2) != (comma != std::string::npos)) break;
        double d;
        if (!parse_number(text.substr(start, comma - start), &d)) break;
        arr.push_back(d);
        start = comma + 1;
      }
      if (arr.size() != 3)
        return quoted(s.key) + " must be three numbers x,y,z, not " + quoted(text);
      *value = arr;
      return check_setting(s, arr);
    }
    case T::kChoice:
      *value = text;
      return check_setting(s, *value);
    case T::kString:
      *value = text;
      return "";
  }
  return "";
}

std::string set_setting(Scene& scene, const Setting& s, const json& value) {
  std::string problem = check_setting(s, value);
  if (!problem.empty()) return problem;
  const json old = s.get(scene);
  s.put(scene, value);
  if (s.load) {
    problem = s.load(scene);
    if (!problem.empty()) s.put(scene, old);
  }
  return problem;
}

std::string set_setting_assignment(Scene& scene, const std::string& assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos) return "expected KEY=VALUE, not " + quoted(assignment);
  const std::string key = assignment.substr(0, eq);
  if (key.rfind("materials.", 0) == 0) return set_material_assignment(scene, assignment);
  if (key.rfind("lights.", 0) == 0) return set_light_assignment(scene, assignment);
  const Setting* s = find_setting(key);
  if (!s) return unknown_setting_message(key);
  json value;
  const std::string problem = parse_setting_text(*s, assignment.substr(eq + 1), &value);
  if (!problem.empty()) return problem;
  return set_setting(scene, *s, value);
}

namespace {
std::string value_text(const Setting& s, const json& v) {
  switch (s.type) {
    case T::kBool:
      return v.get<bool>() ? "on" : "off";
    case T::kInt:
    case T::kFloat:
      return number_text(v.get<double>());
    case T::kVec3:
      return number_text(v[0].get<double>()) + "," + number_text(v[1].get<double>()) + "," +
             number_text(v[2].get<double>());
    case T::kChoice:
    case T::kString:
      return v.get<std::string>();
  }
  return "";
}
}  // namespace

std::string setting_text(const Scene& scene, const Setting& s) {
  return value_text(s, s.get(scene));
}

std::string setting_default_text(const Setting& s) {
  static const Scene defaults;
  return setting_text(defaults, s);
}

std::string setting_values_text(const Setting& s) {
  if (s.type == T::kString) return s.path ? "a file name, \"\" for none" : "text";
  if (s.type == T::kBool || s.type == T::kChoice) {
    std::string out;
    for (size_t i = 0; i < s.choices.size(); ++i) out += (i ? "|" : "") + s.choices[i];
    return out;
  }
  return (s.type == T::kVec3 ? "x,y,z each " : "") + range_text(s);
}

std::string json_text(const json& j) {
  return j.dump(2, ' ', false, json::error_handler_t::replace) + "\n";
}

json settings_to_json(const Scene& scene) {
  json j = json::object();
  for (const Setting& s : settings_table()) j[s.section()][s.name()] = s.get(scene);
  return j;
}

std::string check_camera(const Scene& scene) {
  const CameraDesc& cam = scene.camera;
  const vec3 dir = cam.look_at - cam.position;
  if (glm::length(dir) == 0.0f) return "camera \"position\" and \"look_at\" are the same point";
  if (!std::isfinite(glm::length(dir)))
    return "camera \"position\" and \"look_at\" are too far apart for a float";
  if (glm::length(glm::cross(glm::normalize(dir), cam.up)) < 1e-6f)
    return "camera \"up\" is zero or parallel to the viewing direction";
  return "";
}

std::string check_settings(const Scene& scene) {
  for (const Setting& s : settings_table()) {
    const std::string problem = check_setting(s, s.get(scene));
    if (!problem.empty()) return problem;
  }
  return check_camera(scene);
}

const std::vector<std::string> kMaterialSetKeys = {
    "materials.NAME.type",       "materials.NAME.albedo",
    "materials.NAME.emission",   "materials.NAME.emission_strength",
    "materials.NAME.ior",        "materials.NAME.fresnel",
    "materials.NAME.absorption", "materials.NAME.two_sided",
    "materials.NAME.roughness",  "materials.NAME.scattering",
    "materials.NAME.g",          "materials.NAME.metal",
    "materials.NAME.eta",        "materials.NAME.k",
    "materials.NAME.thickness",  "materials.NAME.transmittance",
    "materials.NAME.exit"};

bool parse_floats(const std::string& s, float* out, int n) {
  size_t start = 0;
  for (int i = 0; i < n; ++i) {
    const size_t comma = s.find(',', start);
    if ((i < n - 1) != (comma != std::string::npos)) return false;
    const std::string part = s.substr(start, comma - start);
    char* end = nullptr;
    out[i] = std::strtof(part.c_str(), &end);
    if (part.empty() || *end != '\0' || !std::isfinite(out[i])) return false;
    start = comma + 1;
  }
  return true;
}

std::string set_material_assignment(Scene& scene, const std::string& assignment) {
  const size_t eq = assignment.find('=');
  const std::string key = assignment.substr(0, eq), value = assignment.substr(eq + 1);
  const size_t dot = key.rfind('.');
  if (dot <= 10) return "expected materials.NAME.FIELD, not " + quoted(key);
  const std::string name = key.substr(10, dot - 10), field = key.substr(dot + 1);
  const uint32_t idx = scene.find_material(name);
  if (idx == kInvalid) {
    std::vector<std::string> names;
    for (const auto& m : scene.materials) names.push_back(m.name);
    const std::string guess = did_you_mean(name, names);
    return "no material " + quoted(name) +
           (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)");
  }
  Material m = scene.materials[idx].material;
  const float strength = max_component(m.emission);
  float f[3];
  auto number = [&](float lo, float hi) {
    return parse_floats(value, f, 1) && f[0] >= lo && f[0] <= hi;
  };
  if (field == "type") {
    bool known = false;
    for (int t = 0; t < kMaterialTypeCount; ++t) {
      if (value != material_type_name(MaterialType(t)) &&
          !(value == "plastic" && MaterialType(t) == MaterialType::kCoatedDiffuse))
        continue;
      m.type = MaterialType(t);
      known = true;
    }
    if (!known)
      return "expected diffuse, mirror, dielectric, conductor, subsurface, coated_diffuse "
             "(plastic) or diffuse_transmission";
  } else if (field == "roughness" && value.find(',') != std::string::npos) {
    if (!parse_floats(value, f, 2) ||
        !(f[0] >= 0.0f && f[0] <= 1.0f && f[1] >= 0.0f && f[1] <= 1.0f))
      return "expected roughness in [0, 1], or u,v for an anisotropic conductor";
    if (m.type != MaterialType::kConductor) return "only conductors take roughness u,v";
    m.roughness = f[0];
    m.roughness_v = f[1];
  } else if (field == "metal") {
    const NamedMetal* metal = find_metal(value);
    if (!metal) {
      const std::string guess = did_you_mean(value, metal_names());
      std::string list;
      for (const std::string& n : metal_names()) list += (list.empty() ? "" : ", ") + n;
      return "unknown metal " + quoted(value) +
             (guess.empty() ? " (known: " + list + ")" : " (did you mean " + quoted(guess) + "?)");
    }
    if (!(m.flags & kMaterialConductorIor)) m.albedo = vec3(1.0f);  // F0 becomes a tint
    m.type = MaterialType::kConductor;
    m.flags |= kMaterialConductorIor;
    m.eta = metal->eta;
    m.k = metal->k;
  } else if (field == "eta" || field == "k") {
    if (!parse_floats(value, f, 3)) return "expected three finite numbers r,g,b";
    const vec3 v(f[0], f[1], f[2]);
    if (field == "eta" ? !(glm::all(glm::greaterThan(v, vec3(0.0f)))) : max_component(-v) > 0.0f)
      return field == "eta" ? "eta components must be > 0" : "k components must be >= 0";
    if (!(m.flags & kMaterialConductorIor)) {  // from Schlick: start from k = 0, eta = 1
      m.albedo = vec3(1.0f);
      m.eta = vec3(1.0f);
      m.k = vec3(0.0f);
    }
    m.type = MaterialType::kConductor;
    m.flags |= kMaterialConductorIor;
    (field == "eta" ? m.eta : m.k) = v;
  } else if (field == "thickness") {
    if (!number(0.0f, 1e9f)) return "expected a thickness in [0, 1e9]";
    m.thickness = f[0];
  } else if (field == "roughness" || field == "g") {
    if (!number(field == "g" ? -0.99f : 0.0f, field == "g" ? 0.99f : 1.0f))
      return field == "g" ? "expected g in [-0.99, 0.99]" : "expected roughness in [0, 1]";
    (field == "g" ? m.g : m.roughness) = f[0];
    if (field == "roughness") m.roughness_v = -1.0f;
  } else if (field == "albedo" || field == "absorption" || field == "emission" ||
             field == "scattering" || field == "transmittance") {
    if (!parse_floats(value, f, 3)) return "expected three finite numbers r,g,b";
    const vec3 v(f[0], f[1], f[2]);
    if (max_component(-v) > 0.0f) return "components must be >= 0";
    if (field == "albedo") {
      if (max_component(v) > 1.0f) return "albedo components must be <= 1";
      m.albedo = v;
    } else if (field == "absorption") {
      m.absorption = v;
    } else if (field == "scattering") {
      m.scattering = v;
    } else if (field == "transmittance") {
      if (max_component(v) > 1.0f) return "transmittance components must be <= 1";
      m.transmittance = v;
    } else {
      m.emission = v * (strength > 0.0f ? strength : 1.0f);
    }
  } else if (field == "emission_strength") {
    if (!number(0.0f, 1e9f)) return "expected a strength in [0, 1e9]";
    const vec3 colour = strength > 0.0f ? m.emission / strength : vec3(1.0f);
    m.emission = colour * f[0];
  } else if (field == "ior") {
    if (!number(1.0f, 4.0f)) return "expected an index of refraction in [1, 4]";
    m.ior = f[0];
  } else if (field == "fresnel") {
    if (value == "exact")
      m.flags &= ~kMaterialSchlickFresnel;
    else if (value == "schlick")
      m.flags |= kMaterialSchlickFresnel;
    else
      return "expected exact or schlick";
  } else if (field == "exit") {
    if (value == "diffuse")
      m.flags &= ~kMaterialSmoothExit;
    else if (value == "smooth")
      m.flags |= kMaterialSmoothExit;
    else
      return "expected diffuse or smooth (how a subsurface random walk leaves the medium)";
  } else if (field == "two_sided") {
    if (value != "on" && value != "off") return "expected on or off";
    m.flags = value == "on" ? (m.flags | kMaterialTwoSidedEmission)
                            : (m.flags & ~kMaterialTwoSidedEmission);
  } else {
    std::vector<std::string> fields;
    for (const std::string& k : kMaterialSetKeys) fields.push_back(k.substr(k.rfind('.') + 1));
    const std::string guess = did_you_mean(field, fields);
    return "unknown material field " + quoted(field) +
           (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)");
  }
  scene.materials[idx].material = m;
  return "";
}

json material_to_json(const Material& m) {
  json j;
  j["type"] = material_type_name(m.type);
  j["albedo"] = to_value(m.albedo);
  const float strength = max_component(m.emission);
  if (strength > 0.0f) {
    j["emission"] = to_value(m.emission / strength);
    j["emission_strength"] = shortest(strength);
    if (m.flags & kMaterialTwoSidedEmission) j["two_sided"] = true;
  }
  if (m.type == MaterialType::kDielectric || m.type == MaterialType::kSubsurface ||
      m.type == MaterialType::kCoatedDiffuse) {
    j["ior"] = shortest(m.ior);
    j["fresnel"] = (m.flags & kMaterialSchlickFresnel) ? "schlick" : "exact";
    if (max_component(m.absorption) > 0.0f) j["absorption"] = to_value(m.absorption);
  }
  if (m.type == MaterialType::kCoatedDiffuse && max_component(m.absorption) > 0.0f)
    j["thickness"] = shortest(m.thickness);
  if (m.type == MaterialType::kConductor && (m.flags & kMaterialConductorIor)) {
    j["eta"] = to_value(m.eta);
    j["k"] = to_value(m.k);
  }
  if (m.type == MaterialType::kDiffuseTransmission) j["transmittance"] = to_value(m.transmittance);
  if (m.type == MaterialType::kSubsurface) {
    j["exit"] = (m.flags & kMaterialSmoothExit) ? "smooth" : "diffuse";
    j.erase("albedo");
    j["scattering"] = to_value(m.scattering);
    j["absorption"] = to_value(m.absorption);
    j["g"] = shortest(m.g);
  }
  if (m.is_anisotropic())
    j["roughness"] = json::array({shortest(m.roughness), shortest(m.roughness_v)});
  else if (m.roughness > 0.0f)
    j["roughness"] = shortest(m.roughness);
  return j;
}

std::string settings_markdown() {
  std::string out;
  std::string section;
  for (const Setting& s : settings_table()) {
    if (s.section() != section) {
      section = s.section();
      out += (out.empty() ? "" : "\n") + std::string("**\"") + section + "\"**\n\n";
      out +=
          "| key (`--set`) | flag | value | default | meaning | an edit in the window |\n"
          "|---|---|---|---|---|---|\n";
    }
    std::string value;
    if (s.type == T::kChoice || s.type == T::kBool)
      value = choice_list(s);
    else if (s.type == T::kString)
      value = s.path ? "a file name (in a scene file, relative to its folder)" : "text";
    else
      value = std::string(type_words(s)) + ", " + range_text(s);
    if (!s.unit.empty()) value += " (" + s.unit + ")";
    std::string def = setting_default_text(s);
    if (s.type == T::kString && def.empty()) def = "\"\"";
    const char* effect = "";
    switch (s.effect) {
      case E::kDisplay:
        effect = "redraws (no restart)";
        break;
      case E::kCamera:
      case E::kImage:
        effect = "restarts the image";
        break;
      case E::kResize:
        effect = "restarts at the new size";
        break;
      case E::kGpu:
        effect = "speed only (no restart)";
        break;
      case E::kStop:
        effect = "stop condition (no restart)";
        break;
      case E::kBackend:
        effect = "new renderer, restarts";
        break;
    }
    out += "| `" + s.key + "` | " + (s.flag.empty() ? "" : "`" + s.flag + "`") + " | " + value +
           " | `" + def + "` | " + s.help + " | " + effect + " |\n";
  }
  return out;
}

}  // namespace tracer
