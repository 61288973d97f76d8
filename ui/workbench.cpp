// The workbench model: edits, accumulator resets, the CPU render thread, navigation, picking,
// export and scene saving.
#include "ui/workbench.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cpu/cpu_backend.h"
#include "image/display.h"
#include "image/image.h"
#include "integrator/export.h"
#include "integrator/gpu_options.h"
#include "integrator/sidecar.h"
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

}  // namespace

Workbench::Workbench(tracer::Scene scene, tracer::BackendChoice backend, int cpu_threads)
    : scene_(std::move(scene)) {
  scene_.settings.backend = backend;
  scene_.settings.threads = cpu_threads;
  initial_camera_ = scene_.camera;
  if (scene_.settings.samples_per_frame > 0) samples_per_frame = scene_.settings.samples_per_frame;
  take_scene_warnings();
  select_object(scene_.objects.empty() ? -1 : 0);
  std::string error;
  if (!set_backend(backend, &error)) {
    messages.error(error + "; using the CPU backend");
    set_backend(tracer::BackendChoice::kCpu, &error);
  }
}

struct Workbench::Load {
  std::string path;
  Clock::time_point start = Clock::now();
  std::atomic<int> stage{0};  // 0: reading the file; 1: building the BVH and the GPU's arrays
  std::atomic<bool> done{false};
  tracer::Scene scene;
  std::shared_ptr<tracer::CompiledScene> compiled;
  std::string error;
  std::thread thread;
};

Workbench::~Workbench() {
  if (load_) load_->thread.join();
  stop_worker();
}

bool Workbench::start_loading(const std::string& path, std::string* error) {
  if (load_) {
    if (error) *error = "still loading " + load_->path + "; wait for it before loading another";
    return false;
  }
  load_ = std::make_unique<Load>();
  load_->path = path;
  const tracer::BackendChoice backend = scene_.settings.backend;
  const int threads = scene_.settings.threads;
  Load* l = load_.get();
  l->thread = std::thread([l, backend, threads] {
    try {
      tracer::Scene s = tracer::load_scene(l->path);
      tracer::flatten_small_instances(s);
      // The renderer running now stays: its settings are the window's, not the file's.
      s.settings.backend = backend;
      s.settings.threads = threads;
      l->stage = 1;
      l->compiled =
          std::make_shared<tracer::CompiledScene>(s, s.settings.width, s.settings.height);
      l->scene = std::move(s);
    } catch (const std::exception& e) {
      l->error = e.what();
    }
    l->done = true;
  });
  last_load_.clear();
  return true;
}

std::string Workbench::loading_status() const {
  if (!load_) return last_load_;
  char buf[64];
  std::snprintf(buf, sizeof buf, " (%.1f s)", seconds_since(load_->start));
  return std::filesystem::path(load_->path).filename().string() +
         (load_->stage == 0 ? ": reading the file" : ": building the BVH") + buf;
}

bool Workbench::finish_loading(bool wait, std::string* error) {
  if (!load_ || (!wait && !load_->done)) return false;
  load_->thread.join();
  const std::unique_ptr<Load> l = std::move(load_);
  const std::string name = std::filesystem::path(l->path).filename().string();
  if (!l->error.empty()) {
    last_load_ = "error: " + l->error;
    if (error) *error = l->error;
    else messages.error(l->error + " (the scene shown stays)");
    return false;
  }
  char buf[128];
  const size_t spheres = l->scene.spheres.size();
  std::snprintf(buf, sizeof buf, ": %zu triangles%s in %.1f s", l->scene.mesh.indices.size(),
                spheres ? (", " + std::to_string(spheres) + " spheres").c_str() : "",
                seconds_since(l->start));
  last_load_ = "loaded " + name + buf;
  scene_ = std::move(l->scene);
  initial_camera_ = scene_.camera;
  scene_warnings_taken_ = scene_notes_taken_ = 0;
  take_scene_warnings();
  selected_material = 0;
  select_object(scene_.objects.empty() ? -1 : 0);
  changed(Edit::kScene);
  ready_compiled_ = l->compiled;  // after changed(), which drops any
  return true;
}

