// Environment maps: the readers (Radiance .hdr through stb_image, PFM of our own, OpenEXR through
// the OpenEXR library, which decodes DWA compression that tinyexr cannot), the checks every
// texel passes, and the flattening of the environment and the distant lights into InfiniteLights
// with the map's piecewise-constant sampling distribution.
#include "scene/environment.h"

#include <ImfRgbaFile.h>
#include <stb_image.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "scene/scene.h"

namespace tracer {
namespace {

namespace fs = std::filesystem;

// A problem with a map file: where (the file, and a header line when there is one) and what.
struct MapError {
  SourceLoc loc;
  std::string problem;
};

[[noreturn]] void fail(const std::string& path, const std::string& problem, int line = 0) {
  throw MapError{SourceLoc{path, line}, problem};
}

// Larger maps are a corrupt header or a mistake: 32k per side and 2^28 texels (4 GiB as RGBA).
constexpr long long kMaxSide = 32768;
constexpr long long kMaxTexels = 1LL << 28;

void check_size(const std::string& path, long long w, long long h, int line = 0) {
  if (w <= 0 || h <= 0 || w > kMaxSide || h > kMaxSide || w * h > kMaxTexels)
    fail(path,
         "map size " + std::to_string(w) + "x" + std::to_string(h) +
             " is empty or too large (at most 32768 per side and 2^28 texels)",
         line);
}

std::vector<unsigned char> read_bytes(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (st.type() == fs::file_type::not_found) fail(path, "no such file");
  if (fs::is_directory(st)) fail(path, "is a directory, not an environment map");
  // Not a device or a pipe, which could be read for ever (a fuzzed scene may name /dev/zero).
  if (!fs::is_regular_file(st)) fail(path, "is not a regular file");
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) fail(path, std::string("cannot open: ") + std::strerror(errno));
  std::vector<unsigned char> bytes;
  unsigned char chunk[1 << 16];
  size_t n;
  while ((n = std::fread(chunk, 1, sizeof chunk, f)) > 0)
    bytes.insert(bytes.end(), chunk, chunk + n);
  const bool error = std::ferror(f);
  std::fclose(f);
  if (error) fail(path, "read error");
  if (bytes.empty()) fail(path, "the file is empty");
  return bytes;
}

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// PFM (Debevec's portable float map): "PF" (RGB) or "Pf" (grey), width and height, a scale whose
// sign gives the byte order (negative: little-endian) and whose magnitude multiplies the values
// (as pbrt-v4 reads it), one whitespace character, then 32-bit floats, rows bottom to top.
void read_pfm(const std::string& path, EnvironmentImage* img) {
  const std::vector<unsigned char> bytes = read_bytes(path);
  size_t pos = 0;
  int line = 1;
  // The next header token (whitespace-separated) and the line it is on.
  auto token = [&](const char* what) {
    while (pos < bytes.size() && std::isspace(bytes[pos])) line += bytes[pos++] == '\n';
    const size_t start = pos;
    while (pos < bytes.size() && !std::isspace(bytes[pos]) && pos - start < 64) ++pos;
    if (pos == start)
      fail(path, std::string("the header ends before its ") + what + " (truncated file?)", line);
    return std::string(bytes.begin() + long(start), bytes.begin() + long(pos));
  };
  const std::string magic = token("type");
  if (magic != "PF" && magic != "Pf")
    fail(path, "not a PFM file (the header must start with PF or Pf, not \"" + magic + "\")", line);
  const int channels = magic == "PF" ? 3 : 1;
  auto integer = [&](const char* what) {
    const std::string t = token(what);
    char* end = nullptr;
    const long long v = std::strtoll(t.c_str(), &end, 10);
    if (*end != '\0' || t[0] == '-' || t[0] == '+')
      fail(path, std::string("the PFM ") + what + " \"" + t + "\" is not a whole number", line);
    return v;
  };
  const long long w = integer("width");
  const long long h = integer("height");
  check_size(path, w, h, line);
  const std::string scale_text = token("scale");
  char* end = nullptr;
  const double scale = std::strtod(scale_text.c_str(), &end);
  if (*end != '\0' || !std::isfinite(scale) || scale == 0.0)
    fail(path,
         "the PFM scale \"" + scale_text +
             "\" is not a non-zero number (its sign gives the byte order)",
         line);
  if (pos >= bytes.size() || !std::isspace(bytes[pos]))
    fail(path, "the PFM header ends without the whitespace before the data (truncated file?)",
         line);
  ++pos;  // exactly one whitespace character ends the header
  const bool little = scale < 0.0;
  const float magnitude = float(std::fabs(scale));
  const size_t count = size_t(w) * size_t(h) * size_t(channels);
  const size_t need = count * 4, have = bytes.size() - pos;
  if (have < need)
    fail(path, "truncated: " + std::to_string(w) + "x" + std::to_string(h) +
                   (channels == 3 ? " RGB" : " grey") + " texels need " + std::to_string(need) +
                   " bytes of data, the file has " + std::to_string(have) + " after its header");
  img->width = int(w);
  img->height = int(h);
  img->rgba.assign(size_t(w) * size_t(h) * 4, 0.0f);
  const unsigned char* data = bytes.data() + pos;
  for (long long y = 0; y < h; ++y) {
    const long long row = h - 1 - y;  // the file's first row is the image's bottom
    for (long long x = 0; x < w; ++x) {
      float* out = &img->rgba[4 * size_t(row * w + x)];
      for (int c = 0; c < channels; ++c) {
        const unsigned char* b = data + 4 * (size_t(y * w + x) * size_t(channels) + size_t(c));
        const uint32_t bits = little ? uint32_t(b[0]) | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 |
                                           uint32_t(b[3]) << 24
                                     : uint32_t(b[3]) | uint32_t(b[2]) << 8 | uint32_t(b[1]) << 16 |
                                           uint32_t(b[0]) << 24;
        float v;
        std::memcpy(&v, &bits, 4);
        out[c] = v * magnitude;
      }
      if (channels == 1) out[1] = out[2] = out[0];
    }
  }
}

// Walks the RGBE scanlines the way stb_image decodes them, with every read checked: stb's
// decoder loops for ever on a run of length 0, which is what a truncated file reads as (its
// reads past the end return 0), and fills missing data silently.
void check_hdr_data(const std::string& path, const std::vector<unsigned char>& b, int w, int h) {
  // The data starts after the blank line that ends the header and the resolution line after it.
  size_t pos = 0;
  while (pos + 1 < b.size() && !(b[pos] == '\n' && b[pos + 1] == '\n')) ++pos;
  pos += 2;
  while (pos < b.size() && b[pos] != '\n') ++pos;
  ++pos;
  auto truncated = [&](int row) {
    fail(path, "truncated Radiance HDR data (scanline " + std::to_string(row + 1) + " of " +
                   std::to_string(h) + " is incomplete)");
  };
  const size_t flat = 4 * size_t(w);
  for (int j = 0; j < h; ++j) {
    // stb reads the whole image flat when the width rules out run-length scanlines or the first
    // scanline is not one (the old format).
    const bool rle_width = w >= 8 && w < 32768;
    if (!rle_width ||
        (j == 0 && pos + 2 < b.size() && (b[pos] != 2 || b[pos + 1] != 2 || (b[pos + 2] & 0x80)))) {
      if (b.size() - std::min(pos, b.size()) < flat * size_t(h - j)) truncated(j);
      return;
    }
    if (pos + 4 > b.size()) truncated(j);
    if (b[pos] != 2 || b[pos + 1] != 2 || (b[pos + 2] & 0x80) ||
        ((int(b[pos + 2]) << 8) | b[pos + 3]) != w)
      fail(path, "corrupt Radiance HDR data (scanline " + std::to_string(j + 1) +
                     " does not start a run-length scanline of the image's width)");
    pos += 4;
    for (int k = 0; k < 4; ++k) {
      for (int i = 0; i < w;) {
        if (pos >= b.size()) truncated(j);
        int count = b[pos++];
        if (count > 128) {
          count -= 128;
          if (pos >= b.size()) truncated(j);
          ++pos;
        } else {
          if (count == 0 || pos + size_t(count) > b.size()) {
            if (count == 0)
              fail(path, "corrupt Radiance HDR data (a run of length 0 in scanline " +
                             std::to_string(j + 1) + ")");
            truncated(j);
          }
          pos += size_t(count);
        }
        if (count > w - i)
          fail(path, "corrupt Radiance HDR data (a run overflows scanline " +
                         std::to_string(j + 1) + ")");
        i += count;
      }
    }
  }
}

// Radiance RGBE through stb_image (linear: stb applies no gamma to HDR files), after
// check_hdr_data.
void read_hdr(const std::string& path, EnvironmentImage* img) {
  const std::vector<unsigned char> bytes = read_bytes(path);
  if (bytes.size() > size_t(INT32_MAX)) fail(path, "the file is too large");
  const int len = int(bytes.size());
  if (!stbi_is_hdr_from_memory(bytes.data(), len))
    fail(path, "not a Radiance HDR file (no #?RADIANCE or #?RGBE signature)", 1);
  int w = 0, h = 0, comp = 0;
  if (!stbi_info_from_memory(bytes.data(), len, &w, &h, &comp))
    fail(path, std::string("malformed Radiance HDR header (") + stbi_failure_reason() + ")");
  check_size(path, w, h);
  check_hdr_data(path, bytes, w, h);
  float* data = stbi_loadf_from_memory(bytes.data(), len, &w, &h, &comp, 3);
  if (!data) fail(path, std::string("corrupt Radiance HDR data (") + stbi_failure_reason() + ")");
  img->width = w;
  img->height = h;
  img->rgba.assign(size_t(w) * size_t(h) * 4, 0.0f);
  for (size_t i = 0; i < size_t(w) * size_t(h); ++i)
    for (int c = 0; c < 3; ++c) img->rgba[4 * i + size_t(c)] = data[3 * i + size_t(c)];
  stbi_image_free(data);
}

// OpenEXR through the library's RGBA interface: every compression it knows (DWAA/DWAB included),
// half or float channels, luminance-only files as grey; the data window is the image.
void read_exr(const std::string& path, EnvironmentImage* img) {
  read_bytes(path);  // the same messages as the other formats for missing and empty files
  try {
    Imf::RgbaInputFile file(path.c_str());
    const Imath::Box2i dw = file.dataWindow();
    const long long w = (long long)dw.max.x - dw.min.x + 1, h = (long long)dw.max.y - dw.min.y + 1;
    check_size(path, w, h);
    std::vector<Imf::Rgba> px(size_t(w) * size_t(h));
    file.setFrameBuffer(px.data() - dw.min.x - (long long)dw.min.y * w, 1, size_t(w));
    file.readPixels(dw.min.y, dw.max.y);
    img->width = int(w);
    img->height = int(h);
    img->rgba.assign(px.size() * 4, 0.0f);
    for (size_t i = 0; i < px.size(); ++i) {
      img->rgba[4 * i + 0] = float(px[i].r);
      img->rgba[4 * i + 1] = float(px[i].g);
      img->rgba[4 * i + 2] = float(px[i].b);
    }
  } catch (const MapError&) {
    throw;
  } catch (const std::exception& e) {
    // OpenEXR's messages name the file already; keep only its reason.
    std::string why = e.what();
    const size_t at = why.find(path);
    if (at != std::string::npos) why.erase(at, path.size());
    fail(path, "cannot read the OpenEXR file (" + why + ")");
  }
}

// Every texel finite; negative ones (lossy compression such as DWA leaves tiny negatives near
// black) clamped to 0 and counted.
void check_texels(const std::string& path, EnvironmentImage* img) {
  for (size_t i = 0; i < img->rgba.size(); ++i) {
    if (i % 4 == 3) continue;
    float& v = img->rgba[i];
    if (!std::isfinite(v)) {
      const size_t t = i / 4;
      fail(path, std::string("texel (") + std::to_string(t % size_t(img->width)) + ", " +
                     std::to_string(t / size_t(img->width)) + ") is " +
                     (std::isnan(v) ? "NaN" : "infinite") +
                     " (counting rows from the top); an environment map must be finite");
    }
    if (v < 0.0f) {
      ++img->negative;
      img->most_negative = std::min(img->most_negative, v);
      v = 0.0f;
    }
  }
}

}  // namespace

