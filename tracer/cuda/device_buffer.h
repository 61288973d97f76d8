// RAII ownership of device memory: freed in the destructor, movable, never copied.
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

#include "cuda/cuda_check.h"

namespace tracer {

template <typename T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(size_t count) { resize(count); }
  ~DeviceBuffer() { release(); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& o) noexcept : ptr_(o.ptr_), count_(o.count_) {
    o.ptr_ = nullptr;
    o.count_ = 0;
  }
  DeviceBuffer& operator=(DeviceBuffer&& o) noexcept {
    if (this != &o) {
      release();
      std::swap(ptr_, o.ptr_);
      std::swap(count_, o.count_);
    }
    return *this;
  }

  // Reallocates only when the size changes; contents are undefined afterwards.
  void resize(size_t count) {
    if (count == count_) return;
    release();
    if (count > 0) TRACER_CUDA_CHECK(cudaMalloc(&ptr_, count * sizeof(T)));
    count_ = count;
  }
  void upload(const std::vector<T>& host) {
    resize(host.size());
    if (!host.empty())
      TRACER_CUDA_CHECK(cudaMemcpy(ptr_, host.data(), host.size() * sizeof(T),
                                   cudaMemcpyHostToDevice));
  }
  void download(std::vector<T>& host) const {
    host.resize(count_);
    if (count_ > 0)
      TRACER_CUDA_CHECK(cudaMemcpy(host.data(), ptr_, count_ * sizeof(T), cudaMemcpyDeviceToHost));
  }
  void zero_async(cudaStream_t s = 0) {
    if (count_ > 0) TRACER_CUDA_CHECK(cudaMemsetAsync(ptr_, 0, count_ * sizeof(T), s));
  }

  T* get() const { return ptr_; }
  size_t size() const { return count_; }
  size_t bytes() const { return count_ * sizeof(T); }

 private:
  void release() {
    if (ptr_) cudaFree(ptr_);  // no throw from a destructor; errors surface on the next call
    ptr_ = nullptr;
    count_ = 0;
  }
  T* ptr_ = nullptr;
  size_t count_ = 0;
};

}  // namespace tracer
