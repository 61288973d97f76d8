#include "integrator/distributed.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>

#include "scene/environment.h"
#include "scene/point_lights.h"
#include "scene/settings.h"

namespace tracer {

BatchScheduler::BatchScheduler(uint32_t spp, double time_limit_s, int ranks, double batch_s)
    : spp_(spp),
      time_limit_s_(time_limit_s),
      batch_s_(batch_s),
      rate_(size_t(std::max(1, ranks)), 0.0),
      batches_(size_t(std::max(1, ranks)), 0),
      samples_(size_t(std::max(1, ranks)), 0) {}

SampleRange BatchScheduler::next(int rank, double ms_per_spp, double now_s) {
  SampleRange r;
  r.first = next_;
  if (stopped_ || rank < 0 || rank >= ranks()) return r;
  if (ms_per_spp > 0.0) rate_[size_t(rank)] = 1.0 / ms_per_spp;
  const double rate = rate_[size_t(rank)];
  double budget_s = batch_s_;
  uint64_t limit = 1u << 16;
  if (spp_ > 0) {
    if (next_ >= spp_) return r;
    const uint32_t remaining = spp_ - next_;
    limit = remaining;
    if (rate > 0.0) {
      // At most half of this rank's share of what remains, by the measured speeds (ranks not
      // measured yet count as fast as this one).
      double total = 0.0;
      for (double x : rate_) total += x > 0.0 ? x : rate;
      const double share = double(remaining) * rate / total;
      limit = std::min<uint64_t>(limit, uint64_t(std::max(1.0, std::ceil(0.5 * share))));
    }
  } else {
    const double left = time_limit_s_ - now_s;
    if (left <= 0.0) return r;
    budget_s = std::min(budget_s, left);
  }
  uint64_t n = 1;  // the first batch measures the rank's speed
  if (rate > 0.0) n = uint64_t(std::max(1.0, std::floor(budget_s * 1000.0 * rate)));
  n = std::min(n, limit);
  n = std::min<uint64_t>(n, uint64_t(UINT32_MAX - next_));
  r.count = uint32_t(n);
  next_ += r.count;
  ++batches_[size_t(rank)];
  samples_[size_t(rank)] += r.count;
  return r;
}

void Accumulation::add(const Accumulation& o) {
  if (width == 0 && height == 0) {
    *this = o;
    return;
  }
  for (int h = 0; h < 2; ++h) {
    for (size_t i = 0; i < sum[h].size() && i < o.sum[h].size(); ++i) sum[h][i] += o.sum[h][i];
    count[h] += o.count[h];
  }
  if (aov_sum.empty()) aov_sum.assign(o.aov_sum.size(), 0.0f);
  for (size_t i = 0; i < aov_sum.size() && i < o.aov_sum.size(); ++i) aov_sum[i] += o.aov_sum[i];
  aov_count += o.aov_count;
  if (aov_ids.empty()) aov_ids = o.aov_ids;
  rays += o.rays;
  nonfinite += o.nonfinite;
  clamped += o.clamped;
  clamped_luminance += o.clamped_luminance;
}

ImageRGB Accumulation::image() const {
  ImageRGB img = make_image(width, height);
  const uint32_t n = samples();
  if (n == 0) return img;
  const double inv = 1.0 / n;
  for (size_t i = 0; i < img.pixels.size(); ++i)
    img.pixels[i] = float((double(sum[0][i]) + double(sum[1][i])) * inv);
  return img;
}

void Accumulation::half_images(ImageRGB* even, ImageRGB* odd) const {
  ImageRGB* outs[2] = {even, odd};
  for (int h = 0; h < 2; ++h) {
    if (!outs[h]) continue;
    *outs[h] = make_image(width, height);
    if (count[h] == 0) continue;
    const double inv = 1.0 / count[h];
    for (size_t i = 0; i < outs[h]->pixels.size(); ++i)
      outs[h]->pixels[i] = float(double(sum[h][i]) * inv);
  }
}

AovImages Accumulation::aov_images() const {
  AovImages out;
  if (aov_count == 0 || aov_sum.empty()) return out;
  const size_t n = size_t(width) * size_t(height);
  out.albedo = make_image(width, height);
  out.normal = make_image(width, height);
  out.depth.assign(n, 0.0f);
  out.material.assign(n, 0);
  out.prim.assign(n, 0);
  const double inv = 1.0 / aov_count;
  for (size_t i = 0; i < n; ++i) {
    const float* v = &aov_sum[i * kAovFloats];
    for (int c = 0; c < 3; ++c) {
      out.albedo.pixels[3 * i + c] = float(v[c] * inv);
      out.normal.pixels[3 * i + c] = float(v[3 + c] * inv);
    }
    out.depth[i] = float(v[6] * inv);
    if (aov_ids.size() >= 2 * n) {
      out.material[i] = aov_ids[2 * i];
      out.prim[i] = aov_ids[2 * i + 1];
    }
  }
  return out;
}

double Accumulation::half_relmse() const {
  if (count[0] == 0 || count[1] == 0) return -1.0;
  ImageRGB a, b;
  half_images(&a, &b);
  return half_images_relmse(a, b);
}

Accumulation accumulation_of_aovs(const Renderer& r, int width, int height) {
  Accumulation acc;
  acc.width = width;
  acc.height = height;
  const AovImages a = r.aov_images();
  if (a.empty()) return acc;
  const size_t n = size_t(width) * size_t(height);
  acc.aov_count = r.aov_samples();
  const float w = float(acc.aov_count);
  acc.aov_sum.resize(n * kAovFloats);
  acc.aov_ids.resize(2 * n);
  for (size_t i = 0; i < n; ++i) {
    float* v = &acc.aov_sum[i * kAovFloats];
    for (int c = 0; c < 3; ++c) {
      v[c] = a.albedo.pixels[3 * i + c] * w;
      v[3 + c] = a.normal.pixels[3 * i + c] * w;
    }
    v[6] = a.depth[i] * w;
    acc.aov_ids[2 * i] = a.material[i];
    acc.aov_ids[2 * i + 1] = a.prim[i];
  }
  return acc;
}

Accumulation accumulation_of(const Renderer& r, int width, int height) {
  Accumulation acc = accumulation_of_aovs(r, width, height);
  for (int h = 0; h < 2; ++h) {
    acc.count[h] = r.half_samples(h);
    acc.sum[h].resize(size_t(width) * size_t(height) * 3);
  }
  r.half_sums(acc.sum[0].data(), acc.sum[1].data());
  return acc;
}

RankPlacement place_rank(BackendChoice asked, int threads_asked, int local_rank, int local_size,
                         int gpus, int hw_threads) {
  RankPlacement p;
  p.backend = asked;
  local_size = std::max(1, local_size);
  hw_threads = std::max(1, hw_threads);
  auto share_cores = [&](int ranks) {
    return threads_asked > 0 ? threads_asked : std::max(1, hw_threads / std::max(1, ranks));
  };
  if (asked == BackendChoice::kCpu) {
    p.threads = share_cores(local_size);
    return p;
  }
  // A GPU rank that falls back to the CPU (the device refuses) takes the share every rank of the
  // host would get.
  p.threads = share_cores(local_size);
  if (asked == BackendChoice::kCuda) {
    p.device = gpus > 0 ? local_rank % gpus : 0;
    if (gpus > 0 && local_size > gpus)
      p.note = std::to_string(local_size) + " ranks on this host share its " +
               std::to_string(gpus) + (gpus == 1 ? " GPU" : " GPUs") + " (--backend cuda)";
    return p;
  }
  if (local_rank < gpus) {
    p.device = local_rank;
    return p;
  }
  p.backend = BackendChoice::kCpu;
  p.threads = share_cores(local_size - std::min(gpus, local_size));
  if (gpus > 0)
    p.note = "a CPU rank: this host's " + std::to_string(gpus) +
             (gpus == 1 ? " GPU is" : " GPUs are") + " taken by its first " +
             std::to_string(gpus) + (gpus == 1 ? " rank" : " ranks");
  return p;
}

namespace {
struct Fnv {
  uint64_t h = 1469598103934665603ull;
  void bytes(const void* p, size_t n) {
    const unsigned char* c = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) h = (h ^ c[i]) * 1099511628211ull;
  }
  template <class T>
  void vec(const std::vector<T>& v) {
    const uint64_t n = v.size();
    bytes(&n, sizeof n);
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
  void text(const std::string& s) { bytes(s.data(), s.size()); }
};
}  // namespace

uint64_t scene_fingerprint(const Scene& scene) {
  nlohmann::json j = settings_to_json(scene);
  j.erase("gpu");      // the GPU's switches never change the image
  j.erase("display");  // applied by rank 0 alone, after the sum
  for (const char* k : {"threads", "backend", "spp", "time_limit_s", "strict", "samples_per_frame"})
    j["render"].erase(k);
  nlohmann::json mats = nlohmann::json::object();
  for (const auto& m : scene.materials) mats[m.name] = material_to_json(m.material);
  j["materials"] = mats;
  j["lights"] = lights_to_json(scene.distant_lights, scene.point_lights);
  Fnv f;
  // (names as their bytes too: two that differ only in bytes that are not UTF-8 differ here)
  f.text(json_text(j));  // (bytes that are not UTF-8 replaced: it never throws)
  for (const auto& m : scene.materials) f.text(m.name);
  f.vec(scene.mesh.positions);
  f.vec(scene.mesh.normals);
  f.vec(scene.mesh.uvs);
  f.vec(scene.mesh.indices);
  f.vec(scene.mesh.materials);
  for (const SphereDesc& s : scene.spheres) {  // field by field: no padding bytes hashed
    f.bytes(&s.center, sizeof s.center);
    f.bytes(&s.radius, sizeof s.radius);
    f.bytes(&s.material, sizeof s.material);
  }
  for (const TextureImage& t : scene.textures) {
    f.vec(t.rgba8);
    const int32_t dims[5] = {t.width, t.height, int32_t(t.srgb), int32_t(t.wrap_s),
                             int32_t(t.wrap_t)};
    f.bytes(dims, sizeof dims);
    f.bytes(&t.uv_transform, sizeof t.uv_transform);
  }
  for (const auto& m : scene.instanced_meshes) {
    f.vec(m.mesh.positions);
    f.vec(m.mesh.normals);
    f.vec(m.mesh.uvs);
    f.vec(m.mesh.indices);
    f.vec(m.mesh.materials);
  }
  for (const MeshInstance& i : scene.instances) {
    f.bytes(&i.mesh, sizeof i.mesh);
    f.bytes(&i.world_from_object, sizeof i.world_from_object);
  }
  if (scene.environment_image) {
    f.vec(scene.environment_image->rgba);
    const int32_t dims[2] = {int32_t(scene.environment_image->width),
                             int32_t(scene.environment_image->height)};
    f.bytes(dims, sizeof dims);
  }
  return f.h;
}

bool parse_frame_range(const std::string& text, int* first, int* last, std::string* problem) {
  auto number = [](const std::string& s, int* out) {
    if (s.empty() || s.size() > 9 || s.find_first_not_of("0123456789") != std::string::npos)
      return false;
    *out = std::atoi(s.c_str());
    return true;
  };
  const size_t dots = text.find("..");
  const std::string a = dots == std::string::npos ? text : text.substr(0, dots);
  const std::string b = dots == std::string::npos ? text : text.substr(dots + 2);
  if (!number(a, first) || !number(b, last)) {
    *problem = "--frames " + text + ": expected A..B or A (frame numbers >= 0), e.g. 1..24";
    return false;
  }
  if (*first > *last) {
    *problem = "--frames " + text + ": the first frame is after the last";
    return false;
  }
  return true;
}

bool has_frame_field(const std::string& pattern) { return pattern.find('#') != std::string::npos; }

std::string frame_path(const std::string& pattern, int frame) {
  const size_t at = pattern.find('#');
  if (at == std::string::npos) return pattern;
  size_t end = at;
  while (end < pattern.size() && pattern[end] == '#') ++end;
  std::string digits = std::to_string(frame);
  if (digits.size() < end - at) digits.insert(0, end - at - digits.size(), '0');
  return pattern.substr(0, at) + digits + pattern.substr(end);
}

}  // namespace tracer