std::string Workbench::backend_name() const { return renderer_ ? renderer_->backend_name() : ""; }
std::string Workbench::device_name() const { return renderer_ ? renderer_->device_name() : ""; }

tracer::Renderer* Workbench::gpu_renderer() {
  return renderer_ && renderer_->backend_name() == "cuda" ? renderer_.get() : nullptr;
}

bool Workbench::set_backend(tracer::BackendChoice b, std::string* error) {
  std::unique_ptr<tracer::Renderer> r;
  std::string note;
  try {
    r = tracer::make_renderer(b, scene_.settings.threads, &note);
  } catch (const std::exception& e) {
    if (error) *error = e.what();
    return false;
  }
  stop_worker();
  renderer_ = std::move(r);
  scene_.settings.backend = b;
  if (!note.empty()) messages.note(note);
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
    display_dirty_ = view_dirty_ = true;
    return;
  }
  if (e == Edit::kStop) {  // the accumulator stays; the CPU worker sees the new target
    if (scene_.settings.samples_per_frame > 0) samples_per_frame = scene_.settings.samples_per_frame;
    std::lock_guard<std::mutex> lk(mutex_);
    worker_target_spp_ = target_spp();
    worker_target_s_ = target_seconds();
    wake_.notify_all();
    return;
  }
  if (e == Edit::kGpuOptions) {  // speed only: the accumulator stays
    if (renderer_) renderer_->set_gpu_options(scene_.gpu);
    return;
  }
  dirty_ = true;
  ready_compiled_.reset();  // a loaded scene's compiled form no longer matches the edited scene
  if (e == Edit::kScene || e == Edit::kResize) geometry_dirty_ = true;
  if (async_) cancel_ = true;  // the CPU pass in flight is stale: abandon it now
}

void Workbench::reset_stats() {
  const uint64_t resets = stats_.resets + 1;
  stats_ = WorkbenchStats();
  stats_.resets = resets;
  since_reset_s_ = 0.0;
  next_curve_spp_ = 1;
  display_dirty_ = view_dirty_ = true;
}

void Workbench::rebuild(bool geometry) {
  // An edit that keeps the triangles and spheres shares the BVHs of the scene before it.
  compiled_ = ready_compiled_ ? std::move(ready_compiled_)
                              : std::make_shared<tracer::CompiledScene>(
                                    scene_, scene_.settings.width, scene_.settings.height,
                                    geometry ? nullptr : compiled_.get());
  ready_compiled_.reset();
  mnee_casters_ = tracer::mnee_has_casters(*compiled_);
  const tracer::IntegratorSettings cfg = tracer::make_integrator_settings(scene_.settings);
  light_yield_ = scene_.settings.light_tracing ? tracer::light_path_yield(*compiled_, cfg) : 1.0f;
  if (!async_) {
    try {
      renderer_->set_gpu_options(scene_.gpu);
      renderer_->set_scene(*compiled_, cfg);
      reset_stats();
      return;
    } catch (const std::exception& e) {
      // E.g. more than the GPU's free memory (the message says what is needed and free): the
      // CPU backend renders the scene instead of the window ending.
      std::string err;
      if (!set_backend(tracer::BackendChoice::kCpu, &err)) throw;
      messages.error(std::string(e.what()) + "; switched to the CPU backend");
    }
  }
  {
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
  }
  reset_stats();
}

bool Workbench::converged() const {
  if (dirty_) return false;  // an edit is waiting to reset the accumulator
  if (target_spp() > 0 && stats_.spp >= target_spp()) return true;
  if (target_seconds() > 0.0 && stats_.elapsed_s >= target_seconds()) return true;
  return false;
}

