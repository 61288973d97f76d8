// CUDA/OpenGL interop for the workbench: an OpenGL pixel buffer object registered with CUDA once
// (and again on resize), mapped each frame so the display kernel writes into it directly, and
// unregistered in the destructor. The GL buffer id is passed as a plain integer so this header
// needs no GL headers.
#pragma once

#include <memory>
#include <string>

namespace tracer {

class CudaRenderer;

class GlInteropBuffer {
 public:
  // Registers the existing GL buffer `pbo` (a GL_PIXEL_UNPACK_BUFFER of at least width*height*4
  // bytes). Throws CudaError when the driver cannot share it (for example Mesa's software GL).
  explicit GlInteropBuffer(unsigned int pbo);
  ~GlInteropBuffer();
  GlInteropBuffer(const GlInteropBuffer&) = delete;
  GlInteropBuffer& operator=(const GlInteropBuffer&) = delete;

  // Maps the buffer, runs the renderer's display kernel into it, unmaps. The caller then
  // uploads the PBO into its texture with glTexSubImage2D (no round trip through host memory).
  void write_display(const CudaRenderer& renderer, float exposure_scale, int tone_map);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tracer
