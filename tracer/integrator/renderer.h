// The host-side interface every backend implements: load a compiled scene, add samples to a
// progressive accumulator, read the mean image and per-frame statistics.
#pragma once

#include <memory>
#include <string>

#include "image/image.h"
#include "integrator/path.h"
#include "scene/compiled_scene.h"

namespace tracer {

struct FrameStats {
  uint32_t spp_added = 0;
  double ms = 0.0;
  RayCounts rays;
  uint64_t nonfinite = 0;  // samples rejected because they were NaN or infinite
};

class Renderer {
 public:
  virtual ~Renderer() = default;
  virtual std::string backend_name() const = 0;  // "cpu" or "cuda"
  virtual std::string device_name() const = 0;    // e.g. "2 threads" or the GPU's name
  // Takes the scene (the caller keeps it alive) and clears the accumulator.
  virtual void set_scene(const CompiledScene& scene, const IntegratorSettings& cfg) = 0;
  virtual void set_settings(const IntegratorSettings& cfg) = 0;  // clears the accumulator
  virtual void reset() = 0;                                        // O(1) on the GPU
  // Adds `spp` samples per pixel; blocks until done.
  virtual FrameStats render(uint32_t spp) = 0;
  virtual uint32_t samples_done() const = 0;
  virtual uint64_t nonfinite_total() const = 0;
  // The mean radiance per pixel so far.
  virtual ImageRGB image() const = 0;
};

enum class BackendChoice { kAuto, kCpu, kCuda };

// kAuto: CUDA when built with it and a device exists, else the CPU (with `note` saying why).
// kCuda without a usable device throws std::runtime_error with the reason.
std::unique_ptr<Renderer> make_renderer(BackendChoice choice, int cpu_threads, std::string* note);

}  // namespace tracer
