// RAII, move-only owners of device memory, pinned host memory, a stream and events.
// Algorithm code never calls cudaMalloc/cudaFree directly.
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>
#include <utility>

#include "cuda/cuda_check.cuh"

namespace gmm_mcl {
namespace cuda {

namespace detail {

struct DeviceAllocator {
  static cudaError_t allocate(void** p, size_t bytes) { return cudaMalloc(p, bytes); }
  static void release(void* p) { cudaFree(p); }  // errors on release are not actionable
};
struct PinnedAllocator {
  static cudaError_t allocate(void** p, size_t bytes) { return cudaMallocHost(p, bytes); }
  static void release(void* p) { cudaFreeHost(p); }
};

// An array of T from Allocator; reserve() grows only (contents are not preserved on growth).
template <typename T, typename Allocator>
class OwnedArray {
 public:
  OwnedArray() = default;
  ~OwnedArray() { release(); }
  OwnedArray(const OwnedArray&) = delete;
  OwnedArray& operator=(const OwnedArray&) = delete;
  OwnedArray(OwnedArray&& o) noexcept : ptr_(o.ptr_), capacity_(o.capacity_) {
    o.ptr_ = nullptr;
    o.capacity_ = 0;
  }
  OwnedArray& operator=(OwnedArray&& o) noexcept {
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
    GMM_MCL_CUDA_CHECK(Allocator::allocate(&p, n * sizeof(T)));
    ptr_ = static_cast<T*>(p);
    capacity_ = n;
  }
  T* data() { return ptr_; }
  const T* data() const { return ptr_; }
  size_t capacity() const { return capacity_; }

 private:
  void release() noexcept {
    if (ptr_) Allocator::release(ptr_);
    ptr_ = nullptr;
    capacity_ = 0;
  }
  T* ptr_ = nullptr;
  size_t capacity_ = 0;
};

}  // namespace detail

// Device array of T. reserve() grows only (contents are not preserved on growth).
template <typename T>
class DeviceBuffer : public detail::OwnedArray<T, detail::DeviceAllocator> {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(size_t n) { this->reserve(n); }
  using detail::OwnedArray<T, detail::DeviceAllocator>::reserve;
  // reserve() after the work queued on `stream` (which may still use the old array) is done:
  // cudaFree is not guaranteed to wait for it.
  void reserve(size_t n, cudaStream_t stream) {
    if (n <= this->capacity()) return;
    GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(stream));
    reserve(n);
  }
};

// Page-locked host array of T (for asynchronous copies); grows only.
template <typename T>
class PinnedBuffer : public detail::OwnedArray<T, detail::PinnedAllocator> {
 public:
  T& operator[](size_t i) { return this->data()[i]; }
  const T& operator[](size_t i) const { return this->data()[i]; }
};

// buffers.reserve(n, stream) for each, in order.
template <typename... Buffers>
void reserveAll(size_t n, cudaStream_t stream, Buffers&... buffers) {
  const int in_order[] = {0, (buffers.reserve(n, stream), 0)...};
  (void)in_order;
}

// `count` elements of T from device memory to host memory, once the work queued on `stream`
// is done (the call returns with the copy complete).
template <typename T>
void copyToHost(T* host, const void* device, size_t count, cudaStream_t stream) {
  if (count > 0) {
    GMM_MCL_CUDA_CHECK(
        cudaMemcpyAsync(host, device, count * sizeof(T), cudaMemcpyDeviceToHost, stream));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(stream));
}

// Queues a copy of `count` elements of T from host memory to device memory on `stream` (the
// host array must live until the stream has run it).
template <typename T>
void copyToDeviceAsync(void* device, const T* host, size_t count, cudaStream_t stream) {
  if (count > 0) {
    GMM_MCL_CUDA_CHECK(
        cudaMemcpyAsync(device, host, count * sizeof(T), cudaMemcpyHostToDevice, stream));
  }
}

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
