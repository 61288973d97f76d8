// Point and spot lights on the host: the scene format's "lights" entries of type "point" and
// "spot", their flux for light selection, their flattening into PointLight
// (scene/point_light_view.h), and the "lights" section as the sidecar and Save scene write it.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "core/diagnostics.h"
#include "scene/environment.h"
#include "scene/point_light_view.h"

namespace tracer {

struct Scene;

// One "lights" entry of type "point" or "spot": radiant intensity I (W/sr, linear RGB) from a
// point, in every direction or, for a spot light, inside a cone whose edge falls off smoothly
// (pbrt-v4's spot light: full intensity within cone_angle - cone_delta_angle of the axis, none
// beyond cone_angle, a smooth step of the cosine between).
struct PointLightDesc {
  std::string name;
  bool spot = false;
  vec3 position = vec3(0.0f);
  vec3 direction = vec3(0.0f, -1.0f, 0.0f);  // spot: where the cone points (need not be unit)
  vec3 intensity = vec3(1.0f);
  float cone_angle_deg = 30.0f;       // spot: half-angle where the falloff ends, (0, 180]
  float cone_delta_angle_deg = 5.0f;  // spot: the falloff's width, [0, cone_angle]
  SourceLoc loc;
};

// The solid angle that turns intensity into flux (pbrt-v4's k_e): 4 pi for a point light,
// 2 pi (1 - (cos start + cos end) / 2) for a spot light.
double point_light_solid_angle(const PointLightDesc& d);
// The flattened light (PointLight::light left kInvalid for CompiledScene to fill).
PointLight make_point_light(const PointLightDesc& d);

// The "lights" section: distant lights, then point and spot lights.
nlohmann::json lights_to_json(const std::vector<DistantLightDesc>& distant,
                              const std::vector<PointLightDesc>& points);

// "lights.NAME.FIELD=VALUE" (--set, the workbench, scripts): a point or spot light's position,
// intensity, direction, cone_angle, cone_delta_angle; a distant light's direction, irradiance,
// angular_diameter. "" or the problem; the light is unchanged on a problem.
std::string set_light_assignment(Scene& scene, const std::string& assignment);
extern const std::vector<std::string> kLightSetKeys;  // "lights.NAME.position", ...

// "2 point lights, 1 spot light" or "" for `info` and the workbench.
std::string describe_point_lights(const std::vector<PointLightDesc>& lights);

}  // namespace tracer
