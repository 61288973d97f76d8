// The JSON scene format (docs/SCENE_FORMAT.md): camera, render settings, named materials and
// objects, read with a line for every value so that each message points at the offending spot.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>
#include <initializer_list>

#include "core/math.h"
#include "materials/metals.h"
#include "materials/subsurface.h"
#include "scene/json_lines.h"
#include "scene/loader.h"
#include "scene/loader_util.h"
#include "scene/pbrt_shapes.h"

namespace tracer {

extern const char* const kBuiltinSceneJson;

namespace {

using nlohmann::json;

const char* json_type_name(const json& v) {
  if (v.is_number()) return "a number";
  if (v.is_string()) return "a string";
  if (v.is_boolean()) return "a boolean";
  if (v.is_null()) return "null";
  if (v.is_array()) return "an array";
  if (v.is_object()) return "an object";
  return "something else";
}

std::string in_quotes(const std::string& s) {
  return "\"" + s + "\"";
}

class JsonSceneReader {
 public:
  JsonSceneReader(const JsonDocument& doc, const std::string& path, Scene& scene)
      : doc_(doc), path_(path), scene_(scene) {}

  void read() {
    const json& root = doc_.root;
    if (!root.is_object())
      fail("", std::string("a scene file must be a JSON object, not ") + json_type_name(root));
    check_keys(
        root, "",
        {"camera", "render", "gpu", "display", "environment", "materials", "objects", "lights"},
        "the scene");
    for (const char* section : {"camera", "render", "gpu", "display", "environment"})
      if (root.contains(section)) read_settings(root[section], section);
    if (root.contains("lights")) read_lights(root["lights"], "/lights");
    if (root.contains("camera")) {
      const std::string problem = check_camera(scene_);
      if (!problem.empty()) fail("/camera", problem);
    }
    if (root.contains("materials")) read_materials(root["materials"], "/materials");
    if (!root.contains("objects")) fail("", "the scene has no \"objects\"");
    read_objects(root["objects"], "/objects");
  }

 private:
  SourceLoc at(const std::string& ptr) const { return {path_, doc_.line_of(ptr)}; }
  [[noreturn]] void fail(const std::string& ptr, const std::string& problem) const {
    throw InputError(at(ptr), problem);
  }

  void require_object(const json& v, const std::string& ptr, const std::string& what) const {
    if (!v.is_object()) fail(ptr, what + " must be a JSON object {...}, not " + json_type_name(v));
  }

  // Unknown keys are errors, not warnings: a misspelt "albdo" would otherwise silently render
  // the default colour.
  void check_keys(const json& obj, const std::string& ptr,
                  std::initializer_list<const char*> allowed, const std::string& where) const {
    std::vector<std::string> names(allowed.begin(), allowed.end());
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      if (std::find(names.begin(), names.end(), it.key()) != names.end()) continue;
      const std::string guess = did_you_mean(it.key(), names);
      const std::string key_ptr = json_pointer_child(ptr, it.key());
      std::string msg = "unknown key " + in_quotes(it.key()) + " in " + where;
      msg += guess.empty() ? " (expected one of: " + join(names) + ")"
                           : " (did you mean " + in_quotes(guess) + "?)";
      throw InputError({path_, doc_.key_line(key_ptr)}, msg);
    }
  }

  static std::string join(const std::vector<std::string>& names) {
    std::string s;
    for (const std::string& n : names) s += (s.empty() ? "" : ", ") + n;
    return s;
  }

  double number(const json& v, const std::string& ptr, const std::string& what) const {
    if (!v.is_number()) fail(ptr, what + " must be a number, not " + json_type_name(v));
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(ptr, what + " is not a finite number (too large for a float?)");
    if (std::fabs(d) > 3.0e38) fail(ptr, what + " is too large for a 32-bit float");
    return d;
  }

  float get_float(const json& obj, const std::string& ptr, const char* key, float def,
                  const std::string& where) const {
    if (!obj.contains(key)) return def;
    return float(number(obj[key], json_pointer_child(ptr, key), in_quotes(key) + " in " + where));
  }

  bool get_bool(const json& obj, const std::string& ptr, const char* key, bool def,
                const std::string& where) const {
    if (!obj.contains(key)) return def;
    const json& v = obj[key];
    if (!v.is_boolean()) {
      fail(json_pointer_child(ptr, key),
           in_quotes(key) + " in " + where + " must be true or false, not " + json_type_name(v));
    }
    return v.get<bool>();
  }

  std::string get_string(const json& obj, const std::string& ptr, const char* key,
                         const std::string& def, const std::string& where) const {
    if (!obj.contains(key)) return def;
    const json& v = obj[key];
    if (!v.is_string()) {
      fail(json_pointer_child(ptr, key),
           in_quotes(key) + " in " + where + " must be a string, not " + json_type_name(v));
    }
    return v.get<std::string>();
  }

  vec3 vec3_value(const json& v, const std::string& ptr, const std::string& what) const {
    if (!v.is_array() || v.size() != 3) {
      fail(ptr, what + " must be an array of 3 numbers, not " +
                    (v.is_array() ? "one of " + std::to_string(v.size()) : json_type_name(v)));
    }
    vec3 out;
    for (int i = 0; i < 3; ++i)
      out[i] = float(number(v[i], json_pointer_child(ptr, size_t(i)), what));
    return out;
  }

  vec3 get_vec3(const json& obj, const std::string& ptr, const char* key, vec3 def,
                const std::string& where) const {
    if (!obj.contains(key)) return def;
    return vec3_value(obj[key], json_pointer_child(ptr, key), in_quotes(key) + " in " + where);
  }

  // A section of the settings table ("camera", "render", "gpu", "display"): every key must be
  // a setting of that section, every value valid for it (settings_table() says what that is).
  void read_settings(const json& obj, const std::string& section) {
    const std::string ptr = "/" + section;
    require_object(obj, ptr, in_quotes(section));
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      const Setting* s = find_setting(section + "." + it.key());
      if (!s) {
        throw InputError({path_, doc_.key_line(json_pointer_child(ptr, it.key()))},
                         unknown_setting_message(it.key(), section));
      }
      json value = it.value();
      // A file named by the scene is relative to the scene's folder; kept absolute, so that a
      // sidecar or saved scene elsewhere names the same file.
      if (s->path && value.is_string() && !value.get<std::string>().empty()) {
        const std::string full = path_join(path_directory(path_), value.get<std::string>());
        value = std::filesystem::absolute(full).lexically_normal().string();
      }
      const std::string problem = set_setting(scene_, *s, value);
      if (!problem.empty()) fail(json_pointer_child(ptr, it.key()), problem);
    }
  }