void Workbench::take_scene_warnings() {
  const std::vector<std::string>& w = scene_.diagnostics.warnings;
  for (; scene_warnings_taken_ < w.size(); ++scene_warnings_taken_)
    messages.warning(w[scene_warnings_taken_]);
  // Notes: the loader's choices (a framing camera, a default light), shown once like warnings.
  const std::vector<std::string>& n = scene_.diagnostics.notes;
  for (; scene_notes_taken_ < n.size(); ++scene_notes_taken_)
    messages.note(n[scene_notes_taken_]);
}

void Workbench::select_object(int i) {
  selected_object = i >= 0 && i < int(scene_.objects.size()) ? i : -1;
  const int m = material_of(selected_object);
  if (m >= 0) selected_material = m;
}

int Workbench::material_of(int object) const {
  if (object < 0 || object >= int(scene_.objects.size())) return -1;
  const tracer::ObjectInfo& o = scene_.objects[size_t(object)];
  // A mesh object's material is its first triangle's (an OBJ or glTF file may use several).
  if (o.is_sphere)
    return o.first < scene_.spheres.size() ? int(scene_.spheres[o.first].material) : -1;
  if (o.is_instances) {
    if (o.first >= scene_.instances.size()) return -1;
    const uint32_t mesh = scene_.instances[o.first].mesh;
    if (mesh >= scene_.instanced_meshes.size()) return -1;
    const auto& mats = scene_.instanced_meshes[mesh].mesh.materials;
    return mats.empty() ? -1 : int(mats[0]);
  }
  if (o.count == 0 || o.first >= scene_.mesh.materials.size()) return -1;
  return int(scene_.mesh.materials[o.first]);
}

