// pbrt-v4 materials, textures and lights mapped onto the renderer's: one function per pbrt
// construct, each naming what it substituted in one warning per kind and file. When the renderer
// gains a feature (an environment light, a thin dielectric), the function of that construct is
// the one place to change.
#pragma once

#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "scene/pbrt_params.h"
#include "scene/scene.h"

namespace tracer {

// The emission an AreaLightSource gives the shapes after it in its attribute block.
struct PbrtAreaLight {
  bool active = false;
  vec3 radiance = vec3(0.0f);  // L x scale, linear sRGB
  bool two_sided = false;
};

class PbrtMaterials {
 public:
  // `base_dir`: the folder relative file names (image textures) are resolved in.
  PbrtMaterials(Scene& scene, PbrtWarnings& warnings, std::string base_dir);

  // Texture "name" "spectrum"|"float" "class" ...: image maps are loaded, checkerboards baked
  // into small images, constants kept as factors.
  void texture(const std::string& name, const std::string& type, const std::string& cls,
               PbrtParams& params, const SourceLoc& loc);
  // MakeNamedMaterial (name non-empty) or Material: maps the material; returns its id.
  int material(const std::string& name, const std::string& type, PbrtParams& params,
               const SourceLoc& loc);
  // The id of a named material (NamedMaterial); an undefined name throws InputError.
  int named(const std::string& name, const SourceLoc& loc) const;
  PbrtAreaLight area_light(const std::string& type, PbrtParams& params, const SourceLoc& loc);
  // LightSource: `world` places it (our world from the light's object space).
  void light(const std::string& type, PbrtParams& params, const mat4& world, const SourceLoc& loc);

  // The scene material for shapes with material `id` (-1: pbrt's default, diffuse 0.5) under
  // `area`; kInvalid for "interface", whose shapes only bound participating media (skipped).
  uint32_t scene_material(int id, const PbrtAreaLight& area);

 private:
  struct Mapped {
    std::string name;  // for the scene's material list
    Material m;
    bool interface = false;
    uint32_t scene_index = kInvalid;
  };
  struct Ctx {
    SourceLoc loc;
    std::string what;  // material "Glass" / Material "diffuse", for messages
  };
  // A colour parameter's value: a constant, or a texture's image times a factor.
  struct Colour {
    bool present = false;
    vec3 rgb = vec3(1.0f);
    uint32_t image = kInvalid;
  };
  enum class Use { kReflectance, kEmission, kIor };

  // One function per pbrt material type.
  Material diffuse(PbrtParams& p, const Ctx& c);
  Material coated_diffuse(PbrtParams& p, const Ctx& c);
  Material conductor(PbrtParams& p, const Ctx& c, const std::string& prefix);
  Material coated_conductor(PbrtParams& p, const Ctx& c);
  Material dielectric(PbrtParams& p, const Ctx& c);
  Material thin_dielectric(PbrtParams& p, const Ctx& c);
  Material diffuse_transmission(PbrtParams& p, const Ctx& c);
  Material subsurface(PbrtParams& p, const Ctx& c);
  int mix(PbrtParams& p, const Ctx& c);
  Material unsupported(const std::string& type, PbrtParams& p, const Ctx& c);

  // One function per light type (pbrt_lights.cpp); light_not_yet for those not supported.
  void light_point(PbrtParams& p, const mat4& world, const SourceLoc& loc);
  void light_spot(PbrtParams& p, const mat4& world, const SourceLoc& loc);
  void point_or_spot(PbrtParams& p, const mat4& world, const SourceLoc& loc, bool spot);
  void light_distant(PbrtParams& p, const mat4& world, const SourceLoc& loc);
  void light_infinite(PbrtParams& p, const mat4& world, const SourceLoc& loc);
  void light_not_yet(const std::string& type, PbrtParams& p, const SourceLoc& loc);

  // Parameters shared by the material types.
  Colour colour(PbrtParams& p, const std::string& name, Use use, const Ctx& c);
  void reflectance(PbrtParams& p, const char* name, vec3 def, const Ctx& c, Material& m);
  // Our perceptual roughness; with `roughness_v` (conductors) u and v apart (v < 0: isotropic),
  // else their geometric mean.
  float roughness(PbrtParams& p, const Ctx& c, const std::string& prefix,
                  float* roughness_v = nullptr);
  float eta(PbrtParams& p, const std::string& name, const Ctx& c);
  void common(PbrtParams& p, const Ctx& c);

  // Textures.
  Colour texture_colour(const std::string& name, const Ctx& c);
  uint32_t load_image(const std::string& file, bool srgb, TextureWrap wrap, const SourceLoc& loc);
  uint32_t bake_checkerboard(PbrtParams& p, const SourceLoc& loc);

  void substituted(const Ctx& c, const std::string& kind, const std::string& problem,
                   const std::string& action);

  Scene& scene_;
  PbrtWarnings& warnings_;
  std::string base_dir_;
  std::vector<Mapped> mapped_;
  std::map<std::string, int> named_;
  struct Tex {
    std::string type, cls;
    SourceLoc loc;
    Colour colour;
  };
  std::map<std::string, Tex> textures_;
  std::map<std::tuple<std::string, bool, int>, uint32_t> images_;
  std::map<std::tuple<int, float, float, float, bool>, uint32_t> emissive_;
  uint32_t default_material_ = kInvalid;
  SourceLoc env_loc_;  // the infinite light that set the environment map
};

}  // namespace tracer