  // "lights": lights that are no geometry: the distant light (a sun), the point light and the
  // spot light.
  void read_lights(const json& ls, const std::string& ptr) {
    if (!ls.is_array())
      fail(ptr, std::string("\"lights\" must be an array [...], not ") + json_type_name(ls));
    for (size_t i = 0; i < ls.size(); ++i) {
      const json& l = ls[i];
      const std::string lp = json_pointer_child(ptr, i);
      const std::string where = "light " + std::to_string(i);
      require_object(l, lp, where);
      const std::string type = get_string(l, lp, "type", "", where);
      const std::vector<std::string> types = {"distant", "point", "spot"};
      if (std::find(types.begin(), types.end(), type) == types.end()) {
        const std::string guess = did_you_mean(type, types);
        fail(l.contains("type") ? json_pointer_child(lp, "type") : lp,
             (type.empty() ? where + " has no \"type\"" : "unknown light type " + in_quotes(type)) +
                 (guess.empty() ? " (expected distant, point or spot)"
                                : " (did you mean " + in_quotes(guess) + "?)"));
      }
      if (type == "distant")
        read_distant_light(l, lp, where);
      else
        read_point_light(l, lp, where, type == "spot");
    }
  }

  // A sun: "direction" towards it, "irradiance" on a surface facing it, "angular_diameter" in
  // degrees (0: a delta light).
  void read_distant_light(const json& l, const std::string& lp, const std::string& where) {
    check_keys(l, lp, {"type", "name", "direction", "irradiance", "angular_diameter"}, where);
    DistantLightDesc d;
    d.name = get_string(l, lp, "name", where, where);
    d.loc = at(lp);
    if (!l.contains("direction")) fail(lp, where + " has no \"direction\" (towards the light)");
    d.direction = get_vec3(l, lp, "direction", d.direction, where);
    const double len2 = double(d.direction.x) * d.direction.x +
                        double(d.direction.y) * d.direction.y +
                        double(d.direction.z) * d.direction.z;
    if (!(len2 > 1e-30) || !std::isfinite(len2))
      fail(json_pointer_child(lp, "direction"),
           "\"direction\" of " + where + " must be a non-zero vector of moderate length");
    d.irradiance = get_vec3(l, lp, "irradiance", d.irradiance, where);
    if (glm::any(glm::lessThan(d.irradiance, vec3(0.0f))))
      fail(json_pointer_child(lp, "irradiance"), "\"irradiance\" of " + where + " must be >= 0");
    d.angular_diameter_deg = get_float(l, lp, "angular_diameter", 0.0f, where);
    if (!(d.angular_diameter_deg >= 0.0f && d.angular_diameter_deg < 180.0f))
      fail(json_pointer_child(lp, "angular_diameter"),
           "\"angular_diameter\" of " + where + " must be in [0, 180) degrees");
    if (max_component(d.irradiance) <= 0.0f)
      scene_.diagnostics.warn(at(lp), where + " has zero irradiance", "it lights nothing");
    scene_.distant_lights.push_back(d);
  }

  // A point light: "position", "intensity" (W/sr) or "power" (W, the flux in all directions).
  // A spot light also "direction" or "look_at" (where the cone points), "cone_angle" (where the
  // falloff ends) and "cone_delta_angle" (its width), in degrees, as pbrt-v4's.
  void read_point_light(const json& l, const std::string& lp, const std::string& where, bool spot) {
    if (spot)
      check_keys(l, lp,
                 {"type", "name", "position", "direction", "look_at", "intensity", "power",
                  "cone_angle", "cone_delta_angle"},
                 where);
    else
      check_keys(l, lp, {"type", "name", "position", "intensity", "power"}, where);
    PointLightDesc d;
    d.spot = spot;
    d.name = get_string(l, lp, "name", where, where);
    d.loc = at(lp);
    if (!l.contains("position")) fail(lp, where + " has no \"position\"");
    d.position = get_vec3(l, lp, "position", d.position, where);
    if (spot) {
      if (l.contains("direction") && l.contains("look_at"))
        fail(json_pointer_child(lp, "look_at"),
             where + " has both \"direction\" and \"look_at\": give one");
      if (!l.contains("direction") && !l.contains("look_at"))
        fail(lp, where + " has no \"direction\" or \"look_at\" (where the cone points)");
      const char* key = l.contains("direction") ? "direction" : "look_at";
      const vec3 v = get_vec3(l, lp, key, vec3(0.0f), where);
      d.direction = l.contains("direction") ? v : v - d.position;
      const double len2 = double(d.direction.x) * d.direction.x +
                          double(d.direction.y) * d.direction.y +
                          double(d.direction.z) * d.direction.z;
      if (!(len2 > 1e-30) || !std::isfinite(len2))
        fail(json_pointer_child(lp, key),
             l.contains("direction")
                 ? "\"direction\" of " + where + " must be a non-zero vector of moderate length"
                 : "\"look_at\" of " + where + " must differ from its \"position\"");
      d.cone_angle_deg = get_float(l, lp, "cone_angle", d.cone_angle_deg, where);
      if (!(d.cone_angle_deg > 0.0f && d.cone_angle_deg <= 180.0f))
        fail(json_pointer_child(lp, "cone_angle"),
             "\"cone_angle\" of " + where + " must be in (0, 180] degrees");
      d.cone_delta_angle_deg = get_float(l, lp, "cone_delta_angle",
                                         std::min(d.cone_delta_angle_deg, d.cone_angle_deg), where);
      if (!(d.cone_delta_angle_deg >= 0.0f && d.cone_delta_angle_deg <= d.cone_angle_deg))
        fail(json_pointer_child(lp, "cone_delta_angle"),
             "\"cone_delta_angle\" of " + where + " must be in [0, cone_angle] degrees");
    }
    if (l.contains("intensity") && l.contains("power"))
      fail(json_pointer_child(lp, "power"),
           where + " has both \"intensity\" and \"power\": give one");
    const char* key = l.contains("power") ? "power" : "intensity";
    const vec3 v = get_vec3(l, lp, key, vec3(1.0f), where);
    if (glm::any(glm::lessThan(v, vec3(0.0f))))
      fail(json_pointer_child(lp, key), in_quotes(key) + " of " + where + " must be >= 0");
    d.intensity = l.contains("power") ? v / float(point_light_solid_angle(d)) : v;
    if (max_component(d.intensity) <= 0.0f)
      scene_.diagnostics.warn(at(lp), where + " has zero " + key, "it lights nothing");
    scene_.point_lights.push_back(d);
  }

