// Choosing a backend, and the few things only the CUDA backend has, declared the same in every
// build: ui/ and app/ reach the backends through this header alone (tracer_backends links the
// CUDA backend privately, so cuda/ headers are out of their reach).
#pragma once

#include <memory>
#include <string>

#include "integrator/renderer.h"

namespace tracer {

// kAuto: CUDA when built with it and a device exists, else the CPU (with `note` saying why).
// kCuda without a usable device throws std::runtime_error with the reason. `device` picks the
// CUDA device (0 .. cuda_device_count() - 1).
std::unique_ptr<Renderer> make_renderer(BackendChoice choice, int cpu_threads, std::string* note,
                                        int device = 0);

// The CUDA backend on `device`, or nullptr with the reason when this build has none or the
// device does not answer.
std::unique_ptr<Renderer> make_cuda_renderer(std::string* why_not, int device = 0);
// CUDA devices that answer (0 in a build without CUDA or on a machine without a GPU).
int cuda_device_count();

// Device-to-device copy bandwidth in GB/s (bytes read + bytes written): the ceiling the
// wavefront's memory traffic is measured against. Needs the CUDA backend and a device.
double measure_copy_bandwidth_gbs();

// Host memory page-locked while this lives (cudaHostRegister), so that copies from the GPU into
// it run at the bus's speed (distributed rendering's shared window). Best effort: in a build
// without CUDA, on a machine without a GPU or where the driver refuses, pinned() is false and
// the memory works as before.
class PinnedHostMemory {
 public:
  PinnedHostMemory(void* ptr, size_t bytes);
  ~PinnedHostMemory();
  PinnedHostMemory(const PinnedHostMemory&) = delete;
  PinnedHostMemory& operator=(const PinnedHostMemory&) = delete;
  bool pinned() const { return pinned_; }

 private:
  void* ptr_;
  bool pinned_ = false;
};

// An OpenGL pixel buffer that the CUDA backend writes its display image into on the device
// (CUDA/GL interop, cuda/gl_interop.h), so the image skips host memory: registered with CUDA by
// the constructor, unregistered by the destructor.
class GlDisplayBuffer {
 public:
  // Registers the GL buffer `pbo` (a GL_PIXEL_UNPACK_BUFFER of at least width*height*4 bytes).
  // Throws when the build has no CUDA backend or the driver cannot share the buffer.
  explicit GlDisplayBuffer(unsigned int pbo);
  ~GlDisplayBuffer();
  GlDisplayBuffer(const GlDisplayBuffer&) = delete;
  GlDisplayBuffer& operator=(const GlDisplayBuffer&) = delete;

  // Writes the display image of `renderer`, which must be the CUDA backend (backend_name()
  // "cuda"), into the buffer; the caller then uploads the buffer into its texture.
  void write_display(const Renderer& renderer, float exposure_scale, ToneMap op);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tracer