void Workbench::update() {
  finish_loading(false, nullptr);  // a background load that is ready replaces the scene
  take_scene_warnings();  // e.g. validation's, after an edit
  if (dirty_) {
    rebuild(geometry_dirty_);
    dirty_ = geometry_dirty_ = false;
  }
  // The denoiser is guided by the albedo and normal AOVs: they are on while it is.
  const bool want_aovs =
      scene_.display.denoise != tracer::DenoiseMode::kOff || aov_view();
  if (async_) {
    tracer::ImageRGB img;  // copied under the lock, compared with the reference after it
    std::unique_lock<std::mutex> lk(mutex_);
    worker_aovs_ = want_aovs;
    stats_.spp = worker_spp_;
    stats_.last = worker_stats_;
    stats_.guide = worker_guide_;
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
    worker_target_spp_ = target_spp();
    worker_target_s_ = target_seconds();
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
  if (renderer_->aovs() != want_aovs) renderer_->set_aovs(want_aovs);
  if (paused || converged()) return;
  uint32_t spp = uint32_t(std::max(1, samples_per_frame));
  if (target_spp() > 0) spp = std::min(spp, target_spp() - stats_.spp);
  const auto start = Clock::now();
  const tracer::FrameStats fs = renderer_->render(spp);
  const double s = seconds_since(start);
  since_reset_s_ += s;
  stats_.spp = renderer_->samples_done();
  stats_.last = fs;
  stats_.guide = renderer_->guide_status();
  stats_.ms_per_frame = s * 1e3;
  stats_.elapsed_s = since_reset_s_;
  stats_.samples_per_s = since_reset_s_ > 0 ? stats_.spp / since_reset_s_ : 0.0;
  stats_.mrays_per_s = double(fs.rays.camera + fs.rays.extension + fs.rays.shadow) / s / 1e6;
  stats_.nonfinite = renderer_->nonfinite_total();
  display_dirty_ = true;
  if (auto_samples_per_frame()) {
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

bool Workbench::denoise_view() const {
  return scene_.display.denoise != tracer::DenoiseMode::kOff && tracer::denoiser_available();
}

std::string Workbench::shown_image() const {
  if (aov_view()) {
    static const char* kNames[] = {"image", "albedo", "normal", "depth", "id"};
    return std::string("shown: the ") + kNames[int(scene_.display.view)] +
           " AOV (display.view; the image accumulates behind it)";
  }
  if (scene_.display.denoise == tracer::DenoiseMode::kOff) return "shown: the raw image";
  if (!tracer::denoiser_available())
    return "shown: the raw image; the denoiser is absent: " + tracer::denoiser_status();
  if (!denoise_error_.empty()) return "shown: the raw image; the denoiser failed: " + denoise_error_;
  if (denoised_reset_ != stats_.resets || denoised_.pixels.empty())
    return "shown: the raw image (the denoiser waits for the AOVs)";
  char buf[256];
  std::snprintf(buf, sizeof buf, "shown: denoised at %u spp by %s (%s, %s, %.1f ms); biased",
                denoised_spp_, denoise_info_.denoiser.c_str(), denoise_info_.device.c_str(),
                denoise_info_.inputs.c_str(), denoise_info_.ms);
  return buf;
}

uint32_t Workbench::shown_denoised_spp() const {
  const bool shown = denoise_view() && denoise_error_.empty() &&
                     denoised_reset_ == stats_.resets && !denoised_.pixels.empty();
  return shown ? denoised_spp_ : 0;
}

void Workbench::current_image(tracer::ImageRGB* img, tracer::AovImages* aovs, uint32_t* spp) {
  if (async_) {
    std::lock_guard<std::mutex> lk(mutex_);
    img->width = published_w_;
    img->height = published_h_;
    img->pixels = published_mean_;
    if (aovs) *aovs = published_aovs_;
    *spp = worker_spp_;
    return;
  }
  *img = renderer_->image();
  if (aovs) *aovs = renderer_->aov_images();
  *spp = renderer_->samples_done();
}

bool Workbench::try_denoise() {
  const uint32_t spp = stats_.spp;
  if (spp == 0) return false;
  const bool new_accumulation = denoised_reset_ != stats_.resets;
  const bool due = new_accumulation ||
                   (spp > denoised_spp_ &&
                    (seconds_since(denoised_at_) >= kDenoiseInterval || converged() || paused));
  if (!due) return false;
  uint32_t at = 0;
  try {
    if (async_) {
      tracer::ImageRGB img;
      tracer::AovImages aovs;
      current_image(&img, &aovs, &at);
      if (img.pixels.empty() || aovs.empty() || img.width != aovs.albedo.width ||
          img.height != aovs.albedo.height)
        return false;  // the AOVs start with the next sample
      denoised_ = tracer::denoise_image(img, &aovs.albedo, &aovs.normal, &denoise_info_);
    } else {
      if (renderer_->aov_samples() == 0) return false;  // they start with the next sample
      at = renderer_->samples_done();
      denoised_ = renderer_->denoised_image(&denoise_info_);  // the GPU's in device memory
    }
  } catch (const std::exception& e) {
    if (denoise_error_ != e.what()) messages.error(e.what());
    denoise_error_ = e.what();
    return false;
  }
  denoise_error_.clear();
  denoised_spp_ = at;
  denoised_reset_ = stats_.resets;
  denoised_at_ = Clock::now();
  return true;
}

bool Workbench::fetch_display(std::vector<uint32_t>& rgba, int& width, int& height) {
  width = scene_.settings.width;
  height = scene_.settings.height;
  if (aov_view()) {
    // Redrawn when asked to (a display edit) or, while samples come in, at most every
    // kDenoiseInterval seconds (each draw copies the AOVs to the host).
    if (!view_dirty_ && (stats_.spp == aov_view_spp_ ||
                         seconds_since(aov_view_at_) < kDenoiseInterval))
      return false;
    view_dirty_ = false;
    tracer::ImageRGB img;
    tracer::AovImages aovs;
    uint32_t at = 0;
    current_image(&img, &aovs, &at);
    display_dirty_ = false;
    aov_view_at_ = Clock::now();
    aov_view_spp_ = stats_.spp;
    rgba.assign(size_t(width) * height, 0xff000000u);
    if (aovs.empty() || aovs.albedo.width != width || aovs.albedo.height != height)
      return true;  // black until the AOVs' first sample
    static const char* kNames[] = {"image", "albedo", "normal", "depth", "id"};
    const tracer::ImageRGB v = tracer::aov_preview(aovs, kNames[int(scene_.display.view)]);
    for (size_t i = 0; i < rgba.size(); ++i)
      rgba[i] = tracer::display_rgba8(vec3(v.pixels[3 * i], v.pixels[3 * i + 1], v.pixels[3 * i + 2]),
                                      1.0f, tracer::ToneMap::kNone);
    return true;
  }
  if (denoise_view()) {
    const bool fresh = try_denoise();
    if (denoised_reset_ == stats_.resets && denoised_.width == width &&
        denoised_.height == height) {
      // Redrawn for a new denoised image or a display edit, not for every rendered frame.
      if (!fresh && !view_dirty_) return false;
      display_dirty_ = view_dirty_ = false;
      rgba.resize(size_t(width) * height);
      const float scale = scene_.display.scale();
      const std::vector<float>& d = denoised_.pixels;
      for (size_t i = 0; i < rgba.size(); ++i)
        rgba[i] = tracer::display_rgba8(vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]), scale,
                                        scene_.display.tone_map);
      return true;
    }
  }
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
    const float scale = scene_.display.scale();
    for (size_t i = 0; i < rgba.size(); ++i)
      rgba[i] = tracer::display_rgba8(vec3(mean[3 * i], mean[3 * i + 1], mean[3 * i + 2]), scale,
                                      scene_.display.tone_map);
    return true;
  }
  if (!display_dirty_) return false;
  display_dirty_ = false;
  renderer_->display_rgba8(rgba, scene_.display.scale(), scene_.display.tone_map);
  return true;
}