  void read_materials(const json& ms, const std::string& ptr) {
    require_object(ms, ptr, "\"materials\"");
    for (auto it = ms.begin(); it != ms.end(); ++it)
      read_material(it.key(), it.value(), json_pointer_child(ptr, it.key()));
  }

  void read_material(const std::string& name, const json& m, const std::string& ptr) {
    if (name.empty()) fail(ptr, "a material name must not be empty");
    scene_.add_material(name, parse_material("material " + in_quotes(name), m, ptr, nullptr));
  }

  // A material definition. With a `base` (a mesh file's material being overridden), the keys
  // given replace the base's values and the rest, textures included, are kept.
  Material parse_material(const std::string& where, const json& m, const std::string& ptr,
                          const Material* base) {
    require_object(m, ptr, where);
    check_keys(m, ptr,
               {"type", "albedo", "emission", "emission_strength", "two_sided", "ior", "fresnel",
                "absorption", "roughness", "scattering", "mean_free_path", "g", "metal", "eta", "k",
                "thickness", "transmittance", "exit"},
               where);
    Material mat = base ? *base : Material();
    std::string type =
        get_string(m, ptr, "type", base ? material_type_name(base->type) : "diffuse", where);
    if (type == "plastic") type = "coated_diffuse";  // the name Mitsuba and Tungsten use
    const std::vector<std::string> types = {
        "diffuse",    "mirror",         "dielectric", "conductor",
        "subsurface", "coated_diffuse", "plastic",    "diffuse_transmission"};
    bool known = false;
    for (int t = 0; t < kMaterialTypeCount; ++t) {
      if (type != material_type_name(MaterialType(t))) continue;
      mat.type = MaterialType(t);
      known = true;
    }
    if (!known) {
      const std::string guess = did_you_mean(type, types);
      fail(json_pointer_child(ptr, "type"),
           "unknown material type " + in_quotes(type) + " in " + where +
               (guess.empty() ? " (expected diffuse, mirror, dielectric, conductor, subsurface, "
                                "coated_diffuse (plastic) or diffuse_transmission)"
                              : " (did you mean " + in_quotes(guess) + "?)"));
    }
    const bool dielectric = mat.type == MaterialType::kDielectric;
    const bool subsurface = mat.type == MaterialType::kSubsurface;
    const bool conductor = mat.type == MaterialType::kConductor;
    const bool coated = mat.type == MaterialType::kCoatedDiffuse;
    const bool transmission = mat.type == MaterialType::kDiffuseTransmission;
    const bool has_boundary = dielectric || subsurface || coated;  // ior and fresnel apply
    const bool base_ior =
        base && base->type == MaterialType::kConductor && (base->flags & kMaterialConductorIor);
    const bool ior_conductor =
        conductor && (m.contains("metal") || m.contains("eta") || m.contains("k") || base_ior);
    // An IOR conductor's albedo tints its Fresnel reflectance: white unless given, also over a
    // base whose albedo meant something else (a diffuse colour, a Schlick F0).
    const vec3 default_albedo = ior_conductor && !base_ior ? vec3(1.0f)
                                : base                     ? base->albedo
                                : dielectric               ? vec3(1.0f)
                                : transmission             ? vec3(0.5f)
                                                           : vec3(0.8f);
    mat.albedo = get_vec3(m, ptr, "albedo", default_albedo, where);
    const vec3 clamped = glm::clamp(mat.albedo, vec3(0.0f), vec3(1.0f));
    if (clamped != mat.albedo) {
      // Albedo above 1 creates energy and below 0 is meaningless; both are likely typos of scale.
      scene_.diagnostics.warn(
          at(json_pointer_child(ptr, "albedo")),
          "\"albedo\" " + vec3_str(mat.albedo) + " in " + where + " is outside [0, 1]",
          "clamped to " + vec3_str(clamped));
      mat.albedo = clamped;
    }
    const vec3 emission = get_vec3(m, ptr, "emission", base ? base->emission : vec3(0.0f), where);
    if (glm::any(glm::lessThan(emission, vec3(0.0f))))
      fail(json_pointer_child(ptr, "emission"), "\"emission\" in " + where + " must be >= 0");
    const float strength = get_float(m, ptr, "emission_strength", 1.0f, where);
    if (strength < 0.0f) {
      fail(json_pointer_child(ptr, "emission_strength"),
           "\"emission_strength\" in " + where + " must be >= 0");
    }
    mat.emission = emission * strength;
    if (m.contains("emission_strength") && !glm::any(glm::greaterThan(emission, vec3(0.0f)))) {
      scene_.diagnostics.warn(at(json_pointer_child(ptr, "emission_strength")),
                              "\"emission_strength\" in " + where +
                                  " scales an emission of zero (give \"emission\")",
                              "no light is emitted");
    }
    const bool two_sided = base && (base->flags & kMaterialTwoSidedEmission);
    const bool smooth_exit = base && (base->flags & kMaterialSmoothExit);
    mat.flags &= ~uint32_t(kMaterialTwoSidedEmission | kMaterialSchlickFresnel |
                           kMaterialConductorIor | kMaterialSmoothExit);
    if (get_bool(m, ptr, "two_sided", two_sided, where)) mat.flags |= kMaterialTwoSidedEmission;

    auto ignored = [&](const char* key, bool applies) {
      if (!applies && m.contains(key)) {
        scene_.diagnostics.warn(at(json_pointer_child(ptr, key)),
                                in_quotes(key) + " has no effect on a " + type + " material",
                                "ignored");
      }
    };
    ignored("ior", has_boundary);
    ignored("fresnel", has_boundary);
    ignored("absorption", has_boundary);
    ignored("roughness", dielectric || conductor || coated);
    for (const char* key : {"scattering", "mean_free_path", "g", "exit"}) ignored(key, subsurface);
    for (const char* key : {"metal", "eta", "k"}) ignored(key, conductor);
    ignored("thickness", coated);
    ignored("transmittance", transmission);

    mat.ior = get_float(m, ptr, "ior", base ? base->ior : subsurface ? 1.4f : 1.5f, where);
    if (has_boundary && !(mat.ior >= 1.0f && mat.ior <= 4.0f)) {
      fail(json_pointer_child(ptr, "ior"), "\"ior\" in " + where + " must be in [1, 4]");
    }
    if ((dielectric || coated) && mat.ior == 1.0f) {
      scene_.diagnostics.warn(
          at(json_pointer_child(ptr, "ior")),
          "\"ior\" 1 makes " + (coated ? "the coat of " : std::string()) + where + " invisible",
          "rendered as given");
    }
    const bool schlick = base && (base->flags & kMaterialSchlickFresnel);
    const std::string fresnel = get_string(m, ptr, "fresnel", schlick ? "schlick" : "exact", where);
    if (fresnel == "schlick") {
      if (has_boundary) mat.flags |= kMaterialSchlickFresnel;
    } else if (fresnel != "exact") {
      const std::string guess = did_you_mean(fresnel, {"exact", "schlick"});
      fail(json_pointer_child(ptr, "fresnel"),
           "\"fresnel\" in " + where + " must be \"exact\" or \"schlick\", not " +
               in_quotes(fresnel) +
               (guess.empty() ? "" : " (did you mean " + in_quotes(guess) + "?)"));
    }
    read_roughness(m, ptr, where, base, mat);
    mat.absorption = get_vec3(m, ptr, "absorption", base ? base->absorption : vec3(0.0f), where);
    if (glm::any(glm::lessThan(mat.absorption, vec3(0.0f))))
      fail(json_pointer_child(ptr, "absorption"), "\"absorption\" in " + where + " must be >= 0");
    mat.thickness = get_float(m, ptr, "thickness", base ? base->thickness : 1.0f, where);
    if (!(mat.thickness >= 0.0f))
      fail(json_pointer_child(ptr, "thickness"), "\"thickness\" in " + where + " must be >= 0");
    if (subsurface) read_medium(m, ptr, where, mat);
    // How a random walk leaves (integrator/medium.h, subsurface_exit_material).
    const std::string exit = get_string(m, ptr, "exit", smooth_exit ? "smooth" : "diffuse", where);
    if (exit == "smooth") {
      if (subsurface) mat.flags |= kMaterialSmoothExit;
    } else if (exit != "diffuse") {
      const std::string guess = did_you_mean(exit, {"diffuse", "smooth"});
      fail(json_pointer_child(ptr, "exit"),
           "\"exit\" in " + where + " must be \"diffuse\" or \"smooth\", not " + in_quotes(exit) +
               (guess.empty() ? "" : " (did you mean " + in_quotes(guess) + "?)"));
    }
    if (ior_conductor) read_complex_ior(m, ptr, where, base, mat);
    if (transmission) read_transmittance(m, ptr, where, base, mat);
    if (!has_boundary) mat.absorption = vec3(0.0f), mat.ior = 1.5f;
    if (!dielectric && !conductor && !coated) mat.roughness = 0.0f;
    if (!conductor) mat.roughness_v = -1.0f;
    return mat;
  }

