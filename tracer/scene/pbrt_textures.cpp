// pbrt-v4 textures: image maps decoded into the scene's texture list as the OBJ and glTF maps
// are, checkerboards baked into small images, constants and scales kept as colour factors.

#include <cmath>

#include "image/image.h"
#include "scene/loader_util.h"
#include "scene/pbrt_materials.h"

namespace tracer {

namespace {

std::string quoted(const std::string& s) {
  return "\"" + s + "\"";
}

}  // namespace

// ---- Textures ----------------------------------------------------------------------------------

void PbrtMaterials::texture(const std::string& name, const std::string& type,
                            const std::string& cls, PbrtParams& p, const SourceLoc& loc) {
  if (type != "spectrum" && type != "float")
    throw InputError(loc, "Texture " + quoted(name) + ": unknown texture type " + quoted(type) +
                              " (expected \"spectrum\" or \"float\")");
  if (textures_.count(name) && textures_[name].type == type)
    warnings_.warn(loc, "texture redefined", "Texture " + quoted(name) + " is defined again",
                   "the new definition replaces the old one");
  Tex t;
  t.type = type;
  t.cls = cls;
  t.loc = loc;
  const Ctx c{loc, "Texture " + quoted(name)};
  if (type == "float") {
    // Float textures drive roughness, alpha, bump and mix amounts, none of which can be textured
    // here: they are reported where a material uses them.
    textures_[name] = t;
    return;
  }
  if (cls == "imagemap") {
    const std::string file = p.get_string("filename", "");
    if (file.empty())
      throw InputError(loc, "Texture " + quoted(name) + ": imagemap needs \"string filename\"");
    const std::string encoding = p.get_string("encoding", "sRGB");
    bool srgb = true;
    if (encoding == "linear") {
      srgb = false;
    } else if (encoding.rfind("gamma", 0) == 0) {
      substituted(c, "gamma encoding", "the encoding " + quoted(encoding) + " is not supported",
                  "decoded the image as sRGB");
    } else if (encoding != "sRGB") {
      throw InputError(loc, "Texture " + quoted(name) + ": unknown encoding " + quoted(encoding) +
                                " (expected \"sRGB\", \"linear\" or \"gamma <value>\")");
    }
    const std::string wrap = p.get_string("wrap", "repeat");
    TextureWrap w = TextureWrap::kRepeat;
    if (wrap == "clamp" || wrap == "black") {
      w = TextureWrap::kClampToEdge;
      if (wrap == "black")
        substituted(c, "wrap black", "wrap mode \"black\" is not supported", "clamped to the edge");
    } else if (wrap != "repeat") {
      substituted(c, "wrap " + wrap, "wrap mode " + quoted(wrap) + " is not supported", "repeated");
    }
    t.colour.present = true;
    t.colour.rgb = vec3(p.get_float("scale", 1.0f));
    if (p.get_bool("invert", false))
      substituted(c, "invert", "inverted image textures are not supported", "used the image as is");
    t.colour.image = load_image(file, srgb, w, loc);
    // Without its image the material falls back to its default colour, as if untextured.
    t.colour.present = t.colour.image != kInvalid;
  } else if (cls == "checkerboard") {
    t.colour.present = true;
    t.colour.image = bake_checkerboard(p, loc);
  } else if (cls == "constant") {
    const Colour v = colour(p, "value", Use::kReflectance, c);
    t.colour.present = true;
    t.colour.rgb = v.present ? v.rgb : vec3(1.0f);
  } else if (cls == "scale") {
    Colour base = colour(p, "tex", Use::kReflectance, c);
    if (!base.present) base.present = true;
    const PbrtParam* s = p.find("scale", {"float", "texture"});
    if (s && s->type == "float") base.rgb *= float(s->numbers[0]);
    if (s && s->type == "texture")
      substituted(c, "scale texture", "a textured scale is not supported", "used 1");
    t.colour = base;
  } else {
    static const std::vector<std::string> kClasses = {
        "imagemap", "checkerboard", "constant", "scale", "mix",    "directionmix", "bilerp",
        "dots",     "fbm",          "wrinkled", "windy", "marble", "ptex"};
    bool known = false;
    for (const std::string& k : kClasses) known |= k == cls;
    if (!known) {
      const std::string guess = did_you_mean(cls, kClasses);
      throw InputError(loc, "Texture " + quoted(name) + ": unknown texture class " + quoted(cls) +
                                (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
    }
    substituted(c, "texture " + cls, "the texture class " + quoted(cls) + " is not supported",
                "materials using it get their default colour");
    textures_[name] = t;  // colour.present stays false
    return;
  }
  p.ignore(
      {"filter", "maxanisotropy", "mapping", "uscale", "vscale", "udelta", "vdelta", "dimension"});
  if (cls == "imagemap" && (p.get_float("uscale", 1) != 1 || p.get_float("vscale", 1) != 1 ||
                            p.get_float("udelta", 0) != 0 || p.get_float("vdelta", 0) != 0))
    substituted(c, "uv transform", "texture coordinate scales and offsets are not supported",
                "used the mesh's coordinates as they are");
  const std::string mapping = p.get_string("mapping", "uv");
  if (mapping != "uv")
    substituted(c, "mapping " + mapping, "the " + quoted(mapping) + " mapping is not supported",
                "used the mesh's uv coordinates");
  p.report_unused(warnings_);
  textures_[name] = t;
}

PbrtMaterials::Colour PbrtMaterials::texture_colour(const std::string& name, const Ctx& c) {
  const auto it = textures_.find(name);
  if (it == textures_.end()) {
    std::vector<std::string> names;
    for (const auto& [n, t] : textures_) names.push_back(n);
    const std::string guess = did_you_mean(name, names);
    throw InputError(c.loc, c.what + ": texture " + quoted(name) + " is not defined" +
                                (guess.empty() ? "" : " (did you mean " + quoted(guess) + "?)"));
  }
  const Tex& t = it->second;
  if (t.type != "spectrum") {
    substituted(
        c, "float texture colour",
        "the float texture " + quoted(name) + " is used as a colour, which is not supported",
        "used the default colour");
    return Colour();
  }
  return t.colour;
}

uint32_t PbrtMaterials::load_image(const std::string& file, bool srgb, TextureWrap wrap,
                                   const SourceLoc& loc) {
  const std::string path = path_join(base_dir_, file);
  const auto key = std::make_tuple(path, srgb, int(wrap));
  const auto cached = images_.find(key);
  if (cached != images_.end()) return cached->second;
  uint32_t& id = images_[key];
  id = kInvalid;
  const std::string what = "image texture " + quoted(file);
  if (!file_exists(path)) {
    warnings_.warn(loc, "missing texture " + path, what + " not found",
                   "rendered the surfaces that use it untextured");
    return id;
  }
  TextureImage t;
  const std::string ext = path_extension_lower(path);
  if (ext == ".exr" || ext == ".hdr") {
    // Linear floats: stored sRGB-encoded in 8 bits like colour maps (values above 1 clip).
    ImageRGB img = read_image(path);
    t.width = img.width;
    t.height = img.height;
    t.rgba8.resize(size_t(t.width) * size_t(t.height) * 4);
    for (size_t i = 0; i < size_t(t.width) * size_t(t.height); ++i) {
      for (int k = 0; k < 3; ++k)
        t.rgba8[4 * i + size_t(k)] = to_srgb8(img.pixels[3 * i + size_t(k)]);
      t.rgba8[4 * i + 3] = 255;
    }
    srgb = true;
  } else {
    if (!decode_texture_file(path, &t, " (used at " + loc.str() + ")")) {
      warnings_.warn(loc, "undecodable texture " + path, what + " cannot be decoded",
                     "rendered the surfaces that use it untextured");
      return id;
    }
  }
  t.srgb = srgb;
  t.wrap_s = t.wrap_t = wrap;
  t.source = path;
  scene_.textures.push_back(std::move(t));
  id = uint32_t(scene_.textures.size() - 1);
  return id;
}

// A 2D checkerboard as an image: 16 texels per check, so that bilinear filtering softens only
// the edges. Exact for uv in [0, 1] (and beyond, when uscale and vscale are even integers).
uint32_t PbrtMaterials::bake_checkerboard(PbrtParams& p, const SourceLoc& loc) {
  const Ctx c{loc, "checkerboard texture"};
  const Colour a = colour(p, "tex1", Use::kReflectance, c);
  const Colour b = colour(p, "tex2", Use::kReflectance, c);
  if (a.image != kInvalid || b.image != kInvalid)
    substituted(c, "checkerboard of textures", "checkerboards of textures are not supported",
                "used their constant factors");
  const vec3 c1 = a.present ? a.rgb : vec3(1.0f), c2 = b.present ? b.rgb : vec3(0.0f);
  if (p.get_int("dimension", 2) == 3)
    substituted(c, "checkerboard 3d", "3D checkerboards are not supported",
                "baked a 2D one over the surface's uv");
  const float su = p.get_float("uscale", 1.0f), sv = p.get_float("vscale", 1.0f);
  const float du = p.get_float("udelta", 0.0f), dv = p.get_float("vdelta", 0.0f);
  const int w = int(glm::clamp(std::ceil(std::fabs(su) * 16.0f), 2.0f, 2048.0f));
  const int h = int(glm::clamp(std::ceil(std::fabs(sv) * 16.0f), 2.0f, 2048.0f));
  if (glm::any(glm::greaterThan(glm::max(c1, c2), vec3(1.0f))))
    substituted(c, "checkerboard > 1", "checker colours above 1", "clamped them to 1");
  TextureImage t;
  t.width = w;
  t.height = h;
  t.srgb = true;
  t.source = "checkerboard at " + loc.str();
  t.rgba8.resize(size_t(w) * size_t(h) * 4);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      // Texel centre in our uv (v down), back to pbrt's (v up).
      const float u = (float(x) + 0.5f) / float(w), v = 1.0f - (float(y) + 0.5f) / float(h);
      // In doubles and through fmod, so that huge scales cannot overflow an int.
      const double cells = std::floor(double(su) * u + du) + std::floor(double(sv) * v + dv);
      const int parity = std::fabs(std::fmod(cells, 2.0)) >= 1.0 ? 1 : 0;
      const vec3 col = parity == 0 ? c1 : c2;
      uint8_t* px = &t.rgba8[(size_t(y) * size_t(w) + size_t(x)) * 4];
      for (int k = 0; k < 3; ++k) px[k] = to_srgb8(glm::clamp(col[k], 0.0f, 1.0f));
      px[3] = 255;
    }
  }
  scene_.textures.push_back(std::move(t));
  return uint32_t(scene_.textures.size() - 1);
}

}  // namespace tracer
