// pbrt-v4 lights: diffuse area lights become emissive materials; point and spot lights, distant
// lights and the infinite light (a map or a constant) become the scene's lights of those kinds;
// goniometric and projection lights are reported and skipped.
#include <algorithm>
#include <cmath>

#include "core/equal_area.h"
#include "scene/loader_util.h"
#include "scene/pbrt_materials.h"
#include "scene/pbrt_spectra.h"

namespace tracer {

namespace {

std::string quoted(const std::string& s) {
  return "\"" + s + "\"";
}

}  // namespace

// ---- Lights ------------------------------------------------------------------------------------

PbrtAreaLight PbrtMaterials::area_light(const std::string& type, PbrtParams& p,
                                        const SourceLoc& loc) {
  if (type != "diffuse")
    throw InputError(loc,
                     "unknown AreaLightSource " + quoted(type) + " (pbrt-v4 has only \"diffuse\")");
  const Ctx c{loc, "AreaLightSource \"diffuse\""};
  PbrtAreaLight a;
  a.active = true;
  const Colour l = colour(p, "L", Use::kEmission, c);
  a.radiance = (l.present ? l.rgb : vec3(1.0f)) * p.get_float("scale", 1.0f);
  a.two_sided = p.get_bool("twosided", false);
  if (p.has("filename")) {
    p.ignore({"filename"});
    substituted(c, "area light image", "image area lights are not supported",
                "used the constant radiance L");
  }
  if (p.has("power")) {
    p.ignore({"power"});
    substituted(c, "area light power", "\"power\" of area lights is not supported",
                "used L x scale");
  }
  p.report_unused(warnings_);
  return a;
}

void PbrtMaterials::light(const std::string& type, PbrtParams& p, const mat4& world,
                          const SourceLoc& loc) {
  if (type == "point")
    light_point(p, world, loc);
  else if (type == "spot")
    light_spot(p, world, loc);
  else if (type == "distant")
    light_distant(p, world, loc);
  else if (type == "infinite")
    light_infinite(p, world, loc);
  else if (type == "goniometric" || type == "projection")
    light_not_yet(type, p, loc);
  else {
    const std::string guess =
        did_you_mean(type, {"point", "spot", "distant", "infinite", "goniometric", "projection"});
    throw InputError(loc, "unknown LightSource " + quoted(type) +
                              (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
  }
}

// pbrt-v4 scales every light's spectrum to one nit before its "scale" (SpectrumToPhotometric);
// for RGB values that leaves the RGB as given, and colour() already normalises blackbody and
// sampled emission spectra to luminance 1. A "power" (point, spot) scales further by
// power / k_e, k_e the solid angle that turns intensity into flux; like pbrt-v4, the RGB's own
// luminance is not divided out.

namespace {

// The light's world transform without its scale: the rotation (or reflection, under our
// mirrored world) that pbrt applies to the light's directions, Gram-Schmidt on its columns.
// `sheared`: whether the transform scaled non-uniformly or sheared (the caller warns).
mat3 light_rotation(const mat4& world, bool* sheared) {
  const mat3 m(world);
  const float sx = glm::length(m[0]), sy = glm::length(m[1]), sz = glm::length(m[2]);
  const float tol = 1e-4f * std::max(sx, std::max(sy, sz));
  *sheared = std::fabs(sx - sy) > tol || std::fabs(sx - sz) > tol ||
             std::fabs(glm::dot(m[0], m[1])) > tol * sx ||
             std::fabs(glm::dot(m[0], m[2])) > tol * sx ||
             std::fabs(glm::dot(m[1], m[2])) > tol * sx;
  const vec3 c0 = glm::normalize(m[0]);
  const vec3 c1 = glm::normalize(m[1] - glm::dot(m[1], c0) * c0);
  const float handed = glm::determinant(m) < 0.0f ? -1.0f : 1.0f;
  return mat3(c0, c1, handed * glm::cross(c0, c1));
}

bool usable_transform(const mat4& world) {
  const float d = glm::determinant(mat3(world));
  return std::isfinite(d) && std::fabs(d) > 1e-30f;
}

vec3 point3(PbrtParams& p, const char* name, vec3 def) {
  const std::vector<double>* v = p.get_numbers(name, "point3");
  if (!v || v->size() < 3) return def;
  return vec3(float((*v)[0]), float((*v)[1]), float((*v)[2]));
}

// "distant (scene.pbrt:424)": a name for the workbench's Lights panel and lights.NAME.FIELD.
std::string light_name(const std::string& type, const SourceLoc& loc) {
  const size_t slash = loc.path.find_last_of('/');
  return type + " (" + (slash == std::string::npos ? loc.path : loc.path.substr(slash + 1)) + ":" +
         std::to_string(loc.line) + ")";
}

}  // namespace

void PbrtMaterials::light_point(PbrtParams& p, const mat4& world, const SourceLoc& loc) {
  point_or_spot(p, world, loc, false);
}
void PbrtMaterials::light_spot(PbrtParams& p, const mat4& world, const SourceLoc& loc) {
  point_or_spot(p, world, loc, true);
}

void PbrtMaterials::point_or_spot(PbrtParams& p, const mat4& world, const SourceLoc& loc,
                                  bool spot) {
  const Ctx c{loc, std::string("LightSource ") + (spot ? "\"spot\"" : "\"point\"")};
  if (!usable_transform(world))
    throw InputError(loc, c.what + ": the current transform is singular");
  PointLightDesc d;
  d.spot = spot;
  d.name = light_name(spot ? "spot" : "point", loc);
  d.loc = loc;
  const Colour i = colour(p, "I", Use::kEmission, c);
  d.intensity = (i.present ? i.rgb : vec3(1.0f)) * p.get_float("scale", 1.0f);
  const vec3 from = point3(p, "from", vec3(0.0f));
  d.position = vec3(world * vec4(from, 1.0f));
  if (spot) {
    const vec3 to = point3(p, "to", vec3(0.0f, 0.0f, 1.0f));
    if (from == to)
      throw InputError(loc, c.what +
                                ": \"from\" and \"to\" are the same point; the cone "
                                "points from one to the other");
    d.direction = glm::normalize(mat3(world) * (to - from));
    d.cone_angle_deg = p.get_float("coneangle", 30.0f);
    if (!(d.cone_angle_deg > 0.0f && d.cone_angle_deg <= 180.0f))
      throw InputError(loc, c.what + ": \"coneangle\" " + std::to_string(d.cone_angle_deg) +
                                " must be in (0, 180] degrees");
    d.cone_delta_angle_deg = p.get_float("conedeltaangle", 5.0f);
    if (!(d.cone_delta_angle_deg >= 0.0f && d.cone_delta_angle_deg <= d.cone_angle_deg)) {
      const float was = d.cone_delta_angle_deg;
      d.cone_delta_angle_deg = std::isfinite(was) ? glm::clamp(was, 0.0f, d.cone_angle_deg) : 0.0f;
      substituted(c, "conedeltaangle",
                  "\"conedeltaangle\" " + std::to_string(was) + " is outside [0, coneangle]",
                  "used " + std::to_string(d.cone_delta_angle_deg));
    }
  }
  const float power = p.get_float("power", -1.0f);
  if (power > 0.0f) d.intensity *= float(double(power) / point_light_solid_angle(d));
  p.report_unused(warnings_);
  if (!(max_component(d.intensity) > 0.0f)) {
    warnings_.warn(loc, "black light", c.what + " has zero intensity", "it lights nothing");
    return;
  }
  scene_.point_lights.push_back(d);
}

void PbrtMaterials::light_distant(PbrtParams& p, const mat4& world, const SourceLoc& loc) {
  const Ctx c{loc, "LightSource \"distant\""};
  if (!usable_transform(world))
    throw InputError(loc, c.what + ": the current transform is singular");
  DistantLightDesc d;
  d.name = light_name("distant", loc);
  d.loc = loc;
  const vec3 from = point3(p, "from", vec3(0.0f)), to = point3(p, "to", vec3(0.0f, 0.0f, 1.0f));
  if (from == to)
    throw InputError(loc, c.what +
                              ": \"from\" and \"to\" are the same point; the light comes "
                              "from \"from\" towards \"to\"");
  d.direction = glm::normalize(mat3(world) * (from - to));
  const Colour l = colour(p, "L", Use::kEmission, c);
  // pbrt-v4's irradiance on a surface facing the light: L x scale, or with "illuminance" that
  // many lux (scale x illuminance with L at one nit).
  d.irradiance = (l.present ? l.rgb : vec3(1.0f)) * p.get_float("scale", 1.0f);
  const float e = p.get_float("illuminance", -1.0f);
  if (e > 0.0f) d.irradiance *= e;
  p.report_unused(warnings_);
  if (!(max_component(d.irradiance) > 0.0f)) {
    warnings_.warn(loc, "black light", c.what + " has zero radiance", "it lights nothing");
    return;
  }
  scene_.distant_lights.push_back(d);
}

// The environment: an equal-area octahedral map ("filename") or a constant radiance ("L", or
// pbrt's default illuminant), placed by the current transform (pbrt's light space has +z up;
// EnvironmentDesc::frame takes our map frame's y, its up, to the light's z). The scene has one
// environment: a second constant one adds its radiance to the first, anything else is skipped.
void PbrtMaterials::light_infinite(PbrtParams& p, const mat4& world, const SourceLoc& loc) {
  const Ctx c{loc, "LightSource \"infinite\""};
  if (!usable_transform(world))
    throw InputError(loc, c.what + ": the current transform is singular");
  const std::string file = p.get_string("filename", "");
  const Colour l = colour(p, "L", Use::kEmission, c);
  if (!file.empty() && l.present)
    throw InputError(loc, c.what +
                              ": \"L\" and \"filename\" cannot both be given (pbrt-v4 "
                              "refuses it too)");
  const float scale = p.get_float("scale", 1.0f);
  const float illuminance = p.get_float("illuminance", -1.0f);
  if (p.has("portal")) {
    p.ignore({"portal"});
    substituted(c, "portal", "portals are not supported",
                "the whole map lights the scene, sampled without the portal");
  }
  p.report_unused(warnings_);
  EnvironmentDesc& env = scene_.environment;
  const bool have_map = !env.file.empty();
  const bool have_constant = !have_map && max_component(env.color) > 0.0f;
  if (file.empty()) {
    // pbrt-v4: illuminance E on an upward surface from a uniform L is pi L.
    vec3 radiance = (l.present ? l.rgb : vec3(1.0f)) * scale;
    if (illuminance > 0.0f) radiance *= illuminance / float(M_PI);
    if (have_map) {
      warnings_.warn(loc, "second infinite light",
                     c.what +
                         ": a constant environment after an environment map (the scene has "
                         "one environment)",
                     "skipped this one");
      return;
    }
    if (have_constant) {
      // Two constant environments are one of their summed radiance.
      env.color = env.color * env.strength + radiance;
      env.strength = 1.0f;
      warnings_.note(loc, "second infinite light",
                     c.what + ": added to the constant environment before it");
      return;
    }
    env.color = radiance;
    env.strength = 1.0f;
    env.frame = mat3(1.0f);
    env_loc_ = loc;
    return;
  }
  if (have_map || have_constant) {
    warnings_.warn(loc, "second infinite light",
                   c.what + ": a second environment (the scene has one, from line " +
                       std::to_string(env_loc_.line) + ")",
                   "skipped this one");
    return;
  }
  const std::string path = path_join(base_dir_, file);
  const EnvironmentDesc old = env;
  env.file = path;
  env.mapping = EnvMapping::kOctahedral;  // pbrt-v4's image infinite lights are equal-area maps
  env.color = vec3(0.0f);
  env.strength = scale;
  const std::string problem = refresh_environment(scene_);
  if (!problem.empty()) {
    env = old;
    throw InputError(loc, c.what + ": " + problem);
  }
  bool sheared = false;
  // Our map frame's x, y (up) and z are the light's x, z and -y (scene/environment_view.h).
  const mat3 swap(vec3(1.0f, 0.0f, 0.0f), vec3(0.0f, 0.0f, 1.0f), vec3(0.0f, -1.0f, 0.0f));
  env.frame = light_rotation(world, &sheared) * swap;
  if (sheared)
    substituted(c, "light transform", "the transform scales non-uniformly or shears",
                "used its rotation");
  if (illuminance > 0.0f) {
    // pbrt-v4's estimate of the map's illuminance on a surface facing the light's +z: the
    // luminance times cos(theta) summed over the texels of the upper hemisphere, times
    // 2 pi / (w h) (as pbrt-v4 computes it, to match its scenes).
    const EnvironmentImage& img = *scene_.environment_image;
    double sum = 0.0;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        const vec3 w = equal_area_square_to_sphere(
            vec2((float(x) + 0.5f) / float(img.width), (float(y) + 0.5f) / float(img.height)));
        if (w.z <= 0.0f) continue;
        const float* t = &img.rgba[4 * (size_t(y) * size_t(img.width) + size_t(x))];
        sum += double(luminance(vec3(t[0], t[1], t[2]))) * double(w.z);
      }
    sum *= 2.0 * M_PI / (double(img.width) * double(img.height));
    if (sum > 0.0)
      env.strength *= float(double(illuminance) / sum);
    else
      substituted(c, "illuminance", "\"illuminance\" of a map that is black above the horizon",
                  "used \"scale\" alone");
  }
  env_loc_ = loc;
}

void PbrtMaterials::light_not_yet(const std::string& type, PbrtParams&, const SourceLoc& loc) {
  warnings_.warn(loc, "LightSource " + type,
                 "LightSource " + quoted(type) + " is not supported yet", "skipped");
}

}  // namespace tracer