  // "roughness": a number, or for a conductor [u, v]: u along the surface's tangent (the world
  // +y axis projected onto it, bsdf_frame), v across.
  void read_roughness(const json& m, const std::string& ptr, const std::string& where,
                      const Material* base, Material& mat) const {
    const std::string key_ptr = json_pointer_child(ptr, "roughness");
    auto check = [&](float r) {
      if (!(r >= 0.0f && r <= 1.0f))
        fail(key_ptr, "\"roughness\" in " + where + " must be in [0, 1]");
      return r;
    };
    if (!m.contains("roughness")) {
      mat.roughness = base ? base->roughness : 0.0f;
      mat.roughness_v = base ? base->roughness_v : -1.0f;
      return;
    }
    const json& r = m["roughness"];
    if (r.is_array()) {
      if (mat.type != MaterialType::kConductor)
        fail(key_ptr, "\"roughness\" [u, v] in " + where +
                          ": anisotropic roughness is for conductors; give one number");
      if (r.size() != 2)
        fail(key_ptr, "\"roughness\" in " + where +
                          " must be a number or [u, v], not an array of " +
                          std::to_string(r.size()));
      mat.roughness = check(float(
          number(r[0], json_pointer_child(key_ptr, size_t(0)), "\"roughness\" u in " + where)));
      mat.roughness_v = check(float(
          number(r[1], json_pointer_child(key_ptr, size_t(1)), "\"roughness\" v in " + where)));
      return;
    }
    mat.roughness = check(get_float(m, ptr, "roughness", 0.0f, where));
    mat.roughness_v = -1.0f;
  }

  // A conductor's complex index of refraction: a named metal ("metal": "Au"), or "eta" and "k",
  // each a number or an RGB triple. "albedo" then tints the reflectance (default white).
  void read_complex_ior(const json& m, const std::string& ptr, const std::string& where,
                        const Material* base, Material& mat) const {
    mat.flags |= kMaterialConductorIor;
    auto colour = [&](const char* key, vec3 def) {
      if (m.contains(key) && m[key].is_number()) return vec3(get_float(m, ptr, key, 0.0f, where));
      return get_vec3(m, ptr, key, def, where);
    };
    if (m.contains("metal")) {
      if (m.contains("eta") || m.contains("k"))
        fail(json_pointer_child(ptr, "metal"),
             "give either \"metal\" or \"eta\" and \"k\" in " + where + ", not both");
      const std::string name = get_string(m, ptr, "metal", "", where);
      const NamedMetal* metal = find_metal(name);
      if (!metal) {
        const std::string guess = did_you_mean(name, metal_names());
        std::string list;
        for (const std::string& n : metal_names()) list += (list.empty() ? "" : ", ") + n;
        fail(json_pointer_child(ptr, "metal"),
             "unknown metal " + in_quotes(name) + " in " + where +
                 (guess.empty() ? " (known: " + list + ")"
                                : " (did you mean " + in_quotes(guess) + "?)"));
      }
      mat.eta = metal->eta;
      mat.k = metal->k;
      return;
    }
    const bool had = base && (base->flags & kMaterialConductorIor);
    if (!had && m.contains("eta") != m.contains("k")) {
      fail(json_pointer_child(ptr, m.contains("eta") ? "eta" : "k"),
           where + " gives \"" + (m.contains("eta") ? "eta" : "k") + "\" without \"" +
               (m.contains("eta") ? "k" : "eta") +
               "\": a conductor's complex index needs both (or a \"metal\")");
    }
    mat.eta = colour("eta", had ? base->eta : vec3(1.0f));
    mat.k = colour("k", had ? base->k : vec3(0.0f));
    if (!glm::all(glm::greaterThan(mat.eta, vec3(0.0f))))
      fail(json_pointer_child(ptr, "eta"), "\"eta\" in " + where + " must be > 0");
    if (glm::any(glm::lessThan(mat.k, vec3(0.0f))))
      fail(json_pointer_child(ptr, "k"), "\"k\" in " + where + " must be >= 0");
  }

