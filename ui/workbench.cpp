// The workbench model: edits, accumulator resets, the CPU render thread, navigation, picking,
// export and scene saving.
#include "ui/workbench.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cpu/cpu_backend.h"
#include "image/image.h"
#include "scene/loader.h"

namespace tracer {
extern const char* const kBuiltinSceneJson;
}

namespace ui {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

bool parse_floats(const std::string& s, float* out, int n) {
  std::stringstream ss(s);
  for (int i = 0; i < n; ++i) {
    if (!(ss >> out[i])) return false;
    if (!std::isfinite(out[i])) return false;
    char comma;
    if (i + 1 < n && ss.peek() == ',') ss >> comma;
  }
  std::string rest;
  ss >> rest;
  return rest.empty();
}

bool parse_bool(const std::string& s, bool* out) {
  if (s == "on" || s == "true" || s == "1") return *out = true, true;
  if (s == "off" || s == "false" || s == "0") return *out = false, true;
  return false;
}

nlohmann::json vec_json(vec3 v) { return {v.x, v.y, v.z}; }

nlohmann::json material_json(const tracer::Material& m) {
  nlohmann::json j;
  j["type"] = tracer::material_type_name(m.type);
  j["albedo"] = vec_json(m.albedo);
  const float strength = tracer::max_component(m.emission);
  if (strength > 0.0f) {
    j["emission"] = vec_json(m.emission / strength);
    j["emission_strength"] = strength;
    if (m.flags & tracer::kMaterialTwoSidedEmission) j["two_sided"] = true;
  }
  if (m.type == tracer::MaterialType::kDielectric || m.type == tracer::MaterialType::kSubsurface) {
    j["ior"] = m.ior;
    j["fresnel"] = (m.flags & tracer::kMaterialSchlickFresnel) ? "schlick" : "exact";
    if (tracer::max_component(m.absorption) > 0.0f) j["absorption"] = vec_json(m.absorption);
  }
  if (m.type == tracer::MaterialType::kSubsurface) {
    j.erase("albedo");
    j["scattering"] = vec_json(m.scattering);
    j["absorption"] = vec_json(m.absorption);
    j["g"] = m.g;
  }
  if (m.roughness > 0.0f) j["roughness"] = m.roughness;
  return j;
}

}  // namespace

Workbench::Workbench(tracer::Scene scene, tracer::BackendChoice backend, int cpu_threads)
    : scene_(std::move(scene)), backend_choice_(backend), cpu_threads_(cpu_threads) {
  initial_camera_ = scene_.camera;
  target_spp = uint32_t(std::max(0, scene_.settings.spp));
  target_seconds = scene_.settings.time_limit_s;
  for (const auto& w : scene_.diagnostics.warnings) messages.push_back("warning: " + w);
  std::string error;
  if (!set_backend(backend, &error)) {
    messages.push_back("error: " + error + "; using the CPU backend");
    set_backend(tracer::BackendChoice::kCpu, &error);
  }
}

Workbench::~Workbench() { stop_worker(); }

std::string Workbench::backend_name() const { return renderer_ ? renderer_->backend_name() : ""; }
std::string Workbench::device_name() const { return renderer_ ? renderer_->device_name() : ""; }

tracer::Renderer* Workbench::gpu_renderer() {
  return renderer_ && renderer_->backend_name() == "cuda" ? renderer_.get() : nullptr;
}

bool Workbench::set_backend(tracer::BackendChoice b, std::string* error) {
  std::unique_ptr<tracer::Renderer> r;
  std::string note;
  try {
    r = tracer::make_renderer(b, cpu_threads_, &note);
  } catch (const std::exception& e) {
    if (error) *error = e.what();
    return false;
  }
  stop_worker();
  renderer_ = std::move(r);
  backend_choice_ = b;
  if (!note.empty()) messages.push_back("note: " + note);
  async_ = renderer_->backend_name() == "cpu";
  if (async_) {
    static_cast<tracer::CpuRenderer*>(renderer_.get())->set_cancel_flag(&cancel_);
    start_worker();
  }
  dirty_ = true;
  geometry_dirty_ = true;
  return true;
}

void Workbench::changed(Edit e) {
  if (e == Edit::kDisplay) {
    display_dirty_ = true;
    return;
  }
  if (e == Edit::kGpuOptions) {  // speed only: the accumulator stays
    if (renderer_) renderer_->set_gpu_options(gpu_);
    return;
  }
  dirty_ = true;
  if (e == Edit::kScene || e == Edit::kResize) geometry_dirty_ = true;
  if (async_) cancel_ = true;  // the CPU pass in flight is stale: abandon it now
}

