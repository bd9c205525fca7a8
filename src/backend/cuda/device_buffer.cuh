// RAII, move-only owners of device memory, pinned host memory, a stream and events.
// Algorithm code never calls cudaMalloc/cudaFree directly.
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>
#include <utility>

#include "cuda/cuda_check.cuh"

namespace gmm_mcl {
namespace cuda {

// Device array of T. reserve() grows only (contents are not preserved on growth).
template <typename T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(size_t n) { reserve(n); }
  ~DeviceBuffer() { release(); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& o) noexcept : ptr_(o.ptr_), capacity_(o.capacity_) {
    o.ptr_ = nullptr;
    o.capacity_ = 0;
  }
  DeviceBuffer& operator=(DeviceBuffer&& o) noexcept {
    if (this != &o) {
      release();
      std::swap(ptr_, o.ptr_);
      std::swap(capacity_, o.capacity_);
    }
    return *this;
  }
  void reserve(size_t n) {
    if (n <= capacity_) return;
    release();
    void* p = nullptr;
    GMM_MCL_CUDA_CHECK(cudaMalloc(&p, n * sizeof(T)));
    ptr_ = static_cast<T*>(p);
    capacity_ = n;
  }
  // reserve() after the work queued on `stream` (which may still use the old array) is done:
  // cudaFree is not guaranteed to wait for it.
  void reserve(size_t n, cudaStream_t stream) {
    if (n <= capacity_) return;
    GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(stream));
    reserve(n);
  }
  T* data() { return ptr_; }
  const T* data() const { return ptr_; }
  size_t capacity() const { return capacity_; }

 private:
  void release() noexcept {
    if (ptr_) cudaFree(ptr_);  // errors on release are not actionable
    ptr_ = nullptr;
    capacity_ = 0;
  }
  T* ptr_ = nullptr;
  size_t capacity_ = 0;
};

// Page-locked host array of T (for asynchronous copies); grows only.
template <typename T>
class PinnedBuffer {
 public:
  PinnedBuffer() = default;
  ~PinnedBuffer() { release(); }
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;
  PinnedBuffer(PinnedBuffer&& o) noexcept : ptr_(o.ptr_), capacity_(o.capacity_) {
    o.ptr_ = nullptr;
    o.capacity_ = 0;
  }
  void reserve(size_t n) {
    if (n <= capacity_) return;
    release();
    void* p = nullptr;
    GMM_MCL_CUDA_CHECK(cudaMallocHost(&p, n * sizeof(T)));
    ptr_ = static_cast<T*>(p);
    capacity_ = n;
  }
  T* data() { return ptr_; }
  const T* data() const { return ptr_; }
  T& operator[](size_t i) { return ptr_[i]; }
  const T& operator[](size_t i) const { return ptr_[i]; }
  size_t capacity() const { return capacity_; }

 private:
  void release() noexcept {
    if (ptr_) cudaFreeHost(ptr_);
    ptr_ = nullptr;
    capacity_ = 0;
  }
  T* ptr_ = nullptr;
  size_t capacity_ = 0;
};

// Makes `device` the calling thread's current device for the scope (each entry point of the
// backend and the device filter: a nodelet's callbacks arrive on any thread of a pool).
class DeviceScope {
 public:
  explicit DeviceScope(int device) { GMM_MCL_CUDA_CHECK(cudaSetDevice(device)); }
  DeviceScope(const DeviceScope&) = delete;
  DeviceScope& operator=(const DeviceScope&) = delete;
};

class Stream {
 public:
  Stream() { GMM_MCL_CUDA_CHECK(cudaStreamCreateWithFlags(&s_, cudaStreamNonBlocking)); }
  ~Stream() {
    if (s_) cudaStreamDestroy(s_);
  }
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;
  cudaStream_t get() const { return s_; }

 private:
  cudaStream_t s_ = nullptr;
};

class Event {
 public:
  Event() { GMM_MCL_CUDA_CHECK(cudaEventCreate(&e_)); }
  ~Event() {
    if (e_) cudaEventDestroy(e_);
  }
  Event(const Event&) = delete;
  Event& operator=(const Event&) = delete;
  Event(Event&& o) noexcept : e_(o.e_) { o.e_ = nullptr; }
  void record(cudaStream_t s) { GMM_MCL_CUDA_CHECK(cudaEventRecord(e_, s)); }
  cudaEvent_t get() const { return e_; }
  // Milliseconds from `start` to this event (both recorded and completed).
  float msSince(const Event& start) const {
    float ms = 0.f;
    GMM_MCL_CUDA_CHECK(cudaEventElapsedTime(&ms, start.e_, e_));
    return ms;
  }

 private:
  cudaEvent_t e_ = nullptr;
};

}  // namespace cuda
}  // namespace gmm_mcl