  // A thin sheet's transmittance; with the reflectance (albedo) at most 1 per channel.
  void read_transmittance(const json& m, const std::string& ptr, const std::string& where,
                          const Material* base, Material& mat) const {
    const bool had = base && base->type == MaterialType::kDiffuseTransmission;
    mat.transmittance =
        get_vec3(m, ptr, "transmittance", had ? base->transmittance : vec3(0.5f), where);
    const std::string key_ptr = json_pointer_child(ptr, "transmittance");
    if (glm::any(glm::lessThan(mat.transmittance, vec3(0.0f))))
      fail(key_ptr, "\"transmittance\" in " + where + " must be >= 0");
    const float sum = max_component(mat.albedo + mat.transmittance);
    if (sum > 1.0f) {
      // More out than in: scale both down so that no channel exceeds 1.
      const vec3 a = mat.albedo / sum, t = mat.transmittance / sum;
      scene_.diagnostics.warn(
          at(m.contains("transmittance") ? key_ptr : ptr),
          "\"albedo\" + \"transmittance\" in " + where + " exceed 1 (" +
              vec3_str(mat.albedo + mat.transmittance) + ")",
          "scaled both down to albedo " + vec3_str(a) + ", transmittance " + vec3_str(t));
      mat.albedo = a;
      mat.transmittance = t;
    }
  }

  // A subsurface medium from either the physical coefficients ("scattering" and "absorption",
  // per unit length) or the artist's pair: the surface colour ("albedo", the multiple-scattering
  // albedo) and "mean_free_path" (per channel, in scene units), inverted with Kulla & Conty's fit.
  void read_medium(const json& m, const std::string& ptr, const std::string& where,
                   Material& mat) {
    mat.g = get_float(m, ptr, "g", 0.0f, where);
    if (!(mat.g > -1.0f && mat.g < 1.0f))
      fail(json_pointer_child(ptr, "g"), "\"g\" in " + where + " must be in (-1, 1)");
    const bool physical = m.contains("scattering");
    if (physical && m.contains("mean_free_path")) {
      fail(json_pointer_child(ptr, "mean_free_path"),
           "give either \"scattering\" + \"absorption\" or \"albedo\" + \"mean_free_path\" in " +
               where + ", not both");
    }
    if (physical) {
      mat.scattering = get_vec3(m, ptr, "scattering", vec3(0.0f), where);
      if (glm::any(glm::lessThan(mat.scattering, vec3(0.0f))))
        fail(json_pointer_child(ptr, "scattering"), "\"scattering\" in " + where + " must be >= 0");
    } else {
      vec3 mfp(1.0f);
      if (m.contains("mean_free_path") && m["mean_free_path"].is_number())
        mfp = vec3(get_float(m, ptr, "mean_free_path", 1.0f, where));
      else
        mfp = get_vec3(m, ptr, "mean_free_path", vec3(1.0f), where);
      if (!glm::all(glm::greaterThan(mfp, vec3(0.0f))))
        fail(json_pointer_child(ptr, "mean_free_path"),
             "\"mean_free_path\" in " + where + " must be > 0");
      vec3 single;
      for (int c = 0; c < 3; ++c) single[c] = albedo_from_surface_colour(mat.albedo[c]);
      const vec3 sigma_t = 1.0f / mfp;
      mat.scattering = single * sigma_t;
      mat.absorption = sigma_t - mat.scattering;
    }
    if (max_component(mat.scattering + mat.absorption) <= 0.0f)
      fail(ptr, where + " has neither scattering nor absorption; use a dielectric instead");
    mat.albedo = vec3(1.0f);  // the boundary transmits untinted; colour comes from the medium
  }

  void read_objects(const json& objs, const std::string& ptr) {
    if (!objs.is_array())
      fail(ptr, std::string("\"objects\" must be an array [...], not ") + json_type_name(objs));
    if (objs.empty()) fail(ptr, "the scene has no objects (\"objects\" is empty)");
    for (size_t i = 0; i < objs.size(); ++i) read_object(objs[i], json_pointer_child(ptr, i), i);
  }

  uint32_t object_material(const json& o, const std::string& ptr, const std::string& where,
                           bool required) const {
    if (!o.contains("material")) {
      if (required) fail(ptr, where + " has no \"material\"");
      return kInvalid;
    }
    const std::string name = get_string(o, ptr, "material", "", where);
    const uint32_t id = scene_.find_material(name);
    if (id != kInvalid) return id;
    std::vector<std::string> names;
    for (const NamedMaterial& m : scene_.materials) names.push_back(m.name);
    const std::string guess = did_you_mean(name, names);
    fail(json_pointer_child(ptr, "material"),
         "unknown material " + in_quotes(name) + " in " + where +
             (guess.empty() ? (names.empty() ? " (no materials are defined)"
                                             : " (defined: " + join(names) + ")")
                            : " (did you mean " + in_quotes(guess) + "?)"));
  }

  // "materials": {"NAME": VALUE} on a mesh object: the file's material NAME (the materials from
  // index `first` and `triangle_materials` from `first_triangle` on came from the file) is
  // replaced by the scene material VALUE names, or edited by VALUE's keys (a material definition
  // whose missing keys keep the file's values).
  void override_file_materials(const json& overrides, const std::string& ptr,
                               const std::string& where, const std::string& file, size_t first,
                               std::vector<uint32_t>& triangle_materials, size_t first_triangle) {
    require_object(overrides, ptr, "\"materials\" of " + where);
    std::vector<std::string> file_names;
    for (size_t i = first; i < scene_.materials.size(); ++i)
      file_names.push_back(scene_.materials[i].name);
    for (auto it = overrides.begin(); it != overrides.end(); ++it) {
      const std::string key_ptr = json_pointer_child(ptr, it.key());
      // add_material renames a file's "x" to "x#2" when the scene already has an "x".
      auto matches = [&](const std::string& name) {
        if (name == it.key()) return true;
        const std::string prefix = it.key() + "#";
        return name.compare(0, prefix.size(), prefix) == 0 && name.size() > prefix.size() &&
               name.find_first_not_of("0123456789", prefix.size()) == std::string::npos &&
               scene_.find_material(it.key()) < first;
      };
      size_t index = scene_.materials.size();
      for (size_t i = first; i < scene_.materials.size(); ++i)
        if (matches(scene_.materials[i].name)) index = i;
      if (index == scene_.materials.size()) {
        const std::string guess = did_you_mean(it.key(), file_names);
        fail(key_ptr, "mesh file " + in_quotes(file) + " of " + where + " has no material " +
                          in_quotes(it.key()) +
                          (!guess.empty() ? " (did you mean " + in_quotes(guess) + "?)"
                           : file_names.empty() ? " (it has no materials)"
                                                : " (its materials: " + join(file_names) + ")"));
      }
      if (it.value().is_string()) {
        const std::string name = it.value().get<std::string>();
        const uint32_t id = scene_.find_material(name);
        if (id == kInvalid || id >= first) {
          std::vector<std::string> names;
          for (size_t i = 0; i < first; ++i) names.push_back(scene_.materials[i].name);
          const std::string guess = did_you_mean(name, names);
          fail(key_ptr, "unknown material " + in_quotes(name) + " in " + where +
                            (guess.empty() ? " (give a material defined in \"materials\" or a "
                                             "definition {...})"
                                           : " (did you mean " + in_quotes(guess) + "?)"));
        }
        for (size_t t = first_triangle; t < triangle_materials.size(); ++t)
          if (triangle_materials[t] == index) triangle_materials[t] = id;
      } else {
        Material& target = scene_.materials[index].material;
        target = parse_material("material " + in_quotes(it.key()) + " of " + where, it.value(),
                                key_ptr, &target);
      }
    }
  }

