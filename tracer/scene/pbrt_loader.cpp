// The pbrt-v4 scene reader: reads directives in order, keeping pbrt's graphics state (the current
// transform, material, area light and orientation, pushed by AttributeBegin), and appends each
// shape to the scene in our world (pbrt_world_to_ours). An object of triangles that emits nothing
// becomes one instanced mesh with an instance per ObjectInstance; other objects are flattened.
#include "scene/pbrt_loader.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <map>
#include <memory>

#include "core/math.h"
#include "scene/loader.h"
#include "scene/pbrt_materials.h"
#include "scene/pbrt_shapes.h"
#include "scene/ply_reader.h"

namespace tracer {

mat4 pbrt_world_to_ours(const mat4& camera_from_world) {
  return glm::determinant(mat3(camera_from_world)) > 0.0f
             ? glm::scale(mat4(1.0f), vec3(-1.0f, 1.0f, 1.0f))
             : mat4(1.0f);
}

namespace {

// More would not fit in memory anyway; instancing makes it easy to ask for.
constexpr size_t kMaxTriangles = 100000000;

std::string quoted(const std::string& s) {
  return "\"" + s + "\"";
}

std::string base_name(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

struct GraphicsState {
  mat4 ctm = mat4(1.0f);  // pbrt world (or camera, before WorldBegin) from object
  bool reverse = false;
  int material = -1;  // PbrtMaterials id; -1: pbrt's default diffuse
  PbrtAreaLight area;
};

// A Shape directive as read; inside ObjectBegin it is kept until instanced.
struct ShapeCall {
  std::string type;
  PbrtParams params;
  SourceLoc loc;
  GraphicsState gs;
};

// A shape in object space, built once however many instances place it.
struct BuiltShape {
  bool skip = false;
  std::string name;
  MeshPart part;
  bool full_sphere = false;  // an analytic sphere of `radius`, unless the transform forbids it
  float radius = 1.0f;
};

struct ObjectDef {
  SourceLoc loc;
  std::vector<ShapeCall> shapes;
  std::vector<std::shared_ptr<BuiltShape>> built;
  // Decided at the first ObjectInstance: kUndecided, kFlattened (a shape that is an analytic
  // sphere or emits), or the index of its mesh in Scene::instanced_meshes.
  static constexpr int kUndecided = -1, kFlattened = -2;
  int instanced = kUndecided;
  // The transform that the shapes share, which instances apply (the mesh is stored without it);
  // identity when the shapes' transforms differ (each is applied to its triangles).
  mat4 shared_ctm = mat4(1.0f);
};

class Loader {
 public:
  Loader(Scene& scene, const std::string& main_path)
      : scene_(scene),
        in_(main_path),
        base_dir_(path_directory(main_path)),
        materials_(scene, warnings_, base_dir_) {
    scene_.source = main_path;
    // pbrt-v4's defaults: a 1280x720 film, 16 samples, volpath with maxdepth 5, a Gaussian
    // filter of radius 1.5 (sigma 0.5).
    scene_.settings.filter = PixelFilter::kGaussian;
    scene_.settings.filter_radius = 1.5f;
    scene_.settings.width = 1280;
    scene_.settings.height = 720;
    scene_.settings.spp = 16;
    scene_.settings.max_depth = 5 + 1;
  }

  void run(std::string text) {
    in_.push(std::move(text), in_.main_path(), {in_.main_path(), 0});
    while (true) {
      const PbrtToken t = in_.next();
      if (t.kind == PbrtToken::kEnd) break;
      if (t.kind != PbrtToken::kWord)
        throw InputError(t.loc(), "expected a directive, found " + t.describe());
      const auto it = handlers().find(t.text);
      if (it == handlers().end()) {
        std::vector<std::string> names;
        for (const auto& [n, h] : handlers()) names.push_back(n);
        const std::string guess = did_you_mean(t.text, names);
        throw InputError(t.loc(),
                         "unknown directive " + quoted(t.text) +
                             (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
      }
      (this->*(it->second))(t);
    }
    if (!in_world_) finish_options({in_.main_path(), 0});
    for (const Saved& s : stack_) {
      warnings_.warn(s.loc, "unclosed block",
                     std::string(s.kind == 'A'   ? "AttributeBegin"
                                 : s.kind == 'T' ? "TransformBegin"
                                                 : "ObjectBegin") +
                         " has no matching End",
                     "closed it at the end of the file");
    }
    warnings_.flush(scene_.diagnostics);
  }

 private:
  using Handler = void (Loader::*)(const PbrtToken&);
  struct Saved {
    GraphicsState gs;
    char kind;  // 'A'ttribute, 'T'ransform, 'O'bject
    SourceLoc loc;
  };

  static const std::map<std::string, Handler>& handlers() {
    static const std::map<std::string, Handler> h = {
        {"AttributeBegin", &Loader::attribute_begin},
        {"AttributeEnd", &Loader::attribute_end},
        {"TransformBegin", &Loader::transform_begin},
        {"TransformEnd", &Loader::transform_end},
        {"Identity", &Loader::identity},
        {"Translate", &Loader::translate},
        {"Scale", &Loader::scale},
        {"Rotate", &Loader::rotate},
        {"LookAt", &Loader::look_at},
        {"Transform", &Loader::transform},
        {"ConcatTransform", &Loader::transform},
        {"CoordinateSystem", &Loader::coordinate_system},
        {"CoordSysTransform", &Loader::coord_sys_transform},
        {"ActiveTransform", &Loader::active_transform},
        {"TransformTimes", &Loader::transform_times},
        {"ReverseOrientation", &Loader::reverse_orientation},
        {"WorldBegin", &Loader::world_begin},
        {"WorldEnd", &Loader::world_end},
        {"Camera", &Loader::camera},
        {"Film", &Loader::film},
        {"Sampler", &Loader::sampler},
        {"Integrator", &Loader::integrator},
        {"PixelFilter", &Loader::pixel_filter},
        {"Accelerator", &Loader::ignored_option},
        {"ColorSpace", &Loader::color_space},
        {"Option", &Loader::option},
        {"MakeNamedMedium", &Loader::medium},
        {"MediumInterface", &Loader::medium_interface},
        {"Attribute", &Loader::attribute},
        {"Texture", &Loader::texture},
        {"Material", &Loader::material},
        {"MakeNamedMaterial", &Loader::make_named_material},
        {"NamedMaterial", &Loader::named_material},
        {"LightSource", &Loader::light_source},
        {"AreaLightSource", &Loader::area_light_source},
        {"Shape", &Loader::shape},
        {"ObjectBegin", &Loader::object_begin},
        {"ObjectEnd", &Loader::object_end},
        {"ObjectInstance", &Loader::object_instance},
        {"Include", &Loader::include},
        {"Import", &Loader::include},
    };
    return h;
  }

  // ---- Arguments ----

  std::string string_arg(const PbrtToken& d) {
    const PbrtToken t = in_.next();
    if (t.kind != PbrtToken::kString)
      throw InputError(t.kind == PbrtToken::kEnd ? d.loc() : t.loc(),
                       d.text + " needs a quoted string, found " + t.describe());
    return t.text;
  }

  // `n` numbers, in brackets or not (pbrt writes Transform's in brackets, LookAt's without).
  std::vector<float> numbers(const PbrtToken& d, size_t n) {
    std::vector<float> v;
    const bool bracket = in_.peek().kind == PbrtToken::kOpen;
    if (bracket) in_.next();
    const std::string context = "in " + d.text + " (line " + std::to_string(d.line) + ")";
    for (size_t i = 0; i < n; ++i) {
      const PbrtToken t = in_.next();
      if (t.kind != PbrtToken::kWord)
        throw InputError(t.kind == PbrtToken::kEnd ? d.loc() : t.loc(),
                         d.text + " takes " + std::to_string(n) + " numbers, found " +
                             t.describe() + " after " + std::to_string(i));
      v.push_back(float(pbrt_number(t, context)));
    }
    if (bracket) {
      const PbrtToken t = in_.next();
      if (t.kind != PbrtToken::kClose)
        throw InputError(t.loc(), d.text + " takes " + std::to_string(n) +
                                      " numbers; expected ']' after them, found " + t.describe());
    }
    return v;
  }

  PbrtParams params(const std::string& owner) { return parse_pbrt_params(in_, owner); }

  void require_world(const PbrtToken& d) {
    if (!in_world_) throw InputError(d.loc(), d.text + " is only allowed after WorldBegin");
  }
  void require_options(const PbrtToken& d) {
    if (in_world_) throw InputError(d.loc(), d.text + " is only allowed before WorldBegin");
  }

  // ---- Transforms ----

  void apply(const PbrtToken& d, const mat4& m, bool replace) {
    if (end_time_only_) {
      warnings_.warn(d.loc(), "motion", "transforms for ActiveTransform EndTime (motion blur)",
                     "ignored them; the shutter-open transform is used");
      return;
    }
    gs_.ctm = replace ? m : gs_.ctm * m;
  }

  void identity(const PbrtToken& d) { apply(d, mat4(1.0f), true); }
  void translate(const PbrtToken& d) {
    const std::vector<float> v = numbers(d, 3);
    apply(d, glm::translate(mat4(1.0f), vec3(v[0], v[1], v[2])), false);
  }
  void scale(const PbrtToken& d) {
    const std::vector<float> v = numbers(d, 3);
    apply(d, glm::scale(mat4(1.0f), vec3(v[0], v[1], v[2])), false);
  }
  void rotate(const PbrtToken& d) {
    const std::vector<float> v = numbers(d, 4);
    const vec3 axis(v[1], v[2], v[3]);
    if (!(glm::length(axis) > 0.0f)) throw InputError(d.loc(), "Rotate about a zero axis");
    apply(d, glm::rotate(mat4(1.0f), glm::radians(v[0]), glm::normalize(axis)), false);
  }
  void look_at(const PbrtToken& d) {
    const std::vector<float> v = numbers(d, 9);
    const vec3 eye(v[0], v[1], v[2]), at(v[3], v[4], v[5]), up(v[6], v[7], v[8]);
    // pbrt's LookAt (camera from world): x = up x dir, y = dir x x, z = dir.
    if (!(glm::length(at - eye) > 0.0f))
      throw InputError(d.loc(), "LookAt: the eye and the point looked at are the same");
    const vec3 dir = glm::normalize(at - eye);
    const vec3 r = glm::cross(glm::length(up) > 0.0f ? glm::normalize(up) : up, dir);
    if (!(glm::length(r) > 1e-6f))
      throw InputError(d.loc(), "LookAt: the up vector " + vec3_str(up) +
                                    " is parallel to the viewing direction (or zero)");
    const vec3 right = glm::normalize(r), new_up = glm::cross(dir, right);
    mat4 world_from_camera(1.0f);
    world_from_camera[0] = vec4(right, 0.0f);
    world_from_camera[1] = vec4(new_up, 0.0f);
    world_from_camera[2] = vec4(dir, 0.0f);
    world_from_camera[3] = vec4(eye, 1.0f);
    apply(d, glm::inverse(world_from_camera), false);
  }
  void transform(const PbrtToken& d) {
    // pbrt lists the matrix column by column (translation in the last four numbers), which is
    // GLM's order.
    const std::vector<float> v = numbers(d, 16);
    const mat4 m = glm::make_mat4(v.data());
    if (glm::determinant(m) == 0.0f)
      warnings_.warn(d.loc(), "singular", d.text + " matrix is singular",
                     "kept it (shapes under it collapse)");
    apply(d, m, d.text == "Transform");
  }
  void coordinate_system(const PbrtToken& d) { coord_systems_[string_arg(d)] = gs_.ctm; }
  void coord_sys_transform(const PbrtToken& d) {
    const std::string name = string_arg(d);
    const auto it = coord_systems_.find(name);
    if (it != coord_systems_.end()) {
      gs_.ctm = it->second;
      return;
    }
    std::vector<std::string> names;
    for (const auto& [n, m] : coord_systems_) names.push_back(n);
    const std::string guess = did_you_mean(name, names);
    warnings_.warn(d.loc(), "coordsys " + name,
                   "CoordSysTransform: no coordinate system " + quoted(name) +
                       (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"),
                   "ignored it");
  }
  void active_transform(const PbrtToken& d) {
    const PbrtToken t = in_.next();
    if (t.kind != PbrtToken::kWord ||
        (t.text != "All" && t.text != "StartTime" && t.text != "EndTime"))
      throw InputError(d.loc(),
                       "ActiveTransform takes All, StartTime or EndTime, not " + t.describe());
    end_time_only_ = t.text == "EndTime";
  }
  void transform_times(const PbrtToken& d) {
    numbers(d, 2);
    warnings_.warn(d.loc(), "motion", "motion blur (TransformTimes) is not supported",
                   "rendered the shutter-open transforms");
  }
  void reverse_orientation(const PbrtToken&) { gs_.reverse = !gs_.reverse; }

  // ---- Blocks ----

  void push(char kind, const PbrtToken& d) { stack_.push_back({gs_, kind, d.loc()}); }
  void pop(char kind, const PbrtToken& d) {
    const char* names[] = {"AttributeBegin", "TransformBegin", "ObjectBegin"};
    const char* want = names[kind == 'A' ? 0 : kind == 'T' ? 1 : 2];
    if (stack_.empty()) throw InputError(d.loc(), d.text + " without a matching " + want);
    const Saved& top = stack_.back();
    if (top.kind != kind) {
      const char* open = names[top.kind == 'A' ? 0 : top.kind == 'T' ? 1 : 2];
      throw InputError(d.loc(), d.text + " closes the " + open + " of line " +
                                    std::to_string(top.loc.line) + " (blocks must nest)");
    }
    if (kind == 'T')
      gs_.ctm = top.gs.ctm;
    else
      gs_ = top.gs;
    stack_.pop_back();
  }
  void attribute_begin(const PbrtToken& d) { push('A', d); }
  void attribute_end(const PbrtToken& d) { pop('A', d); }
  void transform_begin(const PbrtToken& d) { push('T', d); }
  void transform_end(const PbrtToken& d) { pop('T', d); }

  // ---- Options (before WorldBegin) ----

  void camera(const PbrtToken& d) {
    require_options(d);
    const std::string type = string_arg(d);
    PbrtParams p = params("Camera " + quoted(type));
    camera_loc_ = d.loc();
    camera_from_world_ = gs_.ctm;
    coord_systems_["camera"] = glm::inverse(gs_.ctm);
    if (type != "perspective") {
      static const std::vector<std::string> kTypes = {"perspective", "orthographic", "realistic",
                                                      "spherical"};
      bool known = false;
      for (const std::string& k : kTypes) known |= k == type;
      if (!known) {
        const std::string guess = did_you_mean(type, kTypes);
        throw InputError(d.loc(),
                         "unknown Camera " + quoted(type) +
                             (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
      }
      warnings_.warn(d.loc(), "camera " + type, "Camera " + quoted(type) + " is not supported",
                     "substituted a perspective camera with its fov (90 degrees if none)");
    }
    fov_ = p.get_float("fov", 90.0f);
    lens_radius_ = p.get_float("lensradius", 0.0f);
    focal_distance_ = p.get_float("focaldistance", 1e6f);
    frame_aspect_ = p.get_float("frameaspectratio", 0.0f);
    if (p.has("screenwindow")) {
      p.ignore({"screenwindow"});
      warnings_.warn(d.loc(), "screenwindow", "Camera \"screenwindow\" is not supported",
                     "used the full image");
    }
    p.ignore({"shutteropen", "shutterclose", "lensfile", "aperturediameter", "focusdistance",
              "mapping"});
    if (type == "perspective") p.report_unused(warnings_);
  }

  void film(const PbrtToken& d) {
    require_options(d);
    const std::string type = string_arg(d);
    PbrtParams p = params("Film " + quoted(type));
    scene_.settings.width = p.get_int("xresolution", 1280);
    scene_.settings.height = p.get_int("yresolution", 720);
    if (scene_.settings.width < 1 || scene_.settings.height < 1)
      throw InputError(d.loc(), "Film resolution " + std::to_string(scene_.settings.width) + "x" +
                                    std::to_string(scene_.settings.height) + " is not positive");
    const float max_value = p.get_float("maxcomponentvalue", 0.0f);
    if (max_value > 0.0f && std::isfinite(max_value)) scene_.settings.clamp = max_value;
    p.ignore({"filename", "diagonal", "savefp16", "writefp16", "coordinatesystem", "nbuckets",
              "lambdamin", "lambdamax"});
    for (const char* n :
         {"cropwindow", "pixelbounds", "iso", "whitebalance", "sensor", "exposuretime"}) {
      if (!p.has(n)) continue;
      p.ignore({n});
      warnings_.warn(d.loc(), std::string("film ") + n,
                     std::string("Film \"") + n + "\" is not supported", "ignored it");
    }
    if (type != "rgb" && type != "gbuffer" && type != "spectral")
      throw InputError(d.loc(), "unknown Film " + quoted(type) +
                                    " (expected \"rgb\", \"gbuffer\" or \"spectral\")");
    p.report_unused(warnings_);
  }

  void sampler(const PbrtToken& d) {
    require_options(d);
    const std::string type = string_arg(d);
    PbrtParams p = params("Sampler " + quoted(type));
    static const std::vector<std::string> kTypes = {
        "halton", "independent", "paddedsobol", "pmj02bn", "sobol", "stratified", "zsobol"};
    bool known = false;
    for (const std::string& k : kTypes) known |= k == type;
    if (!known) {
      const std::string guess = did_you_mean(type, kTypes);
      throw InputError(d.loc(),
                       "unknown Sampler " + quoted(type) +
                           (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
    }
    // Every sampler gives the same expected image; ours is the render.sampler setting.
    int64_t spp = p.get_int("pixelsamples", 16);
    if (type == "stratified") spp = int64_t(p.get_int("xsamples", 4)) * p.get_int("ysamples", 4);
    if (spp < 1 || spp > (int64_t(1) << 30))
      throw InputError(d.loc(),
                       "Sampler: " + std::to_string(spp) + " pixel samples (expected 1 to 2^30)");
    scene_.settings.spp = int(spp);
    const int seed = p.get_int("seed", -1);
    if (seed >= 0) scene_.settings.seed = uint32_t(seed);
    p.ignore({"jitter", "randomization"});
    p.report_unused(warnings_);
  }

  void integrator(const PbrtToken& d) {
    require_options(d);
    const std::string type = string_arg(d);
    PbrtParams p = params("Integrator " + quoted(type));
    static const std::vector<std::string> kTypes = {
        "path",          "volpath",          "bdpt", "mlt",        "sppm",
        "lightpath",     "ambientocclusion", "aov",  "randomwalk", "simplepath",
        "simplevolpath", "function"};
    bool known = false;
    for (const std::string& k : kTypes) known |= k == type;
    if (!known) {
      const std::string guess = did_you_mean(type, kTypes);
      throw InputError(d.loc(),
                       "unknown Integrator " + quoted(type) +
                           (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
    }
    // pbrt's maxdepth counts bounces: 0 shows emitters only, 1 direct light. Ours counts path
    // segments with the camera ray as the first: 1 shows emitters only, 2 direct light.
    const int maxdepth = p.get_int("maxdepth", 5);
    scene_.settings.max_depth = int(std::clamp<int64_t>(int64_t(maxdepth) + 1, 1, 1024));
    if (type == "path" || type == "volpath") {
      if (p.get_bool("regularize", false))
        warnings_.warn(d.loc(), "regularize", "path regularization is not supported",
                       "rendered without it");
      p.ignore({"lightsampler"});
      p.report_unused(warnings_);
    } else {
      warnings_.warn(d.loc(), "integrator " + type,
                     "Integrator " + quoted(type) + " is not supported",
                     "substituted our path tracer (next-event estimation with MIS) with maxdepth " +
                         std::to_string(maxdepth));
    }
  }

  void ignored_option(const PbrtToken& d) {
    require_options(d);
    string_arg(d);
    params(d.text);  // Accelerator: the BVH is ours; nothing to say.
  }

  // box, triangle and gaussian map onto render.filter (camera/filter.h) with their radius;
  // mitchell and lanczos become the Gaussian of the same radius, with a warning.
  void pixel_filter(const PbrtToken& d) {
    require_options(d);
    const std::string type = string_arg(d);
    PbrtParams p = params("PixelFilter " + quoted(type));
    const float def = type == "box" ? 0.5f : type == "triangle" ? 2.0f
                      : type == "gaussian" ? 1.5f : 2.0f;
    const float rx = p.get_float("xradius", def), ry = p.get_float("yradius", def);
    if (!(rx > 0.0f && ry > 0.0f && rx <= 8.0f && ry <= 8.0f))
      throw InputError(d.loc(), "PixelFilter " + quoted(type) + " radius " + std::to_string(rx) +
                                    " x " + std::to_string(ry) + " is outside (0, 8] pixels");
    if (rx != ry)
      warnings_.warn(d.loc(), "filter radii", "PixelFilter radii differ in x and y",
                     "used their mean for both");
    scene_.settings.filter_radius = 0.5f * (rx + ry);
    if (type == "box") {
      scene_.settings.filter = PixelFilter::kBox;
    } else if (type == "triangle") {
      scene_.settings.filter = PixelFilter::kTent;
    } else if (type == "gaussian") {
      scene_.settings.filter = PixelFilter::kGaussian;
      const float sigma = p.get_float("sigma", 0.5f);
      if (std::abs(sigma - scene_.settings.filter_radius / 3.0f) > 1e-3f)
        warnings_.warn(d.loc(), "gaussian sigma",
                       "a Gaussian filter's sigma other than its radius / 3 is not supported",
                       "used sigma = radius / 3");
    } else {
      scene_.settings.filter = PixelFilter::kGaussian;
      p.ignore({"B", "C", "tau"});
      warnings_.warn(d.loc(), "filter " + type,
                     "PixelFilter " + quoted(type) + " is not supported",
                     "substituted a Gaussian of the same radius");
    }
    p.report_unused(warnings_);
  }

  void color_space(const PbrtToken& d) {
    const std::string name = string_arg(d);
    if (name != "srgb")
      warnings_.warn(d.loc(), "colorspace", "ColorSpace " + quoted(name) + " is not supported",
                     "treated colours as linear sRGB");
  }

  void option(const PbrtToken& d) {
    const std::string name = string_arg(d);
    const PbrtToken v = in_.next();
    if (v.kind != PbrtToken::kWord && v.kind != PbrtToken::kString)
      throw InputError(d.loc(), "Option " + quoted(name) + " needs a value, found " + v.describe());
    warnings_.warn(d.loc(), "option " + name, "Option " + quoted(name) + " is not supported",
                   "ignored it");
  }

  void medium(const PbrtToken& d) {
    string_arg(d);
    params(d.text);
    warnings_.warn(d.loc(), "media", "participating media are not supported",
                   "skipped MakeNamedMedium and MediumInterface");
  }
  void medium_interface(const PbrtToken& d) {
    const std::string inside = string_arg(d);
    std::string outside = inside;
    if (in_.peek().kind == PbrtToken::kString) outside = in_.next().text;
    if (!inside.empty() || !outside.empty())
      warnings_.warn(d.loc(), "media", "participating media are not supported",
                     "skipped MakeNamedMedium and MediumInterface");
  }
  void attribute(const PbrtToken& d) {
    const std::string target = string_arg(d);
    params("Attribute " + quoted(target));
    warnings_.warn(d.loc(), "attribute",
                   "Attribute (default parameters for " + quoted(target) + ") is not supported",
                   "ignored it");
  }

  // ---- World ----

  void world_begin(const PbrtToken& d) {
    require_options(d);
    finish_options(d.loc());
    in_world_ = true;
    gs_.ctm = mat4(1.0f);
    coord_systems_["world"] = mat4(1.0f);
  }
  void world_end(const PbrtToken&) {}  // pbrt-v3's; nothing to do

  // The camera and handedness, once every option is known (Film may follow Camera).
  void finish_options(const SourceLoc& at) {
    (void)at;
    to_ours_ = pbrt_world_to_ours(camera_from_world_);
    const SourceLoc loc = camera_loc_.path.empty() ? SourceLoc{in_.main_path(), 0} : camera_loc_;
    if (std::fabs(glm::determinant(camera_from_world_)) < 1e-12f)
      throw InputError(loc, "the camera transform is singular");
    const mat4 world_from_camera = glm::inverse(camera_from_world_);
    const vec3 eye = vec3(world_from_camera * vec4(0, 0, 0, 1));
    const vec3 forward = mat3(world_from_camera) * vec3(0, 0, 1);
    const vec3 up = mat3(world_from_camera) * vec3(0, 1, 0);
    CameraDesc& cam = scene_.camera;
    cam.position = vec3(to_ours_ * vec4(eye, 1.0f));
    cam.look_at = vec3(to_ours_ * vec4(eye + glm::normalize(forward), 1.0f));
    cam.up = glm::normalize(mat3(to_ours_) * up);
    // fov spans the shorter image axis; ours is vertical.
    const float w = float(scene_.settings.width), h = float(scene_.settings.height);
    const float aspect = frame_aspect_ > 0.0f ? frame_aspect_ : w / h;
    if (frame_aspect_ > 0.0f && std::fabs(frame_aspect_ - w / h) > 1e-3f * w / h)
      warnings_.warn(loc, "frameaspectratio", "Camera \"frameaspectratio\" differs from the film's",
                     "used the film's aspect ratio");
    if (!(fov_ > 0.0f && fov_ < 180.0f))
      throw InputError(loc, "Camera fov " + std::to_string(fov_) + " is outside (0, 180) degrees");
    float vfov = fov_;
    if (aspect < 1.0f)
      vfov = glm::degrees(2.0f * std::atan(std::tan(glm::radians(0.5f * fov_)) / aspect));
    if (vfov < 1.0f || vfov > 179.0f)
      throw InputError(loc, "Camera fov " + std::to_string(fov_) +
                                " gives a vertical field of view of " + std::to_string(vfov) +
                                " degrees, outside [1, 179]");
    cam.vfov_deg = vfov;
    cam.aperture_radius = std::max(lens_radius_, 0.0f);
    // Our focus distance is along the view direction in world units, as pbrt's (in camera units).
    cam.focus_distance = cam.aperture_radius > 0.0f ? focal_distance_ * glm::length(forward) : 0.0f;
  }

  void texture(const PbrtToken& d) {
    require_world(d);
    const std::string name = string_arg(d), type = string_arg(d), cls = string_arg(d);
    PbrtParams p = params("Texture " + quoted(name));
    materials_.texture(name, type, cls, p, d.loc());
  }
  void material(const PbrtToken& d) {
    require_world(d);
    const std::string type = string_arg(d);
    PbrtParams p = params("Material " + quoted(type));
    gs_.material = materials_.material("", type, p, d.loc());
  }
  void make_named_material(const PbrtToken& d) {
    require_world(d);
    const std::string name = string_arg(d);
    PbrtParams p = params("material " + quoted(name));
    const std::string type = p.get_string("type", "");
    if (type.empty())
      throw InputError(d.loc(), "MakeNamedMaterial " + quoted(name) + " has no \"string type\"");
    materials_.material(name, type, p, d.loc());
  }
  void named_material(const PbrtToken& d) {
    require_world(d);
    gs_.material = materials_.named(string_arg(d), d.loc());
  }
  void light_source(const PbrtToken& d) {
    require_world(d);
    const std::string type = string_arg(d);
    PbrtParams p = params("LightSource " + quoted(type));
    materials_.light(type, p, to_ours_ * gs_.ctm, d.loc());
  }
  void area_light_source(const PbrtToken& d) {
    require_world(d);
    const std::string type = string_arg(d);
    PbrtParams p = params("AreaLightSource " + quoted(type));
    gs_.area = materials_.area_light(type, p, d.loc());
  }

  void shape(const PbrtToken& d) {
    require_world(d);
    ShapeCall call;
    call.type = string_arg(d);
    call.params = params("Shape " + quoted(call.type));
    call.loc = d.loc();
    call.gs = gs_;
    if (object_) {
      object_->shapes.push_back(std::move(call));
      object_->built.push_back(nullptr);
      return;
    }
    const std::shared_ptr<BuiltShape> built = build(call);
    emit(call, *built, call.gs.ctm, "");
  }

  void object_begin(const PbrtToken& d) {
    require_world(d);
    const std::string name = string_arg(d);
    if (object_)
      throw InputError(d.loc(), "ObjectBegin " + quoted(name) + " inside another ObjectBegin");
    if (objects_.count(name))
      throw InputError(d.loc(), "object " + quoted(name) + " is defined twice");
    push('O', d);
    object_ = &objects_[name];
    object_->loc = d.loc();
  }
  void object_end(const PbrtToken& d) {
    require_world(d);
    if (!object_) throw InputError(d.loc(), "ObjectEnd without a matching ObjectBegin");
    pop('O', d);
    object_ = nullptr;
  }
  void object_instance(const PbrtToken& d) {
    require_world(d);
    const std::string name = string_arg(d);
    if (object_)
      throw InputError(d.loc(), "ObjectInstance inside ObjectBegin (instances do not nest)");
    const auto it = objects_.find(name);
    if (it == objects_.end()) {
      std::vector<std::string> names;
      for (const auto& [n, o] : objects_) names.push_back(n);
      const std::string guess = did_you_mean(name, names);
      throw InputError(d.loc(),
                       "ObjectInstance: no object " + quoted(name) +
                           (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
    }
    ObjectDef& obj = it->second;
    const int n = ++instance_counts_[name];
    for (size_t i = 0; i < obj.shapes.size(); ++i)
      if (!obj.built[i]) obj.built[i] = build(obj.shapes[i]);
    if (obj.instanced == ObjectDef::kUndecided) obj.instanced = make_instanced_mesh(name, obj);
    if (obj.instanced >= 0) {
      // As emit's transform for a shape, to_ours_ * gs_.ctm * shape ctm, with the shape's part
      // (the shared ctm) left to the instance.
      const mat4 m = to_ours_ * gs_.ctm * obj.shared_ctm;
      if (instance_transform_problem(m).empty()) {
        const uint64_t tris = scene_.instanced_meshes[size_t(obj.instanced)].mesh.indices.size();
        instanced_triangles_ += tris;
        if (instanced_triangles_ + scene_.mesh.indices.size() >= (uint64_t(1) << 31))
          throw InputError(d.loc(), "the instances place more than 2^31 triangles in all (" +
                                        std::to_string(instanced_triangles_) + ")");
        ObjectInfo info;
        info.name = name + " #" + std::to_string(n);
        info.kind = "instances";
        info.is_instances = true;
        info.first = uint32_t(scene_.instances.size());
        info.count = 1;
        info.loc = d.loc();
        scene_.instances.push_back({uint32_t(obj.instanced), m});
        scene_.objects.push_back(info);
        return;
      }
      // A singular or non-finite placement: flattened, as before instancing, so that its
      // triangles are dropped as degenerate with the usual warning rather than failing the load.
    }
    for (size_t i = 0; i < obj.shapes.size(); ++i)
      emit(obj.shapes[i], *obj.built[i], gs_.ctm * obj.shapes[i].gs.ctm,
           " [" + name + " #" + std::to_string(n) + "]");
  }

  // The object's shapes as one instanced mesh (its index), or kFlattened when a shape is an
  // analytic sphere or emits light (emitters must be world-space triangles) or there is nothing to
  // instance. Each shape's triangles are placed by its transform relative to the shared one,
  // exactly as emit places them (append_part: normals by the inverse transpose, winding flipped
  // under a mirroring transform), so that flattening the instances gives emit's triangles.
  int make_instanced_mesh(const std::string& name, ObjectDef& obj) {
    std::vector<uint32_t> materials(obj.shapes.size(), kInvalid);
    bool same_ctm = true;
    size_t triangles = 0;
    for (size_t i = 0; i < obj.shapes.size(); ++i) {
      const BuiltShape& b = *obj.built[i];
      if (b.skip) continue;
      if (b.full_sphere) return ObjectDef::kFlattened;
      const ShapeCall& call = obj.shapes[i];
      materials[i] = materials_.scene_material(call.gs.material, call.gs.area);
      if (materials[i] == kInvalid) continue;  // an interface: emit skips it too
      if (scene_.materials[materials[i]].material.is_emissive()) return ObjectDef::kFlattened;
      same_ctm &= call.gs.ctm == obj.shapes[0].gs.ctm;
      triangles += b.part.indices.size();
    }
    if (triangles == 0) return ObjectDef::kFlattened;
    obj.shared_ctm = same_ctm ? obj.shapes[0].gs.ctm : mat4(1.0f);
    Scene local;
    for (size_t i = 0; i < obj.shapes.size(); ++i) {
      if (materials[i] == kInvalid || obj.built[i]->skip) continue;
      MeshPart part = obj.built[i]->part;
      part.materials.assign(part.indices.size(), materials[i]);
      append_part(local, part, same_ctm ? mat4(1.0f) : obj.shapes[i].gs.ctm);
    }
    scene_.instanced_meshes.push_back({name, std::move(local.mesh)});
    return int(scene_.instanced_meshes.size() - 1);
  }

  void include(const PbrtToken& d) {
    const std::string file = string_arg(d);
    // pbrt resolves relative names against the main file's folder, also inside included files.
    const std::string path = path_join(base_dir_, file);
    if (path_extension_lower(path) == ".gz")
      throw InputError(d.loc(), d.text + " " + quoted(file) +
                                    ": compressed scene files are not supported (gunzip it)");
    in_.push(read_file_text(path, d.loc()), path, d.loc());
  }

  // ---- Shapes ----

  std::shared_ptr<BuiltShape> build(ShapeCall& call) {
    auto b = std::make_shared<BuiltShape>();
    PbrtParams& p = call.params;
    const SourceLoc& loc = call.loc;
    const std::string& type = call.type;
    const bool here = loc.path == in_.main_path();
    b->name = type + " (" + (here ? "" : base_name(loc.path) + ":") + "line " +
              std::to_string(loc.line) + ")";
    if (const PbrtParam* a = p.find("alpha", {"float", "texture"})) {
      if (a->type == "float" && a->numbers[0] <= 0.0) {
        warnings_.warn(loc, "alpha 0", "a shape with alpha 0 is invisible in pbrt", "skipped it");
        b->skip = true;
        p.report_unused(warnings_);
        return b;
      }
      warnings_.warn(loc, "alpha", "alpha cut-outs are not supported", "rendered the shape opaque");
    }
    if (type == "trianglemesh") {
      b->part = pbrt_trianglemesh(p, loc, warnings_);
    } else if (type == "plymesh") {
      const std::string file = p.get_string("filename", "");
      if (file.empty()) throw InputError(loc, "Shape \"plymesh\" needs \"string filename\"");
      b->name = base_name(file);
      const std::string path = path_join(base_dir_, file);
      std::shared_ptr<PlyMesh>& ply = ply_cache_[path];
      if (!ply)
        ply = std::make_shared<PlyMesh>(read_ply(path, loc, " (plymesh at " + loc.str() + ")"));
      if (ply->skipped_faces > 0)
        warnings_.warn(loc, "ply faces",
                       quoted(file) + " has " + std::to_string(ply->skipped_faces) +
                           " faces with fewer than 3 corners",
                       "skipped them");
      b->part = ply->part;
      if (p.has("displacement")) {
        p.ignore({"displacement", "edgelength"});
        warnings_.warn(loc, "displacement", "plymesh displacement is not supported",
                       "rendered the mesh undisplaced");
      }
      p.ignore({"edgelength"});
    } else if (type == "sphere") {
      const float r = p.get_float("radius", 1.0f);
      const float zmin = p.get_float("zmin", -r), zmax = p.get_float("zmax", r);
      const float phimax = p.get_float("phimax", 360.0f);
      if (!(r > 0.0f))
        throw InputError(loc, "Shape \"sphere\": radius " + std::to_string(r) + " is not positive");
      b->full_sphere = std::min(zmin, zmax) <= -r && std::max(zmin, zmax) >= r && phimax >= 360.0f;
      b->radius = r;
      b->part = pbrt_sphere_mesh(r, zmin, zmax, phimax);
    } else if (type == "disk") {
      b->part = pbrt_disk_mesh(p.get_float("height", 0.0f), p.get_float("radius", 1.0f),
                               p.get_float("innerradius", 0.0f), p.get_float("phimax", 360.0f));
    } else if (type == "cylinder") {
      b->part = pbrt_cylinder_mesh(p.get_float("radius", 1.0f), p.get_float("zmin", -1.0f),
                                   p.get_float("zmax", 1.0f), p.get_float("phimax", 360.0f));
    } else if (type == "bilinearmesh") {
      b->part = pbrt_bilinearmesh(p, loc, warnings_);
      p.ignore({"emissionfilename"});
    } else if (type == "loopsubdiv") {
      b->part = pbrt_loopsubdiv(p, loc, warnings_);
      warnings_.warn(loc, "loopsubdiv", "Loop subdivision is not supported",
                     "rendered the control mesh");
    } else if (type == "curve") {
      b->skip = true;
      p.ignore({"P", "basis", "degree", "type", "N", "width", "width0", "width1", "splitdepth"});
      warnings_.warn(loc, "curve", "Shape \"curve\" (hair and fur) is not supported", "skipped it");
    } else {
      static const std::vector<std::string> kTypes = {"trianglemesh", "plymesh",  "sphere",
                                                      "disk",         "cylinder", "bilinearmesh",
                                                      "loopsubdiv",   "curve"};
      const std::string guess = did_you_mean(type, kTypes);
      throw InputError(loc, "unknown Shape " + quoted(type) +
                                (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
    }
    p.report_unused(warnings_);
    pbrt_orient(b->part, call.gs.reverse);
    return b;
  }

  // Places a built shape under `world_from_object` (pbrt world); `suffix` names the instance.
  void emit(const ShapeCall& call, const BuiltShape& b, const mat4& world_from_object,
            const std::string& suffix) {
    if (b.skip) return;
    const uint32_t material = materials_.scene_material(call.gs.material, call.gs.area);
    if (material == kInvalid) return;  // "interface": a media boundary, warned where defined
    const mat4 m = to_ours_ * world_from_object;
    ObjectInfo info;
    info.name = b.name + suffix;
    info.loc = call.loc;
    // An analytic sphere needs a similarity transform and pbrt's outward orientation.
    if (b.full_sphere && !call.gs.reverse) {
      const mat3 a(m);
      const float s = glm::length(a[0]);
      const mat3 ata = glm::transpose(a) * a;
      bool similar = s > 0.0f;
      for (int i = 0; i < 3 && similar; ++i)
        for (int j = 0; j < 3; ++j)
          similar &= std::fabs(ata[i][j] - (i == j ? s * s : 0.0f)) <= 1e-4f * s * s;
      if (similar) {
        SphereDesc sphere;
        sphere.center = vec3(m * vec4(0, 0, 0, 1));
        sphere.radius = b.radius * s;
        sphere.material = material;
        info.kind = "sphere";
        info.is_sphere = true;
        info.first = uint32_t(scene_.spheres.size());
        info.count = 1;
        scene_.spheres.push_back(sphere);
        scene_.objects.push_back(info);
        return;
      }
      warnings_.warn(call.loc, "sphere shear", "a sphere under a non-uniform scale or shear",
                     "tessellated it into " + std::to_string(b.part.indices.size()) + " triangles");
    }
    if (b.part.indices.empty()) return;
    if (scene_.mesh.indices.size() + b.part.indices.size() > kMaxTriangles)
      throw InputError(call.loc, "the scene would have more than " + std::to_string(kMaxTriangles) +
                                     " triangles (instances that are flattened count)");
    MeshPart part = b.part;
    part.materials.assign(part.indices.size(), material);
    info.kind = "mesh";
    info.first = append_part(scene_, part, m);
    info.count = uint32_t(part.indices.size());
    scene_.objects.push_back(info);
  }

  Scene& scene_;
  PbrtWarnings warnings_;
  PbrtInput in_;
  std::string base_dir_;
  PbrtMaterials materials_;
  GraphicsState gs_;
  std::vector<Saved> stack_;
  std::map<std::string, mat4> coord_systems_;
  std::map<std::string, ObjectDef> objects_;
  std::map<std::string, int> instance_counts_;
  uint64_t instanced_triangles_ = 0;
  ObjectDef* object_ = nullptr;
  std::map<std::string, std::shared_ptr<PlyMesh>> ply_cache_;
  bool in_world_ = false;
  bool end_time_only_ = false;
  mat4 to_ours_ = mat4(1.0f);
  // Camera options.
  SourceLoc camera_loc_;
  mat4 camera_from_world_ = mat4(1.0f);
  float fov_ = 90.0f, lens_radius_ = 0.0f, focal_distance_ = 1e6f, frame_aspect_ = 0.0f;
};

}  // namespace

Scene load_pbrt_string(const std::string& text, const std::string& path) {
  Scene scene;
  Loader loader(scene, path);
  loader.run(text);
  validate_scene(scene);
  return scene;
}

Scene load_pbrt_scene(const std::string& path) {
  return load_pbrt_string(read_file_text(path, {path, 0}), path);
}

}  // namespace tracer
