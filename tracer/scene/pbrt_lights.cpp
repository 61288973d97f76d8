// pbrt-v4 lights: diffuse area lights become emissive materials; the other light types are
// reported and skipped until the renderer has them (one function per type to connect).
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

// The renderer has area lights only for now; these are where point, spot, distant and
// environment lights will be connected.
void PbrtMaterials::light_point(PbrtParams& p, const mat4&, const SourceLoc& loc) {
  light_not_yet("point", p, loc);
}
void PbrtMaterials::light_spot(PbrtParams& p, const mat4&, const SourceLoc& loc) {
  light_not_yet("spot", p, loc);
}
void PbrtMaterials::light_distant(PbrtParams& p, const mat4&, const SourceLoc& loc) {
  light_not_yet("distant", p, loc);
}
void PbrtMaterials::light_infinite(PbrtParams& p, const mat4&, const SourceLoc& loc) {
  light_not_yet("infinite", p, loc);
}

void PbrtMaterials::light_not_yet(const std::string& type, PbrtParams&, const SourceLoc& loc) {
  warnings_.warn(loc, "LightSource " + type,
                 "LightSource " + quoted(type) + " is not supported yet", "skipped");
}

}  // namespace tracer