  // scale -> rotate (X, then Y, then Z, degrees) -> translate, or a row-major "matrix".
  mat4 read_transform(const json& o, const std::string& obj_ptr, const std::string& where) const {
    if (!o.contains("transform")) return mat4(1.0f);
    return transform_value(o["transform"], json_pointer_child(obj_ptr, "transform"),
                           "\"transform\" of " + where);
  }

  // A transform's value, `t` at `ptr`; `w` names it in messages.
  mat4 transform_value(const json& t, const std::string& ptr, const std::string& w) const {
    require_object(t, ptr, w);
    check_keys(t, ptr, {"translate", "rotate", "scale", "matrix"}, w);
    if (t.contains("matrix")) {
      if (t.size() > 1)
        fail(ptr, w + ": \"matrix\" cannot be combined with translate/rotate/scale");
      const json& m = t["matrix"];
      const std::string mp = json_pointer_child(ptr, "matrix");
      if (!m.is_array() || m.size() != 16)
        fail(mp, "\"matrix\" in " + w + " must be an array of 16 numbers (row-major)");
      mat4 out;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
          out[c][r] = float(number(m[size_t(r * 4 + c)], json_pointer_child(mp, size_t(r * 4 + c)),
                                   "\"matrix\" in " + w));
      if (out[0][3] != 0.0f || out[1][3] != 0.0f || out[2][3] != 0.0f || out[3][3] != 1.0f)
        fail(mp, "\"matrix\" in " + w + " must be affine (last row 0, 0, 0, 1)");
      if (glm::determinant(mat3(out)) == 0.0f) fail(mp, "\"matrix\" in " + w + " is singular");
      return out;
    }
    vec3 scale(1.0f);
    if (t.contains("scale")) {
      const std::string sp = json_pointer_child(ptr, "scale");
      scale = t["scale"].is_number() ? vec3(float(number(t["scale"], sp, "\"scale\" in " + w)))
                                     : vec3_value(t["scale"], sp, "\"scale\" in " + w);
      if (scale.x == 0.0f || scale.y == 0.0f || scale.z == 0.0f)
        fail(sp, "\"scale\" in " + w + " must not be zero");
    }
    const vec3 rot = get_vec3(t, ptr, "rotate", vec3(0.0f), w);
    const vec3 tr = get_vec3(t, ptr, "translate", vec3(0.0f), w);
    mat4 m = glm::translate(mat4(1.0f), tr);
    m = glm::rotate(m, glm::radians(rot.z), vec3(0, 0, 1));
    m = glm::rotate(m, glm::radians(rot.y), vec3(0, 1, 0));
    m = glm::rotate(m, glm::radians(rot.x), vec3(1, 0, 0));
    return glm::scale(m, scale);
  }

  // "instances" of a mesh or terrain object: its placements, each world_from_object =
  // placement * the object's own `xform`. The value is an array whose items are transforms (the
  // syntax of "transform") or grids, or one grid: {"grid": [nx, ny, nz], "spacing": [sx, sy, sz]}
  // places nx * ny * nz copies translated by (i sx, j sy, k sz).
  std::vector<mat4> read_instances(const json& o, const std::string& obj_ptr,
                                   const std::string& where, const mat4& xform) const {
    const json& v = o["instances"];
    const std::string ptr = json_pointer_child(obj_ptr, "instances");
    const std::string w = "\"instances\" of " + where;
    if (!v.is_array() && !v.is_object())
      fail(ptr, w +
                    " must be an array of transforms or a grid {\"grid\": [nx, ny, nz], "
                    "\"spacing\": [sx, sy, sz]}, not " +
                    json_type_name(v));
    std::vector<mat4> out;
    auto add = [&](const mat4& placement, const std::string& at_ptr) {
      const mat4 m = placement * xform;
      const std::string problem = instance_transform_problem(m);
      if (!problem.empty())
        fail(at_ptr, "the placement of " + w + " (times the object's \"transform\") " + problem);
      out.push_back(m);
    };
    if (v.is_object()) {
      read_grid(v, ptr, w, add);
    } else {
      if (v.empty()) fail(ptr, w + " is empty (give at least one placement, or leave it out)");
      for (size_t i = 0; i < v.size(); ++i) {
        const std::string ip = json_pointer_child(ptr, i);
        const std::string iw = "instance " + std::to_string(i) + " of " + where;
        if (v[i].is_object() && v[i].contains("grid"))
          read_grid(v[i], ip, iw, add);
        else
          add(transform_value(v[i], ip, iw), ip);
        if (out.size() > kMaxInstances)
          fail(ip, w + " place more than " + std::to_string(kMaxInstances) + " instances");
      }
    }
    return out;
  }

  static constexpr size_t kMaxInstances = 10000000;