std::shared_ptr<const EnvironmentImage> read_environment_image(const std::string& path) {
  auto img = std::make_shared<EnvironmentImage>();
  img->path = path;
  try {
    const std::string ext = lower_extension(path);
    if (ext == ".hdr")
      read_hdr(path, img.get());
    else if (ext == ".pfm")
      read_pfm(path, img.get());
    else if (ext == ".exr")
      read_exr(path, img.get());
    else
      fail(path, "environment maps must be .hdr, .pfm or .exr files, not \"" + ext + "\"");
    check_texels(path, img.get());
  } catch (const MapError& e) {
    throw InputError(e.loc, e.problem, "the environment map was not loaded");
  }
  return img;
}

std::string refresh_environment(Scene& scene) {
  const std::string& file = scene.environment.file;
  if (file.empty()) {
    scene.environment_image.reset();
    return "";
  }
  std::shared_ptr<const EnvironmentImage> img = scene.environment_image;
  const bool fresh = !img || img->path != file;
  if (fresh) {
    try {
      img = read_environment_image(file);
    } catch (const InputError& e) {
      return e.what();
    }
  }
  const std::string shape =
      check_env_shape(resolve_env_mapping(scene.environment.mapping, img->width, img->height),
                      img->width, img->height);
  if (!shape.empty()) return SourceLoc{file, 0}.str() + ": " + shape;
  if (fresh && img->negative > 0) {
    char low[32];
    std::snprintf(low, sizeof low, "%.3g", double(img->most_negative));
    scene.diagnostics.warn(SourceLoc{file, 0},
                           std::to_string(img->negative) + " negative texel values (as low as " +
                               low + "; lossy compression such as DWA leaves them near black)",
                           "clamped to 0");
  }
  scene.environment_image = img;
  return "";
}