void Workbench::start_worker() {
  quit_ = false;
  worker_paused_ = paused;
  worker_target_spp_ = target_spp();
  worker_target_s_ = target_seconds();
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
    if (renderer_->aovs() != worker_aovs_) renderer_->set_aovs(worker_aovs_);
    lk.unlock();
    const tracer::FrameStats fs = renderer_->render(1);
    tracer::AovImages aovs = renderer_->aovs() ? renderer_->aov_images() : tracer::AovImages();
    lk.lock();
    if (generation != generation_ || fs.spp_added == 0) continue;  // an edit made it stale
    worker_stats_ = fs;
    worker_guide_ = renderer_->guide_status();
    worker_render_s_ += fs.ms / 1e3;
    worker_spp_ = renderer_->samples_done();
    worker_nonfinite_ = renderer_->nonfinite_total();
    const tracer::ImageRGB img = renderer_->image();
    published_mean_ = img.pixels;
    published_w_ = img.width;
    published_h_ = img.height;
    published_aovs_ = std::move(aovs);
    published_new_ = true;
    if (worker_spp_ % 4 == 0) worker_relmse_ = tracer::half_buffer_relmse(*renderer_);
  }
}

bool Workbench::environment_preview(std::vector<uint32_t>& rgba, int& width, int& height) {
  const tracer::EnvironmentDesc& e = scene_.environment;
  const tracer::EnvironmentImage* img = e.file.empty() ? nullptr : scene_.environment_image.get();
  char key[256];
  std::snprintf(key, sizeof key, "%p %g %g %g %g %g %d", static_cast<const void*>(img),
                double(e.strength), double(e.color.x), double(e.color.y), double(e.color.z),
                double(scene_.display.exposure), int(scene_.display.tone_map));
  if (preview_key_ == key) return false;
  preview_key_ = key;
  const float scale = scene_.display.scale();
  width = height = 0;
  rgba.clear();
  if (img && img->width > 0) {
    width = std::min(256, img->width);
    height = std::max(1, int(std::lround(double(img->height) * width / img->width)));
    rgba.resize(size_t(width) * size_t(height));
    // Each preview texel averages the map's texels it covers (a box filter).
    for (int y = 0; y < height; ++y) {
      const int y0 = y * img->height / height,
                y1 = std::max(y0 + 1, (y + 1) * img->height / height);
      for (int x = 0; x < width; ++x) {
        const int x0 = x * img->width / width, x1 = std::max(x0 + 1, (x + 1) * img->width / width);
        vec3 sum(0.0f);
        for (int j = y0; j < y1; ++j)
          for (int i = x0; i < x1; ++i) {
            const float* t = &img->rgba[4 * (size_t(j) * size_t(img->width) + size_t(i))];
            sum += vec3(t[0], t[1], t[2]);
          }
        sum *= e.strength / float((y1 - y0) * (x1 - x0));
        rgba[size_t(y) * size_t(width) + size_t(x)] =
            tracer::display_rgba8(sum, scale, scene_.display.tone_map);
      }
    }
  } else if (e.file.empty() && tracer::max_component(e.color) > 0.0f) {
    width = 64;
    height = 16;
    rgba.assign(size_t(width) * size_t(height),
                tracer::display_rgba8(e.color * e.strength, scale, scene_.display.tone_map));
  }
  return true;
}

