// CUDA error handling at the backend boundary: every runtime call is checked and a failure
// becomes a BackendError naming the call site and the CUDA error. Nothing here exits.
#pragma once

#include <cuda_runtime_api.h>

#include <string>

#include "gmm_mcl/backend/likelihood_backend_base.h"

namespace gmm_mcl {
namespace cuda {

inline void throwOnError(cudaError_t err, const char* what, const char* file, int line) {
  if (err == cudaSuccess) return;
  throw BackendError(std::string("cuda backend: ") + what + " failed at " + file + ":" +
                     std::to_string(line) + ": " + cudaGetErrorName(err) + " (" +
                     cudaGetErrorString(err) + ")");
}

}  // namespace cuda
}  // namespace gmm_mcl

#define GMM_MCL_CUDA_CHECK(call) ::gmm_mcl::cuda::throwOnError((call), #call, __FILE__, __LINE__)