  template <typename Add>
  void read_grid(const json& g, const std::string& ptr, const std::string& w, Add&& add) const {
    check_keys(g, ptr, {"grid", "spacing"}, w);
    if (!g.contains("grid")) fail(ptr, w + " has no \"grid\" [nx, ny, nz]");
    if (!g.contains("spacing")) fail(ptr, w + " has no \"spacing\" [sx, sy, sz]");
    const json& n = g["grid"];
    const std::string np = json_pointer_child(ptr, "grid");
    if (!n.is_array() || n.size() != 3)
      fail(np, "\"grid\" of " + w + " must be an array of 3 counts [nx, ny, nz], not " +
                   (n.is_array() ? "one of " + std::to_string(n.size()) : json_type_name(n)));
    double count[3];
    for (int i = 0; i < 3; ++i) {
      count[i] = number(n[size_t(i)], json_pointer_child(np, size_t(i)), "\"grid\" of " + w);
      if (!(count[i] >= 1.0) || count[i] != std::floor(count[i]))
        fail(json_pointer_child(np, size_t(i)),
             "\"grid\" counts of " + w + " must be whole numbers >= 1");
    }
    const double total = count[0] * count[1] * count[2];
    if (total > double(kMaxInstances))
      fail(np, "\"grid\" of " + w + " places " + number_text(total) + " instances, more than " +
                   std::to_string(kMaxInstances));
    const vec3 spacing =
        vec3_value(g["spacing"], json_pointer_child(ptr, "spacing"), "\"spacing\" of " + w);
    for (int k = 0; k < int(count[2]); ++k)
      for (int j = 0; j < int(count[1]); ++j)
        for (int i = 0; i < int(count[0]); ++i)
          add(glm::translate(mat4(1.0f), vec3(float(i), float(j), float(k)) * spacing), ptr);
  }

  static std::string number_text(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f", x);
    return buf;
  }

  void read_object(const json& o, const std::string& ptr, size_t index) {
    require_object(o, ptr, "object " + std::to_string(index));
    if (!o.contains("type")) fail(ptr, "object " + std::to_string(index) + " has no \"type\"");
    const std::string type = get_string(o, ptr, "type", "", "object " + std::to_string(index));
    const std::vector<std::string> types = {"sphere", "box", "quad", "disk", "mesh", "terrain"};
    if (std::find(types.begin(), types.end(), type) == types.end()) {
      const std::string guess = did_you_mean(type, types);
      fail(json_pointer_child(ptr, "type"),
           "unknown object type " + in_quotes(type) +
               (guess.empty() ? " (expected sphere, box, quad, disk, mesh or terrain)"
                              : " (did you mean " + in_quotes(guess) + "?)"));
    }
    ObjectInfo info;
    info.kind = type;
    info.loc = at(ptr);
    info.name = type + " " + std::to_string(index);
    info.name = get_string(o, ptr, "name", info.name, "object " + in_quotes(info.name));
    const std::string where = "object " + in_quotes(info.name);
    const mat4 xform = read_transform(o, ptr, where);

    if (type == "sphere") {
      check_keys(o, ptr, {"type", "name", "center", "radius", "material", "transform"}, where);
      SphereDesc s;
      s.material = object_material(o, ptr, where, true);
      s.center = get_vec3(o, ptr, "center", vec3(0.0f), where);
      s.radius = get_float(o, ptr, "radius", 1.0f, where);
      if (!(s.radius > 0.0f))
        fail(json_pointer_child(ptr, "radius"), "\"radius\" of " + where + " must be > 0");
      // A sphere stays a sphere under rotation and uniform scale only.
      const mat3 m(xform);
      const float sx = glm::length(m[0]), sy = glm::length(m[1]), sz = glm::length(m[2]);
      const float tol = 1e-4f * std::max(sx, std::max(sy, sz));
      if (std::fabs(sx - sy) > tol || std::fabs(sx - sz) > tol ||
          std::fabs(glm::dot(m[0], m[1])) > tol * sx ||
          std::fabs(glm::dot(m[0], m[2])) > tol * sx ||
          std::fabs(glm::dot(m[1], m[2])) > tol * sx) {
        fail(json_pointer_child(ptr, "transform"),
             "the transform of " + where +
                 " scales non-uniformly or shears; a sphere allows only "
                 "translate, rotate and a uniform scale");
      }
      s.center = vec3(xform * vec4(s.center, 1.0f));
      s.radius *= sx;
      info.is_sphere = true;
      info.first = uint32_t(scene_.spheres.size());
      info.count = 1;
      scene_.spheres.push_back(s);
    } else if (type == "box") {
      check_keys(o, ptr, {"type", "name", "min", "max", "material", "transform"}, where);
      const uint32_t mat = object_material(o, ptr, where, true);
      const vec3 lo = get_vec3(o, ptr, "min", vec3(-0.5f), where);
      const vec3 hi = get_vec3(o, ptr, "max", vec3(0.5f), where);
      if (!glm::all(glm::lessThan(lo, hi)))
        fail(ptr, "\"min\" of " + where + " must be smaller than \"max\" in every coordinate");
      info.first = append_part(scene_, box_part(lo, hi, mat), xform);
      info.count = 12;
    } else if (type == "quad") {
      check_keys(o, ptr, {"type", "name", "corner", "edge1", "edge2", "material", "transform"},
                 where);
      const uint32_t mat = object_material(o, ptr, where, true);
      const vec3 c = get_vec3(o, ptr, "corner", vec3(0.0f), where);
      const vec3 e1 = get_vec3(o, ptr, "edge1", vec3(1, 0, 0), where);
      const vec3 e2 = get_vec3(o, ptr, "edge2", vec3(0, 1, 0), where);
      if (glm::length(glm::cross(e1, e2)) == 0.0f)
        fail(ptr, "\"edge1\" and \"edge2\" of " + where + " are zero or parallel");
      MeshPart q;
      // Counter-clockwise seen from the front, so the geometric normal is cross(edge1, edge2).
      q.positions = {c, c + e1, c + e1 + e2, c + e2};
      q.indices = {uvec3(0, 1, 2), uvec3(0, 2, 3)};
      q.materials = {mat, mat};
      info.first = append_part(scene_, q, xform);
      info.count = 2;
    } else if (type == "disk") {
      check_keys(o, ptr, {"type", "name", "center", "normal", "radius", "material", "transform"},
                 where);
      const uint32_t mat = object_material(o, ptr, where, true);
      const vec3 c = get_vec3(o, ptr, "center", vec3(0.0f), where);
      const vec3 n = get_vec3(o, ptr, "normal", vec3(0, 1, 0), where);
      const float r = get_float(o, ptr, "radius", 1.0f, where);
      if (!(r > 0.0f))
        fail(json_pointer_child(ptr, "radius"), "\"radius\" of " + where + " must be > 0");
      if (!(glm::dot(n, n) > 1e-30f) || !std::isfinite(glm::dot(n, n)))
        fail(json_pointer_child(ptr, "normal"),
             "\"normal\" of " + where + " must be a non-zero vector of moderate length");
      // pbrt's disk (a polygon of 96 segments, facing +z), turned so that +z is the normal and
      // moved to the centre: an emissive disk is sampled by area as its triangles.
      MeshPart d = pbrt_disk_mesh(0.0f, r, 0.0f, 360.0f);
      d.materials.assign(d.indices.size(), mat);
      const Frame f = Frame::from_normal(glm::normalize(n));
      mat4 place(1.0f);
      place[0] = vec4(f.t, 0.0f);
      place[1] = vec4(f.b, 0.0f);
      place[2] = vec4(f.n, 0.0f);
      place[3] = vec4(c, 1.0f);
      info.first = append_part(scene_, d, xform * place);
      info.count = uint32_t(d.indices.size());
    } else if (type == "terrain") {
      check_keys(o, ptr,
                 {"type", "name", "size", "resolution", "height", "seed", "material", "transform",
                  "instances"},
                 where);
      const uint32_t mat = object_material(o, ptr, where, true);
      const vec3 size = get_vec3(o, ptr, "size", vec3(10.0f, 0.0f, 10.0f), where);
      if (!(size.x > 0.0f) || !(size.z > 0.0f))
        fail(json_pointer_child(ptr, "size"),
             "\"size\" of " + where + " must be > 0 in x and z (its y is unused)");
      const double res = get_float(o, ptr, "resolution", 64.0f, where);
      // 8192^2 cells are 134 million triangles, about 10 GB as a flat mesh.
      if (!(res >= 1.0 && res <= 8192.0) || res != std::floor(res))
        fail(json_pointer_child(ptr, "resolution"),
             "\"resolution\" of " + where + " must be a whole number of cells per side, 1..8192");
      const float height = get_float(o, ptr, "height", 1.0f, where);
      const double seed = get_float(o, ptr, "seed", 1.0f, where);
      if (!(seed >= 0.0 && seed <= 65535.0) || seed != std::floor(seed))
        fail(json_pointer_child(ptr, "seed"),
             "\"seed\" of " + where + " must be a whole number, 0..65535");
      MeshPart t = terrain_mesh(vec2(size.x, size.z), uint32_t(res), height, uint32_t(seed));
      t.materials.assign(t.indices.size(), mat);
      if (o.contains("instances")) {
        const std::vector<mat4> placements = read_instances(o, ptr, where, xform);
        add_instanced_object(scene_, info, triangle_mesh_of(std::move(t)), placements);
        return;
      }
      info.first = append_part(scene_, t, xform);
      info.count = uint32_t(t.indices.size());
    } else {  // mesh
      check_keys(o, ptr,
                 {"type", "name", "file", "material", "materials", "transform", "instances"},
                 where);
      if (!o.contains("file")) fail(ptr, where + " has no \"file\"");
      const std::string file = get_string(o, ptr, "file", "", where);
      const uint32_t mat = object_material(o, ptr, where, false);
      if (o.contains("material") && o.contains("materials")) {
        fail(json_pointer_child(ptr, "materials"),
             where + " has both \"material\" (replaces all of the file's materials) and "
                     "\"materials\" (overrides some by name): give one");
      }
      const std::string full = path_join(path_directory(path_), file);
      const SourceLoc from = at(json_pointer_child(ptr, "file"));
      if (!file_exists(full))
        throw InputError(from, "mesh file " + in_quotes(file) + " of " + where +
                                   " not found (looked for " + in_quotes(full) + ")");
      const uint32_t before = uint32_t(scene_.mesh.indices.size());
      const size_t materials_before = scene_.materials.size();
      if (o.contains("instances")) {
        const std::vector<mat4> placements = read_instances(o, ptr, where, xform);
        TriangleMesh local = read_mesh_file_local(scene_, full, mat, from);
        if (o.contains("materials"))
          override_file_materials(o["materials"], json_pointer_child(ptr, "materials"), where, file,
                                  materials_before, local.materials, 0);
        add_instanced_object(scene_, info, std::move(local), placements);
        return;
      }
      append_mesh_file(scene_, full, xform, mat, from);
      if (o.contains("materials"))
        override_file_materials(o["materials"], json_pointer_child(ptr, "materials"), where, file,
                                materials_before, scene_.mesh.materials, before);
      info.first = before;
      info.count = uint32_t(scene_.mesh.indices.size()) - before;
    }
    scene_.objects.push_back(info);
  }