std::string Workbench::environment_summary() const {
  return tracer::describe_environment(scene_);
}

// ---------------------------------------------------------------------------------------------
// Edits by name, for --set, the script file and tests.

Edit edit_of(tracer::SettingEffect e) {
  using E = tracer::SettingEffect;
  switch (e) {
    case E::kDisplay: return Edit::kDisplay;
    case E::kCamera: return Edit::kCamera;
    case E::kImage: return Edit::kSettings;
    case E::kResize: return Edit::kResize;
    case E::kGpu: return Edit::kGpuOptions;
    case E::kStop: return Edit::kStop;
    case E::kBackend: return Edit::kSettings;
  }
  return Edit::kSettings;
}

bool Workbench::set(const tracer::Setting& s, const nlohmann::json& value, std::string* error) {
  std::string problem = tracer::check_setting(s, value);
  if (problem.empty() && s.effect == tracer::SettingEffect::kBackend) {
    // A new renderer: when it cannot be made, the old one and the old setting stay.
    const tracer::RenderSettings old = scene_.settings;
    s.put(scene_, value);
    if (!set_backend(scene_.settings.backend, &problem)) scene_.settings = old;
    else return true;
  } else if (problem.empty()) {
    const tracer::CameraDesc old_camera = scene_.camera;
    problem = tracer::set_setting(scene_, s, value);   // with its load hook (environment.file)
    if (problem.empty() && s.section() == "camera") {  // the camera's settings go together
      problem = tracer::check_camera(scene_);
      if (!problem.empty()) scene_.camera = old_camera;
    }
    take_scene_warnings();  // what a load hook found (negative texels in a map)
  }
  if (!problem.empty()) {
    if (error) *error = problem;
    return false;
  }
  changed(edit_of(s.effect));
  return true;
}

bool Workbench::apply(const std::string& assignment, std::string* error) {
  auto fail = [&](const std::string& why) {
    if (error) *error = "\"" + assignment + "\": " + why;
    return false;
  };
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos) return fail("expected KEY=VALUE");
  const std::string key = assignment.substr(0, eq);
  if (key.rfind("materials.", 0) == 0) {
    const std::string problem = tracer::set_material_assignment(scene_, assignment);
    if (!problem.empty()) return fail(problem);
    changed(Edit::kMaterial);
    return true;
  }
  if (key.rfind("lights.", 0) == 0) {
    const std::string problem = tracer::set_light_assignment(scene_, assignment);
    if (!problem.empty()) return fail(problem);
    changed(Edit::kSettings);  // the light list and its CDF are rebuilt
    return true;
  }
  const tracer::Setting* s = tracer::find_setting(key);
  if (!s) return fail(tracer::unknown_setting_message(key));
  nlohmann::json value;
  std::string problem = tracer::parse_setting_text(*s, assignment.substr(eq + 1), &value);
  if (problem.empty() && !set(*s, value, &problem)) return fail(problem);
  if (!problem.empty()) return fail(problem);
  return true;
}

