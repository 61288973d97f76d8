// The environment light and the distant lights on the host: their settings (the settings table's
// "environment" section and the scene's "lights"), the readers of environment maps (Radiance
// .hdr, PFM, OpenEXR including DWA compression), and the flattening into InfiniteLights
// (scene/environment_view.h) with the map's sampling distribution.
#pragma once

#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "core/diagnostics.h"
#include "scene/environment_view.h"

namespace tracer {

// How an environment image is laid out. kAuto: a square image is pbrt-v4's equal-area
// octahedral map, any other an equirectangular (latitude-longitude) one: a guess from the shape,
// so scenes may say which (docs/SCENE_FORMAT.md).
enum class EnvMapping { kAuto, kEquirect, kOctahedral };

// The "environment" section of the settings table.
struct EnvironmentDesc {
  std::string file;  // "" : no map (then `color`, when not black, is a constant environment)
  EnvMapping mapping = EnvMapping::kAuto;
  float strength = 1.0f;      // multiplies the map or the colour
  float rotation_deg = 0.0f;  // about +y, counter-clockwise seen from above (right-handed)
  bool visible = true;        // camera rays see the environment; else `background`
  vec3 background = vec3(0.0f);
  vec3 color = vec3(0.0f);  // the constant environment's radiance when there is no file
  // Not a setting: where a scene format places the map, as a rotation whose columns are the
  // world directions of the map's x, y (up) and z axes (pbrt-v4's light transform); the rotation
  // about +y applies after it.
  mat3 frame = mat3(1.0f);
};

// A decoded environment map: linear RGB radiance, rows top to bottom, no negative texels.
struct EnvironmentImage {
  std::string path;  // as it was read (the setting's value)
  int width = 0, height = 0;
  std::vector<float> rgba;  // 4 floats per texel (alpha unused), the layout the GPU loads
  uint64_t negative = 0;    // texel values below 0 that were clamped to 0
  float most_negative = 0.0f;
};

// One "lights" entry of type "distant": a sun. Irradiance is what a surface facing the light
// receives, whatever the angular diameter; the cone's radiance follows from it.
struct DistantLightDesc {
  std::string name;
  vec3 direction = vec3(0.0f, 1.0f, 0.0f);  // towards the light (need not be unit length)
  vec3 irradiance = vec3(1.0f);
  float angular_diameter_deg = 0.0f;  // 0: a delta light; the sun is about 0.53
  SourceLoc loc;
};

// Reads a .hdr (stb_image), .pfm or .exr (OpenEXR) file. Problems throw InputError naming the
// file: missing, unreadable, another extension, a malformed header, truncated data, a NaN or
// infinite texel. Negative texels are clamped to 0 and counted (the caller warns once).
std::shared_ptr<const EnvironmentImage> read_environment_image(const std::string& path);

// The distant lights as the scene format's "lights" (what the sidecar records).
nlohmann::json distant_lights_to_json(const std::vector<DistantLightDesc>& lights);

// The mapping an image is read with: the setting, or for kAuto square -> octahedral, else
// equirectangular.
EnvMapping resolve_env_mapping(EnvMapping setting, int width, int height);
const char* env_mapping_name(EnvMapping m);  // "auto", "equirect", "octahedral"

// Equal-area octahedral maps must be square; other shapes are an error ("" when fine).
std::string check_env_shape(EnvMapping resolved, int width, int height);

// The host arrays behind InfiniteLights, and the figures light selection needs.
struct InfiniteLightsData {
  std::shared_ptr<const EnvironmentImage> image;  // the texels the view points into
  std::vector<float> func, cond_cdf, marg_cdf;
  std::vector<DistantLight> distant;
  InfiniteLights view;
  // The environment's radiance integrated over the sphere (luminance, strength included),
  // and each distant light's irradiance (luminance), for power-proportional light selection.
  double env_luminance_integral = 0.0;
  std::vector<double> distant_luminance;
  // Whether the integrator has anything to do at infinity (a hidden environment with a black
  // background is nothing).
  bool any() const {
    return view.env != kEnvNone || !distant.empty() ||
           (!view.visible && max_component(view.background) > 0.0f);
  }
};

// Flattens the scene's environment (with its image, already read; `image` may be null when
// desc.file is empty) and distant lights. Light indices (env_light, DistantLight::light) are
// left kInvalid for CompiledScene to fill.
void build_infinite_lights(const EnvironmentDesc& desc,
                           const std::shared_ptr<const EnvironmentImage>& image,
                           const std::vector<DistantLightDesc>& distant, InfiniteLightsData* out);

// The importance of each texel cell for sampling: the luminance of the bilinear lookup averaged
// over the cell (so that every direction the lookup gives radiance has a non-zero pdf) times the
// cell's solid angle (for the equirectangular map about sin(theta) du dv). Exposed for tests.
std::vector<float> env_importance(const InfiniteLights& view);

}  // namespace tracer
