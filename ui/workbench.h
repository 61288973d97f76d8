// The workbench model behind the window: the scene being edited, the renderer filling the
// progressive accumulator, what each edit resets, camera navigation, picking, export and scene
// saving. No GL and no ImGui here, so it is tested without a window.
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <thread>
#include <vector>

#include "backends/backend_select.h"
#include "image/convergence.h"
#include "image/denoise.h"
#include "integrator/renderer.h"
#include "scene/compiled_scene.h"
#include "scene/scene.h"
#include "ui/messages.h"

namespace ui {

using tracer::vec3;

// What an edit touched. Everything but kDisplay changes the expected image and so resets the
// accumulator in the same frame; kDisplay (exposure, tone map) only changes how it is shown.
// kStop (the stop condition and samples per frame) neither.
enum class Edit { kDisplay, kCamera, kMaterial, kSettings, kGpuOptions, kResize, kScene, kStop };
// The edit a setting of the settings table makes (its SettingEffect).
Edit edit_of(tracer::SettingEffect e);

using tracer::DisplaySettings;

struct WorkbenchStats {
  uint32_t spp = 0;
  double ms_per_frame = 0.0;       // wall time of the last UI frame's rendering
  double samples_per_s = 0.0;      // samples per pixel per second, recent
  double mrays_per_s = 0.0;
  double elapsed_s = 0.0;          // since the last reset
  uint64_t nonfinite = 0;
  tracer::FrameStats last;         // stage times, alive per bounce, kernel, notes
  double relmse_halves = -1.0;     // convergence estimate (half buffers), < 0 when unknown
  double relmse_reference = -1.0;  // against a loaded reference image, < 0 when none
  // relMSE against the reference over time since the last reset: a point at every doubling of
  // the sample count and every estimate after it (the Stats panel draws it log-log).
  std::vector<tracer::Checkpoint> error_curve;
  uint64_t resets = 0;             // how many times the accumulator was cleared
  tracer::GuideStatus guide;       // path guiding's training (off unless render.guiding)
};

class Workbench {
 public:
  Workbench(tracer::Scene scene, tracer::BackendChoice backend, int cpu_threads = 0);
  ~Workbench();

  // --- state the panels edit directly; call changed() afterwards ---------------------------
  tracer::Scene& scene() { return scene_; }
  tracer::RenderSettings& settings() { return scene_.settings; }
  tracer::GpuOptions& gpu_options() { return scene_.gpu; }
  DisplaySettings& display() { return scene_.display; }
  // GPU: samples added per UI frame; adapted to the frame rate when render.samples_per_frame
  // is 0, else that.
  int samples_per_frame = 1;
  bool auto_samples_per_frame() const { return scene_.settings.samples_per_frame == 0; }
  // The stop condition: render.spp and render.time_limit_s (0: no limit).
  uint32_t target_spp() const { return uint32_t(std::max(0, scene_.settings.spp)); }
  double target_seconds() const { return scene_.settings.time_limit_s; }
  bool paused = false;
  // The object selected in the list or the viewport (-1: none) and the material the Material
  // panel edits: the selected object's when one is selected, else any the user picks.
  int selected_object = -1;
  int selected_material = 0;
  // Selects object i (-1: none) and opens its material. A new scene selects its first object.
  void select_object(int i);
  int material_of(int object) const;  // index into scene().materials, or -1

  void changed(Edit e);

  // --- per UI frame ------------------------------------------------------------------------
  // Applies pending edits (resetting in the same frame) and renders this frame's samples.
  void update();
  const WorkbenchStats& stats() const { return stats_; }
  bool converged() const;  // target spp or time reached
  // The display image as RGBA8 (top row first); false when nothing new since the last call.
  bool fetch_display(std::vector<uint32_t>& rgba, int& width, int& height);
  tracer::Renderer* gpu_renderer();  // the CUDA renderer when it is the active backend
  // Whether the scene has anything manifold NEE connects through or off (mnee_has_casters).
  bool mnee_has_casters() const { return mnee_casters_; }
  // Light tracing's pilot (light_path_yield; 1 while light tracing is off): the share of its
  // light paths that reach the camera, -1 where it finds none at all.
  float light_path_yield() const { return light_yield_; }
  // The denoiser on the viewport (display.denoise, image/denoise.h): on and available. It
  // denoises the mean that is shown, never the accumulator (toggling it never restarts), at
  // once after each restart and then at most every kDenoiseInterval seconds or when the render
  // stops (converged or paused); fetch_display shows the result.
  bool denoise_view() const;
  static constexpr double kDenoiseInterval = 0.5;
  // One line for the Stats panel: which image is shown and, when denoised, by what from what.
  std::string shown_image() const;
  // The viewport shows a denoised image, of this many samples per pixel (0: the raw image).
  uint32_t shown_denoised_spp() const;
  // The viewport shows an AOV (display.view), not the image: it goes through host memory.
  bool aov_view() const { return scene_.display.view != tracer::ViewMode::kImage; }
  int width() const { return scene_.settings.width; }
  int height() const { return scene_.settings.height; }
  std::string backend_name() const;
  std::string device_name() const;

