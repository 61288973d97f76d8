// pbrt-v4 materials as the renderer's: diffuse, mirror, dielectric (smooth or GGX-rough),
// conductor (complex IOR or Schlick F0, anisotropic GGX), coated diffuse, diffuse transmission and
// subsurface; each pbrt type maps to the closest, and what is lost is said once per kind and
// file. Textures: pbrt_textures.cpp; lights: pbrt_lights.cpp.
#include "scene/pbrt_materials.h"

#include <algorithm>
#include <cmath>

#include "core/math.h"
#include "materials/subsurface.h"
#include "scene/loader_util.h"
#include "scene/pbrt_spectra.h"

namespace tracer {

namespace {

std::string quoted(const std::string& s) {
  return "\"" + s + "\"";
}

std::string fmt(float x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", double(x));
  return buf;
}

std::string rgb_str(vec3 v) {
  return "[" + fmt(v.x) + ", " + fmt(v.y) + ", " + fmt(v.z) + "]";
}

}  // namespace

PbrtMaterials::PbrtMaterials(Scene& scene, PbrtWarnings& warnings, std::string base_dir)
    : scene_(scene), warnings_(warnings), base_dir_(std::move(base_dir)) {}

void PbrtMaterials::substituted(const Ctx& c, const std::string& kind, const std::string& problem,
                                const std::string& action) {
  warnings_.warn(c.loc, kind, c.what + ": " + problem, action);
}

// ---- Materials ---------------------------------------------------------------------------------

int PbrtMaterials::material(const std::string& name, const std::string& type, PbrtParams& p,
                            const SourceLoc& loc) {
  if (!name.empty() && named_.count(name))
    throw InputError(loc, "material " + quoted(name) + " is defined twice");
  const Ctx c{loc, name.empty() ? "Material " + quoted(type) : "material " + quoted(name)};
  Mapped out;
  out.name = name.empty() ? type + " (line " + std::to_string(loc.line) + ")" : name;
  common(p, c);
  if (type == "diffuse") {
    out.m = diffuse(p, c);
  } else if (type == "coateddiffuse") {
    out.m = coated_diffuse(p, c);
  } else if (type == "conductor") {
    out.m = conductor(p, c, "");
  } else if (type == "coatedconductor") {
    out.m = coated_conductor(p, c);
  } else if (type == "dielectric") {
    out.m = dielectric(p, c);
  } else if (type == "thindielectric") {
    out.m = thin_dielectric(p, c);
  } else if (type == "diffusetransmission") {
    out.m = diffuse_transmission(p, c);
  } else if (type == "subsurface") {
    out.m = subsurface(p, c);
  } else if (type == "mix") {
    const int chosen = mix(p, c);
    out.m = chosen < 0 ? Material() : mapped_[size_t(chosen)].m;
    out.interface = chosen >= 0 && mapped_[size_t(chosen)].interface;
    if (chosen < 0) out.m.albedo = vec3(0.5f);
  } else if (type == "interface" || type == "none") {
    // A boundary of participating media with no surface: pbrt's rays pass straight through.
    out.interface = true;
    substituted(c, "interface", "\"interface\" bounds participating media, which are not supported",
                "skipped the shapes that use it");
  } else if (type == "measured" || type == "hair") {
    out.m = unsupported(type, p, c);
  } else {
    static const std::vector<std::string> kTypes = {"diffuse",
                                                    "coateddiffuse",
                                                    "conductor",
                                                    "coatedconductor",
                                                    "dielectric",
                                                    "thindielectric",
                                                    "diffusetransmission",
                                                    "subsurface",
                                                    "mix",
                                                    "interface",
                                                    "measured",
                                                    "hair"};
    const std::string guess = did_you_mean(type, kTypes);
    throw InputError(loc, "unknown material type " + quoted(type) +
                              (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
  }
  p.report_unused(warnings_);
  mapped_.push_back(out);
  const int id = int(mapped_.size() - 1);
  if (!name.empty()) named_[name] = id;
  return id;
}

int PbrtMaterials::named(const std::string& name, const SourceLoc& loc) const {
  const auto it = named_.find(name);
  if (it != named_.end()) return it->second;
  std::vector<std::string> names;
  for (const auto& [n, id] : named_) names.push_back(n);
  const std::string guess = did_you_mean(name, names);
  throw InputError(loc, "NamedMaterial " + quoted(name) + " is not defined" +
                            (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
}

// Parameters every material may have.
void PbrtMaterials::common(PbrtParams& p, const Ctx& c) {
  p.ignore({"type"});
  if (p.has("displacement")) {
    p.ignore({"displacement"});
    substituted(c, "displacement", "displacement textures are not supported", "ignored it");
  }
  if (p.has("normalmap")) {
    p.ignore({"normalmap"});
    substituted(c, "normalmap", "normal maps of pbrt materials are not supported", "ignored it");
  }
}

Material PbrtMaterials::diffuse(PbrtParams& p, const Ctx& c) {
  Material m;
  reflectance(p, "reflectance", vec3(0.5f), c, m);
  return m;
}

// pbrt's coateddiffuse: a dielectric interface (eta, roughness) over a diffuse base, with a
// medium of unit extinction between them, `thickness` thick (default 0.01), scattering a share
// `albedo` (default 0). Ours is the closed-form coated diffuse (bsdf.h): the same layers, the
// medium as Beer-Lambert absorption of 1 - albedo per unit length; pbrt's random walk (maxdepth,
// nsamples) is an estimator of the same layers, so its parameters are not needed.
Material PbrtMaterials::coated_diffuse(PbrtParams& p, const Ctx& c) {
  Material m;
  m.type = MaterialType::kCoatedDiffuse;
  reflectance(p, "reflectance", vec3(0.5f), c, m);
  m.roughness = roughness(p, c, "");
  m.ior = p.has("eta") ? eta(p, "eta", c) : 1.5f;
  m.thickness = std::max(p.get_float("thickness", 0.01f), 0.0f);
  vec3 albedo(0.0f);
  if (p.has("albedo")) {
    const Colour a = colour(p, "albedo", Use::kReflectance, c);
    albedo = glm::clamp(a.rgb, vec3(0.0f), vec3(1.0f));
    if (max_component(albedo) > 0.0f || a.image != kInvalid)
      substituted(c, "coateddiffuse albedo", "scattering inside the coat is not supported",
                  "the scattered share is dropped: absorption 1 - albedo per unit thickness");
  }
  m.absorption = vec3(1.0f) - albedo;
  p.ignore({"g", "maxdepth", "nsamples"});
  return m;
}

Material PbrtMaterials::conductor(PbrtParams& p, const Ctx& c, const std::string& prefix) {
  Material m;
  m.type = MaterialType::kConductor;
  m.roughness = roughness(p, c, prefix, &m.roughness_v);
  const Colour refl = colour(p, prefix + "reflectance", Use::kReflectance, c);
  if (refl.present) {
    // pbrt-v4's artist-friendly conductor: the reflectance is the colour at normal incidence.
    m.albedo = refl.rgb;
    m.base_color_tex = refl.image;
    p.ignore({(prefix + "eta").c_str(), (prefix + "k").c_str()});
    return m;
  }
  // The exact Fresnel equations of eta + i k (named spectra as the RGB fits of pbrt_spectra.h);
  // without eta and k, pbrt's default is copper.
  Colour eta = colour(p, prefix + "eta", Use::kIor, c);
  Colour k = colour(p, prefix + "k", Use::kIor, c);
  if (!eta.present) pbrt_named_metal("metal-Cu-eta", &eta.rgb);
  if (!k.present) pbrt_named_metal("metal-Cu-k", &k.rgb);
  m.flags |= kMaterialConductorIor;
  m.albedo = vec3(1.0f);
  m.eta = glm::max(eta.rgb, vec3(1e-3f));
  m.k = glm::max(k.rgb, vec3(0.0f));
  return m;
}

Material PbrtMaterials::coated_conductor(PbrtParams& p, const Ctx& c) {
  Material m = conductor(p, c, "conductor.");
  p.ignore({"interface.roughness", "interface.uroughness", "interface.vroughness", "interface.eta",
            "thickness", "albedo", "g", "maxdepth", "nsamples", "reflectance", "remaproughness"});
  substituted(c, "coatedconductor", "coatedconductor is not supported",
              "substituted its conductor layer (the dielectric coating is dropped)");
  return m;
}

Material PbrtMaterials::dielectric(PbrtParams& p, const Ctx& c) {
  Material m;
  m.type = MaterialType::kDielectric;
  m.albedo = vec3(1.0f);
  m.ior = eta(p, "eta", c);
  m.roughness = roughness(p, c, "");
  return m;
}

Material PbrtMaterials::thin_dielectric(PbrtParams& p, const Ctx& c) {
  Material m;
  m.type = MaterialType::kDielectric;
  m.albedo = vec3(1.0f);
  m.ior = eta(p, "eta", c);
  substituted(c, "thindielectric", "thindielectric (a thin sheet) is not supported",
              "substituted a solid dielectric with its eta");
  return m;
}

Material PbrtMaterials::diffuse_transmission(PbrtParams& p, const Ctx& c) {
  Material m;
  m.type = MaterialType::kDiffuseTransmission;
  reflectance(p, "reflectance", vec3(0.25f), c, m);
  const Colour t = colour(p, "transmittance", Use::kReflectance, c);
  if (t.image != kInvalid)
    substituted(c, "transmittance texture", "a textured transmittance is not supported",
                "used its factor " + rgb_str(t.rgb));
  const float scale = p.get_float("scale", 1.0f);
  m.albedo *= scale;
  m.transmittance = (t.present ? t.rgb : vec3(0.25f)) * scale;
  const float sum = max_component(m.albedo + m.transmittance);
  if (sum > 1.0f) {
    m.albedo /= sum;
    m.transmittance /= sum;
    substituted(c, "diffusetransmission energy", "reflectance + transmittance exceed 1",
                "scaled both down to reflectance " + rgb_str(m.albedo) + ", transmittance " +
                    rgb_str(m.transmittance));
  }
  return m;
}

Material PbrtMaterials::subsurface(PbrtParams& p, const Ctx& c) {
  Material m;
  m.type = MaterialType::kSubsurface;
  m.ior = eta(p, "eta", c);
  m.g = glm::clamp(p.get_float("g", 0.0f), -0.99f, 0.99f);
  const float scale = p.get_float("scale", 1.0f);
  const Colour refl = colour(p, "reflectance", Use::kReflectance, c);
  if (refl.present) {
    // The artist's pair, as the JSON format's albedo + mean_free_path.
    vec3 mfp(1.0f);
    if (const PbrtParam* q = p.find("mfp", {"rgb", "float"}))
      mfp = q->numbers.size() == 3 ? vec3(q->numbers[0], q->numbers[1], q->numbers[2])
                                   : vec3(float(q->numbers[0]));
    mfp = glm::max(mfp / std::max(scale, 1e-6f), vec3(1e-6f));
    vec3 single;
    for (int i = 0; i < 3; ++i) single[i] = albedo_from_surface_colour(refl.rgb[i]);
    m.scattering = single / mfp;
    m.absorption = 1.0f / mfp - m.scattering;
  } else {
    // pbrt-v4's defaults (in mm^-1, times "scale").
    vec3 sa(0.0011f, 0.0024f, 0.014f), ss(2.55f, 3.21f, 3.77f);
    if (const PbrtParam* q = p.find("sigma_a", {"rgb"}))
      sa = vec3(q->numbers[0], q->numbers[1], q->numbers[2]);
    if (const PbrtParam* q = p.find("sigma_s", {"rgb"}))
      ss = vec3(q->numbers[0], q->numbers[1], q->numbers[2]);
    m.absorption = sa * scale;
    m.scattering = ss * scale;
  }
  m.albedo = vec3(1.0f);
  p.ignore({"roughness", "uroughness", "vroughness", "remaproughness"});
  if (p.has("name")) {
    p.ignore({"name"});
    substituted(c, "subsurface name", "named measured media are not supported",
                "used pbrt's default coefficients");
  }
  substituted(c, "subsurface", "pbrt's tabulated BSSRDF is not supported",
              "substituted our random-walk subsurface material with the same coefficients");
  return m;
}

int PbrtMaterials::mix(PbrtParams& p, const Ctx& c) {
  const PbrtParam* list = p.find("materials", {"string"});
  if (!list || list->strings.size() != 2)
    throw InputError(c.loc, c.what + ": \"mix\" needs \"string materials\" with two names");
  float amount = 0.5f;
  if (const PbrtParam* a = p.find("amount", {"float", "texture"})) {
    if (a->type == "float")
      amount = float(a->numbers[0]);
    else
      substituted(c, "mix texture", "a textured mix amount is not supported", "used 0.5");
  }
  // pbrt-v4 picks the second material with probability "amount".
  const int first = named(list->strings[0], list->loc), second = named(list->strings[1], list->loc);
  const int chosen = amount > 0.5f ? second : first;
  substituted(c, "mix", "mixing materials is not supported",
              "used " + quoted(mapped_[size_t(chosen)].name) + ", the one of larger weight");
  return chosen;
}

Material PbrtMaterials::unsupported(const std::string& type, PbrtParams& p, const Ctx& c) {
  Material m;
  m.albedo = vec3(0.5f);
  for (const char* n : {"filename", "sigma_a", "color", "eumelanin", "pheomelanin", "eta", "beta_m",
                        "beta_n", "alpha"})
    p.ignore({n});
  substituted(c, type, quoted(type) + " materials are not supported", "substituted grey diffuse");
  return m;
}

// ---- Shared parameters -------------------------------------------------------------------------

PbrtMaterials::Colour PbrtMaterials::colour(PbrtParams& p, const std::string& name, Use use,
                                            const Ctx& c) {
  Colour out;
  const PbrtParam* q = use == Use::kReflectance
                           ? p.find(name, {"rgb", "spectrum", "float", "texture"})
                           : p.find(name, {"rgb", "spectrum", "float", "blackbody"});
  if (!q) return out;
  out.present = true;
  if (q->type == "rgb") {
    out.rgb = vec3(q->numbers[0], q->numbers[1], q->numbers[2]);
  } else if (q->type == "float") {
    out.rgb = vec3(float(q->numbers[0]));
  } else if (q->type == "texture") {
    out = texture_colour(q->strings[0], {q->loc, c.what});
  } else if (q->type == "blackbody") {
    if (use == Use::kEmission) {
      out.rgb = blackbody_rgb(float(q->numbers[0]));
    } else {
      substituted(c, "blackbody " + name,
                  "a blackbody spectrum as \"" + name + "\" is not supported", "used the default");
      out.present = false;
    }
  } else if (!q->strings.empty()) {  // a named spectrum or a spectrum file
    const std::string& s = q->strings[0];
    float glass = 0.0f;
    if (use == Use::kIor && pbrt_named_metal(s, &out.rgb)) {
      // the metals' RGB fits
    } else if (use == Use::kIor && pbrt_named_glass(s, &glass)) {
      out.rgb = vec3(glass);
      substituted(c, "named glass", "the dispersion of " + quoted(s) + " is not supported",
                  "used its index at 587.6 nm, " + fmt(glass));
    } else if (use == Use::kEmission &&
               (s == "stdillum-D65" || s == "stdillum-D50" || s == "stdillum-A")) {
      out.rgb =
          s == "stdillum-D65" ? vec3(1.0f) : blackbody_rgb(s == "stdillum-A" ? 2856.0f : 5003.0f);
    } else if (s.rfind("stdillum-", 0) == 0 && use == Use::kEmission) {
      out.rgb = vec3(1.0f);
      substituted(c, "stdillum", "the illuminant " + quoted(s) + " is not supported",
                  "used white of luminance 1");
    } else if (file_exists(path_join(base_dir_, s))) {
      substituted(c, "spectrum file", "spectrum files such as " + quoted(s) + " are not supported",
                  "used the default");
      out.present = false;
    } else {
      const std::string guess = did_you_mean(s, pbrt_spectrum_names());
      throw InputError(q->loc, c.what + ": " + q->decl() + ": unknown named spectrum " + quoted(s) +
                                   (guess.empty() ? " (and no such spectrum file)"
                                                  : " (did you mean " + quoted(guess) + "?)"));
    }
  } else {  // sampled (wavelength, value) pairs
    if (use == Use::kEmission) {
      out.rgb = emission_spectrum_rgb(q->numbers);
    } else if (use == Use::kReflectance) {
      out.rgb = reflectance_spectrum_rgb(q->numbers);
      substituted(c, "sampled reflectance", "a sampled reflectance spectrum",
                  "converted it to RGB under an equal-energy illuminant: " + rgb_str(out.rgb));
    } else {
      out.rgb = vec3(spectrum_at(q->numbers, 610.0f), spectrum_at(q->numbers, 550.0f),
                     spectrum_at(q->numbers, 465.0f));
      substituted(c, "sampled ior", "a sampled " + quoted(name) + " spectrum",
                  "used its values at 610, 550 and 465 nm: " + rgb_str(out.rgb));
    }
  }
  return out;
}

void PbrtMaterials::reflectance(PbrtParams& p, const char* name, vec3 def, const Ctx& c,
                                Material& m) {
  const Colour r = colour(p, name, Use::kReflectance, c);
  m.albedo = r.present ? r.rgb : def;
  m.base_color_tex = r.present ? r.image : kInvalid;
}

// pbrt's microfacet roughness: "uroughness"/"vroughness" (default "roughness", default 0), the
// Trowbridge-Reitz alpha directly, or through RoughnessToAlpha (sqrt in pbrt-v4) when
// "remaproughness" (default true). Ours is perceptual: alpha = roughness^2.
float PbrtMaterials::roughness(PbrtParams& p, const Ctx& c, const std::string& prefix,
                               float* roughness_v) {
  float r = 0.0f;
  if (const PbrtParam* q = p.find(prefix + "roughness", {"float", "texture"})) {
    if (q->type == "float")
      r = float(q->numbers[0]);
    else
      substituted(c, "roughness texture", "roughness textures are not supported", "used 0");
  }
  float u = r, v = r;
  for (const char* axis : {"uroughness", "vroughness"}) {
    if (const PbrtParam* q = p.find(prefix + axis, {"float", "texture"})) {
      const float x = q->type == "float" ? float(q->numbers[0]) : r;
      if (q->type != "float")
        substituted(c, "roughness texture", "roughness textures are not supported",
                    "used " + fmt(r));
      (axis[0] == 'u' ? u : v) = x;
    }
  }
  const bool remap = p.get_bool("remaproughness", true);
  float au = std::max(u, 0.0f), av = std::max(v, 0.0f);
  if (remap) au = std::sqrt(au), av = std::sqrt(av);
  const bool anisotropic = std::fabs(au - av) > 1e-6f * std::max(au, av);
  if (roughness_v) {  // a conductor: u along the tangent, v across (bsdf_frame's convention)
    *roughness_v = anisotropic ? glm::clamp(std::sqrt(av), 0.0f, 1.0f) : -1.0f;
    return glm::clamp(std::sqrt(au), 0.0f, 1.0f);
  }
  if (anisotropic)
    substituted(c, "anisotropic", "anisotropic roughness is supported by conductors only",
                "used the geometric mean of the two alphas");
  const float alpha = std::sqrt(au * av);
  return glm::clamp(std::sqrt(alpha), 0.0f, 1.0f);
}

float PbrtMaterials::eta(PbrtParams& p, const std::string& name, const Ctx& c) {
  const Colour e = colour(p, name, Use::kIor, c);
  float v = e.present ? e.rgb.y : 1.5f;
  if (e.present && (e.rgb.x != e.rgb.y || e.rgb.z != e.rgb.y))
    substituted(c, "eta rgb", "a coloured index of refraction", "used its green value " + fmt(v));
  if (v < 1.0f && v > 0.0f) {
    substituted(c, "eta < 1", "eta " + fmt(v) + " < 1 (the outside is the denser medium)",
                "used 1/eta = " + fmt(1.0f / v));
    v = 1.0f / v;
  }
  if (!(v > 1.0f) || v > 4.0f) {
    const float repaired = glm::clamp(v, 1.001f, 4.0f);
    substituted(c, "eta range", "eta " + fmt(v) + " is outside our dielectric's (1, 4]",
                "used " + fmt(repaired));
    v = repaired;
  }
  return v;
}

// ---- Scene materials ---------------------------------------------------------------------------

uint32_t PbrtMaterials::scene_material(int id, const PbrtAreaLight& area) {
  if (id >= 0 && mapped_[size_t(id)].interface) return kInvalid;
  if (!area.active) {
    if (id < 0) {
      if (default_material_ == kInvalid) {
        Material m;
        m.albedo = vec3(0.5f);
        default_material_ = scene_.add_material("default diffuse", m);
      }
      return default_material_;
    }
    Mapped& mp = mapped_[size_t(id)];
    if (mp.scene_index == kInvalid) mp.scene_index = scene_.add_material(mp.name, mp.m);
    return mp.scene_index;
  }
  const auto key =
      std::make_tuple(id, area.radiance.x, area.radiance.y, area.radiance.z, area.two_sided);
  const auto found = emissive_.find(key);
  if (found != emissive_.end()) return found->second;
  Material m;
  m.albedo = vec3(0.5f);
  if (id >= 0) m = mapped_[size_t(id)].m;
  m.emission = area.radiance;
  if (area.two_sided) m.flags |= kMaterialTwoSidedEmission;
  const std::string name =
      (id >= 0 ? mapped_[size_t(id)].name : std::string("default diffuse")) + " (area light)";
  const uint32_t index = scene_.add_material(name, m);
  emissive_[key] = index;
  return index;
}

}  // namespace tracer