// ---------------------------------------------------------------------------------------------

bool Workbench::load_scene(const std::string& path, std::string* error) {
  std::string err;
  if (!start_loading(path, &err) || !finish_loading(true, &err)) {
    if (error) *error = err;
    return false;
  }
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
    if (!warn.empty()) messages.warning(warn);
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
    tracer::AovImages aovs;
    uint32_t spp = 0;
    tracer::check_writable(path);  // a path that cannot be written is the first thing to say
    // The worker may be adding a pass: this takes what it last published.
    current_image(&img, &aovs, &spp);
    if (img.pixels.empty() || spp == 0) return "nothing rendered yet; nothing was exported";
    // With the denoiser on the AOVs exist: they go with the image (EXR layers or PNGs beside).
    tracer::AovRequest request;
    if (!aovs.empty()) request.albedo = request.normal = request.depth = request.id = true;
    tracer::SidecarRun run;
    run.output = path;
    run.backend = renderer_->backend_name();
    run.device = renderer_->device_name();
    run.spp = spp;
    run.wall_time_s = stats_.elapsed_s;
    run.nonfinite = stats_.nonfinite;
    run.last = stats_.last;
    if (compiled_) run.features = tracer::describe_features(compiled_->features());
    run.aov_samples = aovs.empty() ? 0 : (async_ ? spp : renderer_->aov_samples());
    tracer::export_render(path, img, &aovs, request, scene_, run);
  } catch (const std::exception& e) {
    return e.what();
  }
  take_scene_warnings();
  messages.info("exported " + path);
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
      messages.note("material edits of " + src +
                    " are not saved (the JSON format cannot override a mesh file's own "
                    "materials)");
    }
    // Every setting of the table but the machine's choices (backend, threads), so that the
    // file opens the same way anywhere.
    nlohmann::json settings = tracer::settings_to_json(scene_);
    settings["render"].erase("backend");
    settings["render"].erase("threads");
    for (auto it = settings.begin(); it != settings.end(); ++it) j[it.key()] = it.value();
    // The lights as edited (the Lights panel, lights.NAME.FIELD), also those of a pbrt scene.
    if (!scene_.distant_lights.empty() || !scene_.point_lights.empty())
      j["lights"] = tracer::lights_to_json(scene_.distant_lights, scene_.point_lights);
    else
      j.erase("lights");
    if (json_source && j.contains("materials")) {
      for (auto it = j["materials"].begin(); it != j["materials"].end(); ++it) {
        const uint32_t idx = scene_.find_material(it.key());
        if (idx != tracer::kInvalid) it.value() = tracer::material_to_json(scene_.materials[idx].material);
      }
    }
    tracer::write_text_atomic(path, tracer::json_text(j));
  } catch (const std::exception& e) {
    return e.what();
  }
  messages.info("saved scene " + path);
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
  const tracer::SceneView& view = compiled_->view();
  const uint32_t tris = view.tri_count;
  // An instanced triangle: the instance it belongs to (hit ids run over the instances in order,
  // each its mesh's triangle count, after the triangles and spheres).
  uint32_t instance = tracer::kInvalid;
  if (h.prim >= tris && h.prim - tris >= view.sphere_count) {
    uint64_t base = uint64_t(tris) + view.sphere_count;
    for (size_t i = 0; i < scene_.instances.size(); ++i) {
      base += scene_.instanced_meshes[scene_.instances[i].mesh].mesh.indices.size();
      if (h.prim < base) {
        instance = uint32_t(i);
        break;
      }
    }
  }
  for (size_t i = 0; i < scene_.objects.size(); ++i) {
    const tracer::ObjectInfo& o = scene_.objects[i];
    if (o.is_instances ? (instance != tracer::kInvalid && instance >= o.first &&
                          instance - o.first < o.count)
        : o.is_sphere  ? (h.prim >= tris && h.prim - tris == o.first)
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
