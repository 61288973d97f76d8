// Point and spot lights on the host: flux, flattening, the "lights" section as JSON, and edits by
// name (lights.NAME.FIELD).
#include "scene/point_lights.h"

#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>

#include "scene/scene.h"

namespace tracer {

namespace {

double radians(double deg) {
  return deg * M_PI / 180.0;
}

// The falloff's cosines (pbrt-v4: cosFalloffEnd = cos(coneangle), cosFalloffStart =
// cos(coneangle - conedeltaangle)).
void spot_cosines(const PointLightDesc& d, double* cos_start, double* cos_end) {
  *cos_end = std::cos(radians(d.cone_angle_deg));
  *cos_start = std::cos(radians(d.cone_angle_deg - d.cone_delta_angle_deg));
}

std::string quoted(const std::string& s) {
  return "\"" + s + "\"";
}

}  // namespace

const std::vector<std::string> kLightSetKeys = {
    "lights.NAME.position",        "lights.NAME.intensity",        "lights.NAME.direction",
    "lights.NAME.cone_angle",      "lights.NAME.cone_delta_angle", "lights.NAME.irradiance",
    "lights.NAME.angular_diameter"};

double point_light_solid_angle(const PointLightDesc& d) {
  if (!d.spot) return 4.0 * M_PI;
  double cos_start, cos_end;
  spot_cosines(d, &cos_start, &cos_end);
  return 2.0 * M_PI * (1.0 - 0.5 * (cos_start + cos_end));
}

PointLight make_point_light(const PointLightDesc& d) {
  PointLight pl;
  pl.position = d.position;
  pl.intensity = d.intensity;
  pl.light = kInvalid;
  if (d.spot) {
    double cos_start, cos_end;
    spot_cosines(d, &cos_start, &cos_end);
    pl.cos_falloff_start = float(cos_start);
    pl.cos_falloff_end = float(cos_end);
    pl.axis = glm::normalize(d.direction);
  } else {
    pl.cos_falloff_start = pl.cos_falloff_end = -2.0f;  // point_light_intensity: no cone
    pl.axis = vec3(0.0f, 0.0f, 1.0f);
  }
  return pl;
}

nlohmann::json lights_to_json(const std::vector<DistantLightDesc>& distant,
                              const std::vector<PointLightDesc>& points) {
  nlohmann::json out = distant_lights_to_json(distant);
  auto v = [](vec3 x) { return nlohmann::json::array({x.x, x.y, x.z}); };
  for (const PointLightDesc& d : points) {
    nlohmann::json j = {{"type", d.spot ? "spot" : "point"},
                        {"name", d.name},
                        {"position", v(d.position)},
                        {"intensity", v(d.intensity)}};
    if (d.spot) {
      j["direction"] = v(d.direction);
      j["cone_angle"] = d.cone_angle_deg;
      j["cone_delta_angle"] = d.cone_delta_angle_deg;
    }
    out.push_back(j);
  }
  return out;
}

std::string set_light_assignment(Scene& scene, const std::string& assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos) return "expected KEY=VALUE, not " + quoted(assignment);
  const std::string key = assignment.substr(0, eq), value = assignment.substr(eq + 1);
  const size_t dot = key.rfind('.');
  if (key.rfind("lights.", 0) != 0 || dot == std::string::npos || dot <= 7)
    return "expected lights.NAME.FIELD, not " + quoted(key);
  const std::string name = key.substr(7, dot - 7), field = key.substr(dot + 1);
  PointLightDesc* point = nullptr;
  DistantLightDesc* distant = nullptr;
  std::vector<std::string> names;
  for (PointLightDesc& p : scene.point_lights) {
    names.push_back(p.name);
    if (p.name == name && !point) point = &p;
  }
  for (DistantLightDesc& d : scene.distant_lights) {
    names.push_back(d.name);
    if (d.name == name && !point && !distant) distant = &d;
  }
  if (!point && !distant) {
    const std::string guess = did_you_mean(name, names);
    return "no light " + quoted(name) +
           (guess.empty() ? (names.empty() ? " (the scene has no \"lights\")" : "")
                          : " (did you mean " + quoted(guess) + "?)");
  }
  float f[3];
  auto vector = [&](bool non_negative, bool non_zero, std::string* problem) {
    if (!parse_floats(value, f, 3)) {
      *problem = "expected three finite numbers x,y,z";
      return vec3(0.0f);
    }
    const vec3 v(f[0], f[1], f[2]);
    if (non_negative && max_component(-v) > 0.0f) *problem = "components must be >= 0";
    if (non_zero && !(glm::dot(v, v) > 1e-30f)) *problem = "expected a non-zero direction";
    return v;
  };
  auto number = [&](float lo, float hi) {
    return parse_floats(value, f, 1) && f[0] >= lo && f[0] <= hi;
  };
  std::string problem;
  if (point) {
    PointLightDesc d = *point;
    if (field == "position") {
      d.position = vector(false, false, &problem);
    } else if (field == "intensity") {
      d.intensity = vector(true, false, &problem);
    } else if (field == "direction" && d.spot) {
      d.direction = vector(false, true, &problem);
    } else if (field == "cone_angle" && d.spot) {
      if (!number(1e-3f, 180.0f)) return "expected a cone angle in (0, 180] degrees";
      d.cone_angle_deg = f[0];
      d.cone_delta_angle_deg = std::min(d.cone_delta_angle_deg, d.cone_angle_deg);
    } else if (field == "cone_delta_angle" && d.spot) {
      if (!number(0.0f, d.cone_angle_deg))
        return "expected a falloff width in [0, cone_angle] = [0, " +
               std::to_string(d.cone_angle_deg) + "] degrees";
      d.cone_delta_angle_deg = f[0];
    } else {
      return "unknown field " + quoted(field) + " of " + (d.spot ? "spot" : "point") + " light " +
             quoted(name) +
             (d.spot ? " (position, intensity, direction, cone_angle, cone_delta_angle)"
                     : " (position, intensity)");
    }
    if (!problem.empty()) return problem;
    *point = d;
    return "";
  }
  DistantLightDesc d = *distant;
  if (field == "direction") {
    d.direction = vector(false, true, &problem);
  } else if (field == "irradiance") {
    d.irradiance = vector(true, false, &problem);
  } else if (field == "angular_diameter") {
    if (!number(0.0f, 179.9f)) return "expected an angular diameter in [0, 180) degrees";
    d.angular_diameter_deg = f[0];
  } else {
    return "unknown field " + quoted(field) + " of distant light " + quoted(name) +
           " (direction, irradiance, angular_diameter)";
  }
  if (!problem.empty()) return problem;
  *distant = d;
  return "";
}

std::string describe_point_lights(const std::vector<PointLightDesc>& lights) {
  size_t points = 0, spots = 0;
  for (const PointLightDesc& d : lights) (d.spot ? spots : points)++;
  std::string s;
  if (points) s = std::to_string(points) + (points == 1 ? " point light" : " point lights");
  if (spots)
    s += (s.empty() ? "" : ", ") + std::to_string(spots) +
         (spots == 1 ? " spot light" : " spot lights");
  return s;
}

}  // namespace tracer
