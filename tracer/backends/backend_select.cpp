// Backend selection: CUDA when it was built and a device answers, otherwise the CPU. The only
// place above both backends: it alone knows CudaRenderer, and in a build without CUDA it defines
// the CUDA-only functions of backend_select.h as answers that say so.
#include "backends/backend_select.h"

#include <stdexcept>

#include "cpu/cpu_backend.h"
#if defined(TRACER_CUDA_BACKEND)
#include "cuda/cuda_renderer.h"
#include "cuda/gl_interop.h"
#endif

namespace tracer {

std::unique_ptr<Renderer> make_renderer(BackendChoice choice, int cpu_threads, std::string* note,
                                        int device) {
  if (choice == BackendChoice::kCpu) return std::make_unique<CpuRenderer>(cpu_threads);
  std::string why;
  if (auto r = make_cuda_renderer(&why, device)) return r;
  if (choice == BackendChoice::kCuda) throw std::runtime_error("--backend cuda: " + why);
  if (note) *note = "using the CPU backend: " + why;
  return std::make_unique<CpuRenderer>(cpu_threads);
}

#if defined(TRACER_CUDA_BACKEND)

PinnedHostMemory::PinnedHostMemory(void* ptr, size_t bytes) : ptr_(ptr) {
  pinned_ = ptr && bytes > 0 && cuda_device_count() > 0 && cuda_pin_host(ptr, bytes);
}
PinnedHostMemory::~PinnedHostMemory() {
  if (pinned_) cuda_unpin_host(ptr_);
}

struct GlDisplayBuffer::Impl {
  GlInteropBuffer interop;
  explicit Impl(unsigned int pbo) : interop(pbo) {}
};

GlDisplayBuffer::GlDisplayBuffer(unsigned int pbo) : impl_(std::make_unique<Impl>(pbo)) {}

void GlDisplayBuffer::write_display(const Renderer& renderer, float exposure_scale, ToneMap op) {
  if (renderer.backend_name() != "cuda")
    throw std::logic_error("GlDisplayBuffer::write_display: the renderer is not the CUDA backend");
  impl_->interop.write_display(static_cast<const CudaRenderer&>(renderer), exposure_scale, int(op));
}

#else

namespace {
constexpr const char* kNoCuda =
    "this build has no CUDA backend (nvcc was not found at configure time)";
}  // namespace

std::unique_ptr<Renderer> make_cuda_renderer(std::string* why_not, int) {
  if (why_not) *why_not = kNoCuda;
  return nullptr;
}

int cuda_device_count() { return 0; }

PinnedHostMemory::PinnedHostMemory(void* ptr, size_t) : ptr_(ptr) {}
PinnedHostMemory::~PinnedHostMemory() = default;

double measure_copy_bandwidth_gbs() {
  throw std::logic_error(std::string("measure_copy_bandwidth_gbs: ") + kNoCuda);
}

struct GlDisplayBuffer::Impl {};

GlDisplayBuffer::GlDisplayBuffer(unsigned int) {
  throw std::runtime_error(kNoCuda);
}

void GlDisplayBuffer::write_display(const Renderer&, float, ToneMap) {
  throw std::logic_error(std::string("GlDisplayBuffer::write_display: ") + kNoCuda);
}

#endif

GlDisplayBuffer::~GlDisplayBuffer() = default;

}  // namespace tracer