  // Four vertices per face so that faces do not share (and average) normals.
  static MeshPart box_part(vec3 lo, vec3 hi, uint32_t mat) {
    MeshPart b;
    const vec3 d = hi - lo;
    // Each face as corner + two edges with cross(e1, e2) pointing out of the box.
    const struct {
      vec3 corner, e1, e2;
    } faces[6] = {
        {lo, vec3(0, 0, d.z), vec3(0, d.y, 0)},                      // -x
        {vec3(hi.x, lo.y, lo.z), vec3(0, d.y, 0), vec3(0, 0, d.z)},  // +x
        {lo, vec3(d.x, 0, 0), vec3(0, 0, d.z)},                      // -y
        {vec3(lo.x, hi.y, lo.z), vec3(0, 0, d.z), vec3(d.x, 0, 0)},  // +y
        {lo, vec3(0, d.y, 0), vec3(d.x, 0, 0)},                      // -z
        {vec3(lo.x, lo.y, hi.z), vec3(d.x, 0, 0), vec3(0, d.y, 0)},  // +z
    };
    for (const auto& f : faces) {
      const uint32_t base = uint32_t(b.positions.size());
      b.positions.insert(b.positions.end(),
                         {f.corner, f.corner + f.e1, f.corner + f.e1 + f.e2, f.corner + f.e2});
      b.indices.push_back(uvec3(base, base + 1, base + 2));
      b.indices.push_back(uvec3(base, base + 2, base + 3));
      b.materials.insert(b.materials.end(), {mat, mat});
    }
    return b;
  }

  const JsonDocument& doc_;
  const std::string& path_;
  Scene& scene_;
};

}  // namespace

Scene load_scene_from_json(const std::string& text, const std::string& path) {
  Scene scene;
  scene.source = path;
  const JsonDocument doc = parse_json_with_lines(text, path);
  JsonSceneReader(doc, path, scene).read();
  validate_scene(scene);
  return scene;
}

Scene builtin_default_scene() {
  return load_scene_from_json(kBuiltinSceneJson, "<built-in>");
}

}  // namespace tracer