  // --- actions -----------------------------------------------------------------------------
  // Any key of the settings table or a material field, in the --set language:
  // "materials.glass.ior=1.7", "camera.vfov=50", "display.exposure=1", "render.nee=off", ...
  bool apply(const std::string& assignment, std::string* error);
  // Sets one setting of the table to a value of its type (as the panels do), then changed().
  bool set(const tracer::Setting& s, const nlohmann::json& value, std::string* error);
  bool set_backend(tracer::BackendChoice b, std::string* error);
  // Loads a scene file and waits for it (scripts, tests); on an error the old scene stays.
  bool load_scene(const std::string& path, std::string* error);
  // Loads a scene file on a background thread (reading it, then the BVH and the rest of the
  // compiled scene) while the old scene stays on screen and goes on rendering; update() swaps
  // the new one in when it is ready, or posts the error and keeps the old one. False, with the
  // reason, while another load runs.
  bool start_loading(const std::string& path, std::string* error);
  bool loading() const { return load_ != nullptr; }
  // While loading: "terrain_10m.json: building the BVH (3.2 s)"; afterwards what the last load
  // did: "loaded terrain_10m.json: 10008338 triangles in 4.1 s" or its error.
  std::string loading_status() const;
  // Writes the current image (PNG tone-mapped with the display settings, or EXR linear) and its
  // JSON sidecar, atomically. Returns "" or the error.
  std::string export_image(const std::string& path);
  std::string save_scene(const std::string& path);  // JSON that reloads every edit
  // An EXR/PNG of the current render size; "<stem>.variance.exr" beside it (written by
  // `pathtracer bench --error`) is loaded too, and its noise is subtracted from the relMSE.
  bool load_reference(const std::string& path, std::string* error);

  // Camera navigation (orbit about look_at, pan, dolly, fly) and picking in image coordinates
  // u, v in [0, 1] from the top-left corner.
  void orbit(float dx_deg, float dy_deg);
  void pan(float dx, float dy);
  void zoom(float factor);
  void fly(float forward, float right, float up);
  void reset_view();
  int pick_object(float u, float v) const;   // index into scene().objects, or -1
  bool focus_at(float u, float v);          // sets focus_distance to the hit under (u, v)

  // A small picture of the environment for the Environment panel: the map as stored (at most
  // 256 texels wide), times environment.strength, through the display's exposure and tone map;
  // a constant environment as a swatch; 0 x 0 without an environment. False when it is the same
  // as the last call's.
  bool environment_preview(std::vector<uint32_t>& rgba, int& width, int& height);
  // "1024x512 equirect (auto), 596 negative texels clamped" or "constant colour" or "none".
  std::string environment_summary() const;

  // Messages for the UI and stderr (errors, warnings with the scene's own, notes), newest last.
  MessageLog messages;

 private:
  void rebuild(bool geometry);
  struct Load;
  // Installs a finished background load (waiting for it when `wait`); true when a new scene was
  // installed, false when none was ready or it failed (the error in *error, else in messages).
  bool finish_loading(bool wait, std::string* error);
  std::unique_ptr<Load> load_;
  std::string last_load_;  // loading_status() after a load
  // A compiled scene that came with a load, taken by the next rebuild() unless an edit came
  // first (changed() drops it).
  std::shared_ptr<tracer::CompiledScene> ready_compiled_;
  void start_worker();
  void stop_worker();
  void worker_loop();
  void reset_stats();
  void take_scene_warnings();  // the scene's diagnostics not yet in `messages`
  tracer::Ray camera_ray(float u, float v) const;

  tracer::Scene scene_;
  tracer::CameraDesc initial_camera_;
  size_t scene_warnings_taken_ = 0;
  size_t scene_notes_taken_ = 0;
  std::unique_ptr<tracer::Renderer> renderer_;
  std::shared_ptr<tracer::CompiledScene> compiled_;
  bool mnee_casters_ = true;  // mnee_has_casters(*compiled_)
  float light_yield_ = 1.0f;  // light_path_yield(*compiled_, ...) with light tracing on
  bool dirty_ = true, geometry_dirty_ = true, display_dirty_ = true;
  WorkbenchStats stats_;
  double since_reset_s_ = 0.0;
  void record_reference_error(const tracer::ImageRGB& img);
  // The viewport's denoised image: of which accumulation (stats_.resets) at which spp.
  bool try_denoise();
  tracer::ImageRGB denoised_;
  uint32_t denoised_spp_ = 0;
  uint64_t denoised_reset_ = ~0ull;
  std::chrono::steady_clock::time_point denoised_at_{};
  tracer::DenoiseInfo denoise_info_;
  std::string denoise_error_;
  std::chrono::steady_clock::time_point aov_view_at_{};  // when the AOV view was last drawn
  uint32_t aov_view_spp_ = 0;
  // A display edit or a restart since the AOV view or the denoised image was last drawn.
  bool view_dirty_ = true;
  // The current image and its AOVs for the denoiser and the export.
  void current_image(tracer::ImageRGB* img, tracer::AovImages* aovs, uint32_t* spp);
  std::unique_ptr<tracer::ReferenceImage> reference_;
  int frames_since_estimate_ = 0;
  uint32_t next_curve_spp_ = 1;
  std::string preview_key_;  // what environment_preview last drew

  // CPU backend: a worker thread renders passes while the UI runs.
  bool async_ = false;
  std::thread worker_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::atomic<bool> cancel_{false};
  bool quit_ = false;
  bool worker_reset_ = false;
  std::shared_ptr<tracer::CompiledScene> worker_scene_;
  tracer::IntegratorSettings worker_cfg_;
  std::vector<float> published_mean_;
  tracer::AovImages published_aovs_;  // with AOVs on (the denoiser asks for them)
  bool worker_aovs_ = false;
  int published_w_ = 0, published_h_ = 0;
  bool published_new_ = false;
  tracer::FrameStats worker_stats_;
  tracer::GuideStatus worker_guide_;
  uint32_t worker_spp_ = 0;
  double worker_relmse_ = -1.0;
  uint64_t worker_nonfinite_ = 0;
  double worker_render_s_ = 0.0;
  uint64_t generation_ = 0;
  bool worker_paused_ = false;  // copies of the public fields, read by the worker under mutex_
  uint32_t worker_target_spp_ = 0;
  double worker_target_s_ = 0.0;
};

}  // namespace ui