void Workbench::reset_stats() {
  const uint64_t resets = stats_.resets + 1;
  stats_ = WorkbenchStats();
  stats_.resets = resets;
  since_reset_s_ = 0.0;
  next_curve_spp_ = 1;
  display_dirty_ = true;
}

void Workbench::rebuild(bool /*geometry*/) {
  compiled_ = std::make_shared<tracer::CompiledScene>(scene_, scene_.settings.width,
                                                      scene_.settings.height);
  const tracer::IntegratorSettings cfg = tracer::make_integrator_settings(scene_.settings);
  if (async_) {
    std::lock_guard<std::mutex> lk(mutex_);
    worker_scene_ = compiled_;
    worker_cfg_ = cfg;
    worker_reset_ = true;
    ++generation_;
    cancel_ = true;
    published_new_ = false;
    worker_spp_ = 0;
    worker_render_s_ = 0.0;
    worker_relmse_ = -1.0;
    worker_nonfinite_ = 0;
    wake_.notify_all();
  } else {
    renderer_->set_gpu_options(gpu_);
    renderer_->set_scene(*compiled_, cfg);
  }
  reset_stats();
}

bool Workbench::converged() const {
  if (dirty_) return false;  // an edit is waiting to reset the accumulator
  if (target_spp > 0 && stats_.spp >= target_spp) return true;
  if (target_seconds > 0.0 && stats_.elapsed_s >= target_seconds) return true;
  return false;
}

void Workbench::update() {
  if (dirty_) {
    rebuild(geometry_dirty_);
    dirty_ = geometry_dirty_ = false;
  }
  if (async_) {
    tracer::ImageRGB img;  // copied under the lock, compared with the reference after it
    std::unique_lock<std::mutex> lk(mutex_);
    stats_.spp = worker_spp_;
    stats_.last = worker_stats_;
    stats_.ms_per_frame = worker_stats_.ms;
    stats_.elapsed_s = worker_render_s_;
    stats_.samples_per_s = worker_render_s_ > 0 ? worker_spp_ / worker_render_s_ : 0.0;
    const auto& r = worker_stats_.rays;
    stats_.mrays_per_s =
        worker_stats_.ms > 0 ? double(r.camera + r.extension + r.shadow) / worker_stats_.ms / 1e3
                             : 0.0;
    stats_.nonfinite = worker_nonfinite_;
    stats_.relmse_halves = worker_relmse_;
    worker_paused_ = paused;
    worker_target_spp_ = target_spp;
    worker_target_s_ = target_seconds;
    wake_.notify_all();  // targets or pause may have changed
    if (reference_ && (++frames_since_estimate_ >= 30 || stats_.spp >= next_curve_spp_) &&
        !published_mean_.empty() && stats_.spp > 0) {
      frames_since_estimate_ = 0;
      img.width = published_w_;
      img.height = published_h_;
      img.pixels = published_mean_;
    }
    lk.unlock();  // the worker keeps rendering while the image is compared
    if (!img.pixels.empty()) record_reference_error(img);
    return;
  }
  if (paused || converged()) return;
  uint32_t spp = uint32_t(std::max(1, samples_per_frame));
  if (target_spp > 0) spp = std::min(spp, target_spp - stats_.spp);
  const auto start = Clock::now();
  const tracer::FrameStats fs = renderer_->render(spp);
  const double s = seconds_since(start);
  since_reset_s_ += s;
  stats_.spp = renderer_->samples_done();
  stats_.last = fs;
  stats_.ms_per_frame = s * 1e3;
  stats_.elapsed_s = since_reset_s_;
  stats_.samples_per_s = since_reset_s_ > 0 ? stats_.spp / since_reset_s_ : 0.0;
  stats_.mrays_per_s = double(fs.rays.camera + fs.rays.extension + fs.rays.shadow) / s / 1e6;
  stats_.nonfinite = renderer_->nonfinite_total();
  display_dirty_ = true;
  if (auto_samples_per_frame) {
    // Keep the GPU's share of a UI frame near 10 ms so the window stays above 60 frames/s.
    const double per_sample_ms = std::max(1e-3, s * 1e3 / spp);
    samples_per_frame = std::clamp(int(10.0 / per_sample_ms), 1, 1024);
  }
  if (++frames_since_estimate_ >= 30) {
    frames_since_estimate_ = 0;
    stats_.relmse_halves = tracer::half_buffer_relmse(*renderer_);
    if (reference_) record_reference_error(renderer_->image());
  } else if (reference_ && stats_.spp >= next_curve_spp_) {
    record_reference_error(renderer_->image());
  }
}