std::string describe_environment(const Scene& scene) {
  const EnvironmentDesc& e = scene.environment;
  const EnvironmentImage* img = scene.environment_image.get();
  char num[160];
  std::string s;
  if (!e.file.empty() && img) {
    s = fs::path(e.file).filename().string() + ", " + std::to_string(img->width) + "x" +
        std::to_string(img->height) + " " +
        env_mapping_name(resolve_env_mapping(e.mapping, img->width, img->height));
    if (e.mapping == EnvMapping::kAuto) s += " (auto)";
    std::snprintf(num, sizeof num, ", strength %g, rotation %g deg", double(e.strength),
                  double(e.rotation_deg));
    s += num;
    if (img->negative) s += ", " + std::to_string(img->negative) + " negative texels clamped";
  } else if (max_component(e.color) > 0.0f) {
    std::snprintf(num, sizeof num, "constant colour [%g, %g, %g] x %g", double(e.color.x),
                  double(e.color.y), double(e.color.z), double(e.strength));
    s = num;
  } else {
    s = "none";
  }
  if (!e.visible) s += ", hidden from the camera";
  const size_t n = scene.distant_lights.size();
  if (n) s += "; " + std::to_string(n) + (n == 1 ? " distant light" : " distant lights");
  return s;
}

nlohmann::json distant_lights_to_json(const std::vector<DistantLightDesc>& lights) {
  nlohmann::json out = nlohmann::json::array();
  for (const DistantLightDesc& d : lights) {
    auto v = [](vec3 x) { return nlohmann::json::array({x.x, x.y, x.z}); };
    out.push_back({{"type", "distant"},
                   {"name", d.name},
                   {"direction", v(d.direction)},
                   {"irradiance", v(d.irradiance)},
                   {"angular_diameter", d.angular_diameter_deg}});
  }
  return out;
}

