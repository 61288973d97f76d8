// The export of a render: colour, denoised colour, AOVs and sidecar (export.h).
#include "integrator/export.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "core/rng.h"
#include "scene/loader_util.h"

namespace tracer {
namespace {

std::string with_suffix(const std::string& path, const std::string& suffix,
                        const std::string& ext) {
  const std::string e = path_extension_lower(path);
  const std::string stem = e.empty() ? path : path.substr(0, path.size() - e.size());
  return stem + "." + suffix + ext;
}

// The object a hit id belongs to (Scene::objects), or -1: triangles by their ranges, spheres by
// index, instanced triangles through the instances' hit-id ranges (as CompiledScene numbers
// them: after the triangles and spheres, instance after instance).
std::vector<float> object_ids(const Scene& scene, const std::vector<uint32_t>& prims) {
  const uint64_t tris = scene.mesh.indices.size(), spheres = scene.spheres.size();
  std::vector<uint64_t> inst_end;  // one past each instance's last hit id
  uint64_t base = tris + spheres;
  for (const MeshInstance& mi : scene.instances) {
    base += mi.mesh < scene.instanced_meshes.size()
                ? scene.instanced_meshes[mi.mesh].mesh.indices.size()
                : 0;
    inst_end.push_back(base);
  }
  std::vector<float> out(prims.size(), -1.0f);
  for (size_t i = 0; i < prims.size(); ++i) {
    const uint64_t p = prims[i];
    if (prims[i] == kInvalid) continue;
    for (size_t o = 0; o < scene.objects.size(); ++o) {
      const ObjectInfo& ob = scene.objects[o];
      bool mine = false;
      if (p < tris) {
        mine = ob.is_triangles() && p >= ob.first && p < uint64_t(ob.first) + ob.count;
      } else if (p < tris + spheres) {
        mine = ob.is_sphere && ob.first == p - tris;
      } else if (ob.is_instances) {
        const size_t k = size_t(std::upper_bound(inst_end.begin(), inst_end.end(), p) -
                                inst_end.begin());
        mine = k >= ob.first && k < size_t(ob.first) + ob.count;
      }
      if (mine) {
        out[i] = float(o);
        break;
      }
    }
  }
  return out;
}

std::vector<ExrChannel> aov_layers(const AovImages& a, const AovRequest& r, const Scene& scene) {
  std::vector<ExrChannel> out;
  auto rgb = [&](const ImageRGB& img, const std::string& prefix, const char* names) {
    for (int c = 0; c < 3; ++c) {
      ExrChannel ch;
      ch.name = prefix + "." + names[c];
      ch.values.resize(img.pixels.size() / 3);
      for (size_t i = 0; i < ch.values.size(); ++i) ch.values[i] = img.pixels[3 * i + c];
      out.push_back(std::move(ch));
    }
  };
  if (r.albedo) rgb(a.albedo, "albedo", "RGB");
  if (r.normal) rgb(a.normal, "normal", "XYZ");
  if (r.depth) out.push_back({"depth.Z", a.depth});
  if (r.id) {
    ExrChannel mat{"id.material", std::vector<float>(a.material.size())};
    for (size_t i = 0; i < a.material.size(); ++i)
      mat.values[i] = a.material[i] == kInvalid ? -1.0f : float(a.material[i]);
    out.push_back(std::move(mat));
    out.push_back({"id.object", object_ids(scene, a.prim)});
  }
  return out;
}


}  // namespace

std::vector<std::string> AovRequest::names() const {
  std::vector<std::string> n;
  if (albedo) n.push_back("albedo");
  if (normal) n.push_back("normal");
  if (depth) n.push_back("depth");
  if (id) n.push_back("id");
  return n;
}

bool parse_aov_list(const std::string& list, AovRequest* out, std::string* problem) {
  AovRequest r;
  r.png = out->png;
  std::stringstream ss(list);
  std::string word;
  while (std::getline(ss, word, ',')) {
    word.erase(0, word.find_first_not_of(" \t"));
    word.erase(word.find_last_not_of(" \t") + 1);
    if (word == "albedo") r.albedo = true;
    else if (word == "normal") r.normal = true;
    else if (word == "depth") r.depth = true;
    else if (word == "id") r.id = true;
    else if (word == "all") r.albedo = r.normal = r.depth = r.id = true;
    else if (!word.empty()) {
      *problem = "--aov: unknown AOV '" + word + "' (expected albedo, normal, depth, id or all)";
      return false;
    }
  }
  *out = r;
  return true;
}

std::string denoised_path(const std::string& path) {
  return with_suffix(path, "denoised", path_extension_lower(path));
}

std::string aov_png_path(const std::string& path, const std::string& aov) {
  return with_suffix(path, aov, ".png");
}

ImageRGB aov_preview(const AovImages& a, const std::string& which) {
  ImageRGB out = make_image(a.albedo.width, a.albedo.height);
  const size_t n = a.depth.size();
  if (which == "albedo") return a.albedo;
  if (which == "normal") {
    for (size_t i = 0; i < 3 * n; ++i)
      out.pixels[i] = srgb_to_linear(std::clamp(a.normal.pixels[i] * 0.5f + 0.5f, 0.0f, 1.0f));
    return out;
  }
  if (which == "depth") {
    float lo = 1e30f, hi = 0.0f;
    for (float d : a.depth)
      if (d > 0.0f) lo = std::min(lo, d), hi = std::max(hi, d);
    for (size_t i = 0; i < n; ++i) {
      const float d = a.depth[i];
      const float t = d > 0.0f && hi > lo ? 1.0f - (d - lo) / (hi - lo) : d > 0.0f ? 1.0f : 0.0f;
      const float v = srgb_to_linear(0.1f + 0.9f * t) * (d > 0.0f ? 1.0f : 0.0f);
      for (int c = 0; c < 3; ++c) out.pixels[3 * i + c] = v;
    }
    return out;
  }
  if (which == "id") {
    for (size_t i = 0; i < n; ++i) {
      if (a.material[i] == kInvalid) continue;
      const uint32_t h = uint32_t(mix64(a.material[i] + 1ull));  // a colour per material
      for (int c = 0; c < 3; ++c)
        out.pixels[3 * i + c] = srgb_to_linear(float((h >> (8 * c)) & 0xffu) / 255.0f);
    }
    return out;
  }
  throw std::invalid_argument("aov_preview: unknown AOV '" + which + "'");
}

ExportResult export_render(const std::string& path, const ImageRGB& color, const AovImages* aovs,
                           const AovRequest& request, const Scene& scene, SidecarRun run,
                           const ImageRGB* given, const DenoiseInfo* given_info) {
  ExportResult res;
  const DenoiseMode mode = scene.display.denoise;
  if (aovs && aovs->empty()) aovs = nullptr;
  if (request.any() && !aovs)
    throw std::runtime_error(path + ": the AOVs were not recorded (no sample with AOVs on)");
  const bool exr = path_extension_lower(path) == ".exr";
  // Everything that can fail without touching a file first: the denoiser.
  ImageRGB denoised;
  if (mode != DenoiseMode::kOff && given) {
    denoised = *given;
    if (given_info) res.denoise = *given_info;
  } else if (mode != DenoiseMode::kOff) {
    denoised = denoise_image(color, aovs ? &aovs->albedo : nullptr,
                             aovs ? &aovs->normal : nullptr, &res.denoise);
  }
  const ImageRGB& main = mode == DenoiseMode::kOn ? denoised : color;
  const std::vector<ExrChannel> layers =
      aovs && request.any() ? aov_layers(*aovs, request, scene) : std::vector<ExrChannel>();
  auto write_main = [&](const std::string& p, const ImageRGB& img) {
    if (exr && !layers.empty()) {
      write_exr_layers(p, img, layers);
    } else {
      write_image(p, img, scene.display.exposure, scene.display.tone_map);
    }
    res.files.push_back(p);
  };
  write_main(path, main);
  if (mode == DenoiseMode::kBoth) write_main(denoised_path(path), denoised);
  if (aovs && (request.png || !exr)) {
    for (const std::string& name : request.names()) {
      const std::string p = aov_png_path(path, name);
      write_image(p, aov_preview(*aovs, name));
      res.files.push_back(p);
    }
  }
  run.output = path;
  run.aovs = request.names();
  run.aov_samples = aovs ? run.aov_samples : 0;
  run.denoise = res.denoise;
  run.denoised_output = mode == DenoiseMode::kBoth ? denoised_path(path)
                        : mode == DenoiseMode::kOn ? path
                                                   : "";
  write_sidecar(scene, run);
  res.files.push_back(path + ".json");
  return res;
}

}  // namespace tracer