void Workbench::record_reference_error(const tracer::ImageRGB& img) {
  while (next_curve_spp_ <= stats_.spp) next_curve_spp_ *= 2;
  if (img.width != reference_->mean.width || img.height != reference_->mean.height) {
    stats_.relmse_reference = -1.0;  // the render was resized after the reference was loaded
    return;
  }
  tracer::Checkpoint cp;
  cp.spp = stats_.spp;
  cp.seconds = stats_.elapsed_s;
  cp.error = tracer::error_terms(img, *reference_);
  // Below the reference's own noise the estimate can dip under 0: show 0, not "no reference".
  stats_.relmse_reference = std::max(0.0, cp.error.relmse);
  auto& curve = stats_.error_curve;
  // Log spacing: a new point once time or samples have grown by 5%, at most 1,000 points.
  if (curve.empty() || (cp.spp > curve.back().spp && curve.size() < 1000 &&
                        (cp.seconds > 1.05 * curve.back().seconds ||
                         cp.spp >= 1.05 * curve.back().spp)))
    curve.push_back(cp);
}

bool Workbench::fetch_display(std::vector<uint32_t>& rgba, int& width, int& height) {
  width = scene_.settings.width;
  height = scene_.settings.height;
  if (async_) {
    std::unique_lock<std::mutex> lk(mutex_);
    if (!published_new_ && !display_dirty_) return false;
    published_new_ = false;
    display_dirty_ = false;
    std::vector<float> mean = published_mean_;
    const int w = published_w_, h = published_h_;
    lk.unlock();
    if (w != width || h != height || mean.empty()) {
      rgba.assign(size_t(width) * height, 0xff000000u);
      return true;
    }
    rgba.resize(size_t(w) * h);
    const float scale = display_.scale();
    for (size_t i = 0; i < rgba.size(); ++i)
      rgba[i] = tracer::display_rgba8(vec3(mean[3 * i], mean[3 * i + 1], mean[3 * i + 2]), scale,
                                      display_.tone_map);
    return true;
  }
  if (!display_dirty_) return false;
  display_dirty_ = false;
  renderer_->display_rgba8(rgba, display_.scale(), display_.tone_map);
  return true;
}

void Workbench::start_worker() {
  quit_ = false;
  worker_paused_ = paused;
  worker_target_spp_ = target_spp;
  worker_target_s_ = target_seconds;
  worker_ = std::thread([this] { worker_loop(); });
}

void Workbench::stop_worker() {
  if (!worker_.joinable()) return;
  {
    std::lock_guard<std::mutex> lk(mutex_);
    quit_ = true;
    cancel_ = true;
  }
  wake_.notify_all();
  worker_.join();
}

void Workbench::worker_loop() {
  std::shared_ptr<tracer::CompiledScene> active;
  uint64_t generation = 0;
  std::unique_lock<std::mutex> lk(mutex_);
  for (;;) {
    wake_.wait(lk, [&] {
      const bool done = (worker_target_spp_ > 0 && worker_spp_ >= worker_target_spp_) ||
                        (worker_target_s_ > 0.0 && worker_render_s_ >= worker_target_s_);
      // After an edit (cancel_ set) wait for the new scene instead of spinning on cancelled
      // passes until update() hands it over.
      return quit_ || worker_reset_ || (active && !worker_paused_ && !done && !cancel_);
    });
    if (quit_) return;
    if (worker_reset_) {
      active = worker_scene_;
      renderer_->set_scene(*active, worker_cfg_);
      worker_reset_ = false;
      generation = generation_;
      cancel_ = false;
    }
    lk.unlock();
    const tracer::FrameStats fs = renderer_->render(1);
    lk.lock();
    if (generation != generation_ || fs.spp_added == 0) continue;  // an edit made it stale
    worker_stats_ = fs;
    worker_render_s_ += fs.ms / 1e3;
    worker_spp_ = renderer_->samples_done();
    worker_nonfinite_ = renderer_->nonfinite_total();
    const tracer::ImageRGB img = renderer_->image();
    published_mean_ = img.pixels;
    published_w_ = img.width;
    published_h_ = img.height;
    published_new_ = true;
    if (worker_spp_ % 4 == 0) worker_relmse_ = tracer::half_buffer_relmse(*renderer_);
  }
}

