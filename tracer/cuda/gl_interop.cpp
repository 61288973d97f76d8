// CUDA/OpenGL buffer sharing (cuda-samples' volumeRender pattern: map, get pointer, launch,
// unmap). The only tracer file that sees an OpenGL type, through cuda_gl_interop.h.
#include "cuda/gl_interop.h"

#include <GL/gl.h>
#include <cuda_gl_interop.h>

#include "cuda/cuda_check.h"
#include "cuda/cuda_renderer.h"

namespace tracer {

struct GlInteropBuffer::Impl {
  cudaGraphicsResource_t resource = nullptr;
};

GlInteropBuffer::GlInteropBuffer(unsigned int pbo) : impl_(std::make_unique<Impl>()) {
  TRACER_CUDA_CHECK(cudaGraphicsGLRegisterBuffer(&impl_->resource, GLuint(pbo),
                                                 cudaGraphicsRegisterFlagsWriteDiscard));
}

GlInteropBuffer::~GlInteropBuffer() {
  if (impl_ && impl_->resource) cudaGraphicsUnregisterResource(impl_->resource);
}

void GlInteropBuffer::write_display(const CudaRenderer& renderer, float exposure_scale,
                                    int tone_map) {
  TRACER_CUDA_CHECK(cudaGraphicsMapResources(1, &impl_->resource, 0));
  void* ptr = nullptr;
  size_t bytes = 0;
  const cudaError_t err = cudaGraphicsResourceGetMappedPointer(&ptr, &bytes, impl_->resource);
  if (err == cudaSuccess && bytes < size_t(4) * renderer.width_times_height()) {
    cudaGraphicsUnmapResources(1, &impl_->resource, 0);
    throw CudaError("the OpenGL pixel buffer is smaller than the image");
  }
  if (err == cudaSuccess) {
    try {
      renderer.display_to_device(ptr, exposure_scale, ToneMap(tone_map));
    } catch (...) {
      cudaGraphicsUnmapResources(1, &impl_->resource, 0);
      throw;
    }
  }
  TRACER_CUDA_CHECK(cudaGraphicsUnmapResources(1, &impl_->resource, 0));
  TRACER_CUDA_CHECK(err);
}

}  // namespace tracer
