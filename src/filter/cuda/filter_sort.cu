// The device filter's sorts and scans, from cub (in every CUDA toolkit). This file holds only
// these wrappers: CUDA 13's cub needs C++17 (cmake/cuda_backend.cmake compiles this file, and
// only this one, with -std=c++17 there); the code itself is C++14 and older toolkits compile it
// as such.
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>

#include "cuda/filter_kernels.cuh"

namespace gmm_mcl {
namespace cuda {

cudaError_t sortPairsU32(void* temp, size_t* temp_bytes, const uint32_t* keys_in,
                         uint32_t* keys_out, const int* values_in, int* values_out, int n,
                         cudaStream_t stream) {
  return cub::DeviceRadixSort::SortPairs(temp, *temp_bytes, keys_in, keys_out, values_in,
                                         values_out, n, 0, 32, stream);
}

cudaError_t sortPairsDescendingF64(void* temp, size_t* temp_bytes, const double* keys_in,
                                   double* keys_out, const int* values_in, int* values_out, int n,
                                   cudaStream_t stream) {
  return cub::DeviceRadixSort::SortPairsDescending(temp, *temp_bytes, keys_in, keys_out, values_in,
                                                   values_out, n, 0, 64, stream);
}

cudaError_t sortKeysU64(void* temp, size_t* temp_bytes, const uint64_t* keys_in, uint64_t* keys_out,
                        int n, cudaStream_t stream) {
  return cub::DeviceRadixSort::SortKeys(temp, *temp_bytes, keys_in, keys_out, n, 0, 64, stream);
}

cudaError_t inclusiveSumF64(void* temp, size_t* temp_bytes, const double* in, double* out, int n,
                            cudaStream_t stream) {
  return cub::DeviceScan::InclusiveSum(temp, *temp_bytes, in, out, n, stream);
}

}  // namespace cuda
}  // namespace gmm_mcl