// ---------------------------------------------------------------------------------------------
// Edits by name, for --set, the script file and tests.

std::vector<std::string> Workbench::settable_keys() {
  return {"camera.position", "camera.look_at", "camera.up", "camera.vfov", "camera.aperture",
          "camera.focus_distance", "render.max_depth", "render.spp", "render.time",
          "render.width", "render.height", "render.nee", "render.mis", "render.russian_roulette",
          "render.rr_start_depth", "render.seed", "render.jitter", "render.samples_per_frame",
          "render.clamp", "render.sampler",
          "display.exposure", "display.tonemap", "gpu.kernel", "gpu.compaction", "gpu.tail", "gpu.sort",
          "gpu.cache", "gpu.flat",
          "backend", "materials.NAME.type",
          "materials.NAME.albedo", "materials.NAME.emission", "materials.NAME.emission_strength",
          "materials.NAME.ior", "materials.NAME.fresnel", "materials.NAME.absorption",
          "materials.NAME.two_sided", "materials.NAME.roughness", "materials.NAME.scattering",
          "materials.NAME.g"};
}

bool Workbench::apply(const std::string& assignment, std::string* error) {
  auto fail = [&](const std::string& why) {
    if (error) *error = "\"" + assignment + "\": " + why;
    return false;
  };
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos) return fail("expected KEY=VALUE");
  const std::string key = assignment.substr(0, eq), value = assignment.substr(eq + 1);
  float f[3];
  bool b;
  auto number = [&](float lo, float hi) {
    if (!parse_floats(value, f, 1)) return false;
    return f[0] >= lo && f[0] <= hi;
  };
  tracer::CameraDesc& cam = scene_.camera;
  tracer::RenderSettings& rs = scene_.settings;
  if (key == "camera.position" || key == "camera.look_at" || key == "camera.up") {
    if (!parse_floats(value, f, 3)) return fail("expected three numbers x,y,z");
    vec3& v = key == "camera.position" ? cam.position : key == "camera.look_at" ? cam.look_at : cam.up;
    v = vec3(f[0], f[1], f[2]);
    changed(Edit::kCamera);
  } else if (key == "camera.vfov") {
    if (!number(1.0f, 179.0f)) return fail("expected degrees in [1, 179]");
    cam.vfov_deg = f[0];
    changed(Edit::kCamera);
  } else if (key == "camera.aperture") {
    if (!number(0.0f, 1e6f)) return fail("expected a lens radius >= 0");
    cam.aperture_radius = f[0];
    changed(Edit::kCamera);
  } else if (key == "camera.focus_distance") {
    if (!number(0.0f, 1e9f)) return fail("expected a distance >= 0 (0: distance to look_at)");
    cam.focus_distance = f[0];
    changed(Edit::kCamera);
  } else if (key == "render.max_depth" || key == "render.rr_start_depth") {
    if (!number(1.0f, 1024.0f) || f[0] != std::floor(f[0]))
      return fail("expected a whole number from 1 to 1024");
    (key == "render.max_depth" ? rs.max_depth : rs.rr_start_depth) = int(f[0]);
    changed(Edit::kSettings);
  } else if (key == "render.seed") {
    if (!number(0.0f, 4294967295.0f) || f[0] != std::floor(f[0]))
      return fail("expected a whole number >= 0");
    rs.seed = uint32_t(f[0]);
    changed(Edit::kSettings);
  } else if (key == "render.nee" || key == "render.mis" || key == "render.russian_roulette" ||
             key == "render.jitter") {
    if (!parse_bool(value, &b)) return fail("expected on or off");
    (key == "render.nee" ? rs.nee : key == "render.mis" ? rs.mis
     : key == "render.jitter" ? rs.jitter : rs.russian_roulette) = b;
    changed(Edit::kSettings);
  } else if (key == "render.sampler") {
    if (!tracer::parse_sampler(value, &rs.sampler)) return fail("expected random, sobol or sobol-pairs");
    changed(Edit::kSettings);
  } else if (key == "render.clamp") {
    if (!number(0.0f, 1e30f)) return fail("expected a radiance >= 0 (0: off)");
    rs.clamp = f[0];
    changed(Edit::kSettings);
  } else if (key == "render.spp") {
    if (!number(0.0f, 1e9f)) return fail("expected a sample count (0: no limit)");
    target_spp = uint32_t(f[0]);
  } else if (key == "render.time") {
    if (!number(0.0f, 1e7f)) return fail("expected seconds (0: no limit)");
    target_seconds = f[0];
  } else if (key == "render.samples_per_frame") {
    if (!number(0.0f, 1024.0f)) return fail("expected 0 (automatic) to 1024");
    auto_samples_per_frame = f[0] == 0.0f;
    if (f[0] > 0) samples_per_frame = int(f[0]);
  } else if (key == "render.width" || key == "render.height") {
    if (!number(1.0f, 16384.0f)) return fail("expected 1 to 16384 pixels");
    (key == "render.width" ? rs.width : rs.height) = int(f[0]);
    changed(Edit::kResize);
  } else if (key == "display.exposure") {
    if (!number(-20.0f, 20.0f)) return fail("expected stops in [-20, 20]");
    display_.exposure = f[0];
    changed(Edit::kDisplay);
  } else if (key == "display.tonemap") {
    if (!tracer::parse_tone_map(value, &display_.tone_map))
      return fail("expected none, reinhard or aces");
    changed(Edit::kDisplay);
  } else if (key == "gpu.kernel") {
    if (value == "auto") gpu_.kernel = tracer::KernelMode::kAuto;
    else if (value == "wavefront") gpu_.kernel = tracer::KernelMode::kWavefront;
    else if (value == "megakernel") gpu_.kernel = tracer::KernelMode::kMegakernel;
    else return fail("expected auto, wavefront or megakernel");
    changed(Edit::kGpuOptions);
  } else if (key == "gpu.compaction") {
    if (!tracer::parse_compaction(value, &gpu_.compaction)) {
      if (!parse_bool(value, &b)) return fail("expected on (auto), shade, cub or off");
      gpu_.compaction = b ? tracer::Compaction::kAuto : tracer::Compaction::kOff;
    }
    changed(Edit::kGpuOptions);
  } else if (key == "gpu.tail") {
    if (!number(0.0f, 1.0f)) return fail("expected a fraction of the pixels in [0, 1] (0: off)");
    gpu_.tail_fraction = f[0];
    changed(Edit::kGpuOptions);
  } else if (key == "gpu.sort" || key == "gpu.cache" || key == "gpu.flat") {
    if (!parse_bool(value, &b)) return fail("expected on or off");
    (key == "gpu.sort"    ? gpu_.sort_materials
     : key == "gpu.cache" ? gpu_.first_bounce_cache
                          : gpu_.flat_list) = b;
    changed(Edit::kGpuOptions);
  } else if (key == "backend") {
    tracer::BackendChoice c;
    if (value == "cpu") c = tracer::BackendChoice::kCpu;
    else if (value == "cuda") c = tracer::BackendChoice::kCuda;
    else if (value == "auto") c = tracer::BackendChoice::kAuto;
    else return fail("expected auto, cpu or cuda");
    std::string why;
    if (!set_backend(c, &why)) return fail(why);
  } else if (key.rfind("materials.", 0) == 0) {
    const size_t dot = key.rfind('.');
    const std::string name = key.substr(10, dot - 10), field = key.substr(dot + 1);
    const uint32_t idx = scene_.find_material(name);
    if (idx == tracer::kInvalid) {
      std::vector<std::string> names;
      for (const auto& m : scene_.materials) names.push_back(m.name);
      const std::string guess = tracer::did_you_mean(name, names);
      return fail("no material \"" + name + "\"" +
                  (guess.empty() ? "" : " (did you mean \"" + guess + "\"?)"));
    }
    tracer::Material& m = scene_.materials[idx].material;
    const float strength = tracer::max_component(m.emission);
    if (field == "type") {
      if (value == "diffuse") m.type = tracer::MaterialType::kDiffuse;
      else if (value == "mirror") m.type = tracer::MaterialType::kMirror;
      else if (value == "dielectric") m.type = tracer::MaterialType::kDielectric;
      else if (value == "conductor") m.type = tracer::MaterialType::kConductor;
      else if (value == "subsurface") m.type = tracer::MaterialType::kSubsurface;
      else return fail("expected diffuse, mirror, dielectric, conductor or subsurface");
    } else if (field == "roughness" || field == "g") {
      if (!number(field == "g" ? -0.99f : 0.0f, field == "g" ? 0.99f : 1.0f))
        return fail(field == "g" ? "expected g in (-1, 1)" : "expected roughness in [0, 1]");
      (field == "g" ? m.g : m.roughness) = f[0];
    } else if (field == "albedo" || field == "absorption" || field == "emission" ||
               field == "scattering") {
      if (!parse_floats(value, f, 3)) return fail("expected three numbers r,g,b");
      const vec3 v(f[0], f[1], f[2]);
      if (tracer::max_component(-v) > 0.0f) return fail("components must be >= 0");
      if (field == "albedo") {
        if (tracer::max_component(v) > 1.0f) return fail("albedo components must be <= 1");
        m.albedo = v;
      } else if (field == "absorption") {
        m.absorption = v;
      } else if (field == "scattering") {
        m.scattering = v;
      } else {
        m.emission = v * (strength > 0.0f ? strength : 1.0f);
      }
    } else if (field == "emission_strength") {
      if (!number(0.0f, 1e9f)) return fail("expected a strength >= 0");
      const vec3 colour = strength > 0.0f ? m.emission / strength : vec3(1.0f);
      m.emission = colour * f[0];
    } else if (field == "ior") {
      if (!number(1.0f, 4.0f)) return fail("expected an index of refraction in [1, 4]");
      m.ior = f[0];
    } else if (field == "fresnel") {
      if (value == "exact") m.flags &= ~tracer::kMaterialSchlickFresnel;
      else if (value == "schlick") m.flags |= tracer::kMaterialSchlickFresnel;
      else return fail("expected exact or schlick");
    } else if (field == "two_sided") {
      if (!parse_bool(value, &b)) return fail("expected on or off");
      m.flags = b ? (m.flags | tracer::kMaterialTwoSidedEmission)
                  : (m.flags & ~tracer::kMaterialTwoSidedEmission);
    } else {
      return fail("unknown material field \"" + field + "\"");
    }
    changed(Edit::kMaterial);
  } else {
    const std::string guess = tracer::did_you_mean(key, settable_keys());
    return fail("unknown key" + (guess.empty() ? "" : " (did you mean \"" + guess + "\"?)"));
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

bool Workbench::load_scene(const std::string& path, std::string* error) {
  try {
    tracer::Scene s = tracer::load_scene(path);
    scene_ = std::move(s);
  } catch (const std::exception& e) {
    if (error) *error = e.what();
    return false;
  }
  initial_camera_ = scene_.camera;
  target_spp = uint32_t(std::max(0, scene_.settings.spp));
  selected_object = -1;
  selected_material = 0;
  for (const auto& w : scene_.diagnostics.warnings) messages.push_back("warning: " + w);
  changed(Edit::kScene);
  return true;
}

bool Workbench::load_reference(const std::string& path, std::string* error) {
  try {
    auto ref = std::make_unique<tracer::ReferenceImage>();
    ref->mean = tracer::read_image(path);
    if (ref->mean.width != width() || ref->mean.height != height()) {
      if (error)
        *error = path + ": the reference is " + std::to_string(ref->mean.width) + "x" +
                 std::to_string(ref->mean.height) + " but the render is " +
                 std::to_string(width()) + "x" + std::to_string(height()) +
                 "; not loaded (set the size first, or render a reference of this size)";
      return false;
    }
    const std::string var = tracer::variance_path_for(path);
    if (std::filesystem::exists(var)) {
      ref->variance = tracer::read_image(var);
      if (ref->variance.width != ref->mean.width || ref->variance.height != ref->mean.height)
        ref->variance = tracer::ImageRGB();
    }
    reference_ = std::move(ref);
    const std::string warn = tracer::reference_independence_warning(
        path, scene_.settings.seed, tracer::sampler_name(scene_.settings.sampler));
    if (!warn.empty()) messages.push_back("warning: " + warn);
  } catch (const std::exception& e) {
    if (error) *error = e.what();
    return false;
  }
  stats_.error_curve.clear();
  next_curve_spp_ = 1;
  return true;
}

std::string Workbench::export_image(const std::string& path) {
  try {
    tracer::ImageRGB img;
    uint32_t spp;
    if (async_) {  // the worker may be adding a pass: take what it last published
      std::lock_guard<std::mutex> lk(mutex_);
      img.width = published_w_;
      img.height = published_h_;
      img.pixels = published_mean_;
      spp = worker_spp_;
      if (img.pixels.empty()) return "nothing rendered yet; nothing was exported";
    } else {
      img = renderer_->image();
      spp = renderer_->samples_done();
    }
    tracer::write_image(path, img, display_.exposure, display_.tone_map);
    nlohmann::json j;
    j["scene"] = scene_.source;
    j["output"] = path;
    j["version"] = TRACER_VERSION;
    j["backend"] = renderer_->backend_name();
    j["device"] = renderer_->device_name();
    const auto& rs = scene_.settings;
    j["settings"] = {{"width", rs.width},         {"height", rs.height},
                     {"max_depth", rs.max_depth}, {"nee", rs.nee},
                     {"mis", rs.mis},             {"russian_roulette", rs.russian_roulette},
                     {"rr_start_depth", rs.rr_start_depth}, {"seed", rs.seed},
                     {"jitter", rs.jitter},       {"sampler", tracer::sampler_name(rs.sampler)},
                     {"exposure", display_.exposure},
                     {"tonemap", tracer::tone_map_name(display_.tone_map)}};
    j["camera"] = {{"position", vec_json(scene_.camera.position)},
                   {"look_at", vec_json(scene_.camera.look_at)},
                   {"up", vec_json(scene_.camera.up)},
                   {"vfov", scene_.camera.vfov_deg},
                   {"aperture", scene_.camera.aperture_radius},
                   {"focus_distance", scene_.camera.focus_distance}};
    nlohmann::json mats;
    for (const auto& m : scene_.materials) mats[m.name] = material_json(m.material);
    j["materials"] = mats;
    j["spp"] = spp;
    j["wall_time_s"] = stats_.elapsed_s;
    j["nonfinite_samples"] = stats_.nonfinite;
    tracer::write_text_atomic(path + ".json", j.dump(2) + "\n");
  } catch (const std::exception& e) {
    return e.what();
  }
  messages.push_back("exported " + path);
  return "";
}

std::string Workbench::save_scene(const std::string& path) {
  try {
    nlohmann::json j;
    const std::string& src = scene_.source;
    const bool json_source = src == "<built-in>" ||
                             (src.size() > 5 && src.compare(src.size() - 5, 5, ".json") == 0);
    if (json_source) {
      std::string text;
      if (src == "<built-in>") {
        text = tracer::kBuiltinSceneJson;
      } else {
        std::ifstream f(src);
        if (!f) return src + ": cannot be read again to save the scene; nothing was saved";
        text.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
      }
      j = nlohmann::json::parse(text);
      // Mesh paths are relative to the scene file's folder: make them absolute.
      if (j.contains("objects")) {
        const std::string dir = src == "<built-in>" ? "" : src.substr(0, src.find_last_of('/') + 1);
        for (auto& o : j["objects"])
          if (o.contains("file") && !dir.empty() && o["file"].get<std::string>()[0] != '/')
            o["file"] = dir + o["file"].get<std::string>();
      }
    } else {
      j["objects"] = nlohmann::json::array({{{"type", "mesh"}, {"file", src}}});
      messages.push_back("note: material edits of " + src +
                         " are not saved (the JSON format cannot override a mesh file's own "
                         "materials)");
    }
    const auto& c = scene_.camera;
    j["camera"] = {{"position", vec_json(c.position)}, {"look_at", vec_json(c.look_at)},
                   {"up", vec_json(c.up)},             {"vfov", c.vfov_deg},
                   {"aperture", c.aperture_radius},    {"focus_distance", c.focus_distance}};
    const auto& rs = scene_.settings;
    j["render"] = {{"width", rs.width},         {"height", rs.height},
                   {"spp", std::max<uint32_t>(1, target_spp)},
                   {"max_depth", rs.max_depth}, {"nee", rs.nee},
                   {"mis", rs.mis},             {"russian_roulette", rs.russian_roulette},
                   {"rr_start_depth", rs.rr_start_depth}, {"seed", rs.seed},
                   {"jitter", rs.jitter}, {"clamp", rs.clamp},
                   {"sampler", tracer::sampler_name(rs.sampler)}};
    if (json_source && j.contains("materials")) {
      for (auto it = j["materials"].begin(); it != j["materials"].end(); ++it) {
        const uint32_t idx = scene_.find_material(it.key());
        if (idx != tracer::kInvalid) it.value() = material_json(scene_.materials[idx].material);
      }
    }
    tracer::write_text_atomic(path, j.dump(2) + "\n");
  } catch (const std::exception& e) {
    return e.what();
  }
  messages.push_back("saved scene " + path);
  return "";
}

// ---------------------------------------------------------------------------------------------
// Navigation and picking.

void Workbench::orbit(float dx_deg, float dy_deg) {
  tracer::CameraDesc& c = scene_.camera;
  const vec3 up = glm::normalize(c.up);
  vec3 off = c.position - c.look_at;
  const float r = glm::length(off);
  if (r <= 0.0f) return;
  const float yaw = glm::radians(-dx_deg);
  // Rotate about up (yaw), then about the right axis (pitch), keeping away from the poles.
  const vec3 u = up * glm::dot(up, off);
  const vec3 v = off - u;
  off = u + v * std::cos(yaw) + glm::cross(up, v) * std::sin(yaw);
  const float elev = std::asin(std::clamp(glm::dot(off / r, up), -1.0f, 1.0f));
  const float new_elev = std::clamp(elev + glm::radians(dy_deg), glm::radians(-85.0f),
                                    glm::radians(85.0f));
  vec3 horiz = off - up * glm::dot(up, off);
  if (glm::length(horiz) < 1e-6f * r) return;
  horiz = glm::normalize(horiz);
  c.position = c.look_at + r * (std::cos(new_elev) * horiz + std::sin(new_elev) * up);
  changed(Edit::kCamera);
}

void Workbench::pan(float dx, float dy) {
  tracer::CameraDesc& c = scene_.camera;
  const vec3 fwd = glm::normalize(c.look_at - c.position);
  const vec3 right = glm::normalize(glm::cross(fwd, c.up));
  const vec3 up = glm::cross(right, fwd);
  const float dist = glm::length(c.look_at - c.position);
  const vec3 d = (right * dx + up * dy) * dist;
  c.position += d;
  c.look_at += d;
  changed(Edit::kCamera);
}

void Workbench::zoom(float factor) {
  tracer::CameraDesc& c = scene_.camera;
  c.position = c.look_at + (c.position - c.look_at) * std::clamp(factor, 0.01f, 100.0f);
  changed(Edit::kCamera);
}

void Workbench::fly(float forward, float right_amount, float up_amount) {
  tracer::CameraDesc& c = scene_.camera;
  const vec3 fwd = glm::normalize(c.look_at - c.position);
  const vec3 right = glm::normalize(glm::cross(fwd, c.up));
  const vec3 up = glm::cross(right, fwd);
  const float dist = glm::length(c.look_at - c.position);
  const vec3 d = (fwd * forward + right * right_amount + up * up_amount) * dist;
  c.position += d;
  c.look_at += d;
  changed(Edit::kCamera);
}

void Workbench::reset_view() {
  scene_.camera = initial_camera_;
  changed(Edit::kCamera);
}

tracer::Ray Workbench::camera_ray(float u, float v) const {
  const tracer::Camera cam = tracer::make_camera(scene_.camera, width(), height());
  const float px = u * width(), py = v * height();
  const uint32_t x = uint32_t(std::clamp(px, 0.0f, float(width() - 1)));
  const uint32_t y = uint32_t(std::clamp(py, 0.0f, float(height() - 1)));
  tracer::Camera pinhole = cam;
  pinhole.lens_radius = 0.0f;  // through the lens centre
  return pinhole.generate_ray(x, y, tracer::vec2(px - x, py - y), tracer::vec2(0.5f));
}

int Workbench::pick_object(float u, float v) const {
  if (!compiled_ || u < 0 || v < 0 || u > 1 || v > 1) return -1;
  const tracer::Hit h = tracer::intersect_closest(compiled_->view(), camera_ray(u, v));
  if (!h.valid()) return -1;
  const uint32_t tris = compiled_->view().tri_count;
  for (size_t i = 0; i < scene_.objects.size(); ++i) {
    const tracer::ObjectInfo& o = scene_.objects[i];
    if (o.is_sphere ? (h.prim >= tris && h.prim - tris == o.first)
                    : (h.prim < tris && h.prim >= o.first && h.prim < o.first + o.count))
      return int(i);
  }
  return -1;
}

bool Workbench::focus_at(float u, float v) {
  if (!compiled_) return false;
  const tracer::Ray r = camera_ray(u, v);
  const tracer::Hit h = tracer::intersect_closest(compiled_->view(), r);
  if (!h.valid()) return false;
  const vec3 fwd = glm::normalize(scene_.camera.look_at - scene_.camera.position);
  scene_.camera.focus_distance = h.t * glm::dot(r.d, fwd);  // the plane of focus is normal to fwd
  changed(Edit::kCamera);
  return true;
}

}  // namespace ui