EnvMapping resolve_env_mapping(EnvMapping setting, int width, int height) {
  if (setting != EnvMapping::kAuto) return setting;
  return width == height ? EnvMapping::kOctahedral : EnvMapping::kEquirect;
}

const char* env_mapping_name(EnvMapping m) {
  switch (m) {
    case EnvMapping::kAuto:
      return "auto";
    case EnvMapping::kEquirect:
      return "equirect";
    case EnvMapping::kOctahedral:
      return "octahedral";
  }
  return "";
}

std::string check_env_shape(EnvMapping resolved, int width, int height) {
  if (resolved == EnvMapping::kOctahedral && width != height)
    return "an octahedral map must be square, not " + std::to_string(width) + "x" +
           std::to_string(height);
  return "";
}

std::vector<float> env_importance(const InfiniteLights& v) {
  const int w = int(v.width), h = int(v.height);
  std::vector<float> lum(size_t(w) * size_t(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      lum[size_t(y) * size_t(w) + size_t(x)] = luminance(env_texel(v, x, y));
  // The bilinear lookup averaged over a cell weighs the texel 3/4 and each neighbour 1/8 per axis
  // (the average of a linear ramp over each half of the cell).
  auto at = [&](int x, int y) {
    if (v.env == kEnvOctahedral) {
      equal_area_wrap(x, y, w);
    } else {
      x = (x % w + w) % w;
      y = std::clamp(y, 0, h - 1);
    }
    return double(lum[size_t(y) * size_t(w) + size_t(x)]);
  };
  const double k[3] = {0.125, 0.75, 0.125};
  std::vector<float> func(lum.size());
  for (int y = 0; y < h; ++y) {
    // The cell's solid angle (equirectangular rows: 2 pi / w (cos theta0 - cos theta1)).
    const double omega = v.env == kEnvEquirect ? 4.0 * M_PI / w * std::sin(M_PI * (y + 0.5) / h) *
                                                     std::sin(0.5 * M_PI / h)
                                               : 4.0 * M_PI / (double(w) * h);
    for (int x = 0; x < w; ++x) {
      double sum = 0.0;
      for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) sum += k[j] * k[i] * at(x + i - 1, y + j - 1);
      func[size_t(y) * size_t(w) + size_t(x)] = float(sum * omega);
    }
  }
  return func;
}

void build_infinite_lights(const EnvironmentDesc& desc,
                           const std::shared_ptr<const EnvironmentImage>& image,
                           const std::vector<DistantLightDesc>& distant, InfiniteLightsData* out) {
  *out = InfiniteLightsData();
  InfiniteLights& v = out->view;
  const double rot = double(desc.rotation_deg) * M_PI / 180.0;
  const float c = float(std::cos(rot)), s = float(std::sin(rot));
  // Right-handed about +y (glm is column-major: columns are the images of x, y, z).
  const mat3 turn(vec3(c, 0.0f, -s), vec3(0.0f, 1.0f, 0.0f), vec3(s, 0.0f, c));
  v.to_world = turn * desc.frame;
  v.to_map = glm::transpose(v.to_world);
  v.strength = desc.strength;
  v.visible = desc.visible ? 1u : 0u;
  v.background = desc.background;
  if (!desc.file.empty() && image && desc.strength > 0.0f) {
    const EnvMapping m = resolve_env_mapping(desc.mapping, image->width, image->height);
    out->image = image;
    v.env = m == EnvMapping::kOctahedral ? kEnvOctahedral : kEnvEquirect;
    v.width = uint32_t(image->width);
    v.height = uint32_t(image->height);
    v.texels = image->rgba.data();
    out->func = env_importance(v);
    const uint32_t w = v.width, h = v.height;
    out->cond_cdf.assign(size_t(h) * (w + 1), 0.0f);
    out->marg_cdf.assign(h + 1, 0.0f);
    std::vector<double> row_sum(h, 0.0);
    double total = 0.0;
    for (uint32_t y = 0; y < h; ++y) {
      const float* f = &out->func[size_t(y) * w];
      float* cdf = &out->cond_cdf[size_t(y) * (w + 1)];
      double acc = 0.0;
      for (uint32_t x = 0; x < w; ++x) acc += f[x];
      row_sum[y] = acc;
      double run = 0.0;
      for (uint32_t x = 0; x < w; ++x) {
        run += f[x];
        // A row of zeros is never chosen; a uniform CDF keeps it well-formed.
        cdf[x + 1] = acc > 0.0 ? float(run / acc) : float(double(x + 1) / w);
      }
      cdf[w] = 1.0f;
      total += acc;
    }
    if (total > 0.0) {
      double run = 0.0;
      for (uint32_t y = 0; y < h; ++y) {
        run += row_sum[y];
        out->marg_cdf[y + 1] = float(run / total);
      }
      out->marg_cdf[h] = 1.0f;
      v.func_sum = float(total);
      v.func = out->func.data();
      v.cond_cdf = out->cond_cdf.data();
      v.marg_cdf = out->marg_cdf.data();
      // func is the mean luminance times the solid angle: its sum is the radiance integral.
      out->env_luminance_integral = total * double(desc.strength);
    } else {
      v.env = kEnvNone;  // a black map lights nothing
      v.width = v.height = 0;
      v.texels = nullptr;
      out->func.clear();
      out->cond_cdf.clear();
      out->marg_cdf.clear();
      out->image.reset();
    }
  } else if (desc.file.empty() && max_component(desc.color) > 0.0f && desc.strength > 0.0f) {
    v.env = kEnvConstant;
    v.constant = desc.color * desc.strength;
    out->env_luminance_integral = 4.0 * M_PI * double(luminance(v.constant));
  }
  for (const DistantLightDesc& d : distant) {
    DistantLight dl;
    dl.dir = glm::normalize(d.direction);
    // 1 - cos(a) = 2 sin^2(a / 2), in double: the sun's is 1e-5, where cos rounds to a few bits.
    const double half = 0.5 * double(d.angular_diameter_deg) * M_PI / 180.0;
    const double s = std::sin(0.5 * half);
    dl.one_minus_cos = float(2.0 * s * s);
    // Irradiance E from a uniform disc of half-angle a on a surface facing it: L pi sin^2(a).
    const double sin_a = std::sin(half);
    dl.radiance = half > 0.0 ? d.irradiance / float(M_PI * sin_a * sin_a) : d.irradiance;
    dl.light = kInvalid;
    if (!(max_component(d.irradiance) > 0.0f)) continue;  // a black sun gives nothing
    out->distant.push_back(dl);
    double lum = double(luminance(d.irradiance));
    if (!(lum > 0.0)) lum = double(max_component(d.irradiance));
    out->distant_luminance.push_back(lum);
  }
  v.distant = out->distant.empty() ? nullptr : out->distant.data();
  v.distant_count = uint32_t(out->distant.size());
}

}  // namespace tracer
