#include <stdexcept>

#include "gmm_mcl/backend/cpu_backend.h"

namespace gmm_mcl {

#if defined(GMM_MCL_HAVE_CUDA)
// Defined in src/backend/cuda/: nullptr with *why set when no usable device is present.
std::unique_ptr<LikelihoodBackend> makeCudaBackend(std::string* why);
bool cudaBackendCompiled() { return true; }
#else
bool cudaBackendCompiled() { return false; }
#endif

std::unique_ptr<LikelihoodBackend> makeBackend(const std::string& name, std::string* warning) {
  if (warning) warning->clear();
  if (name == "cpu") return std::make_unique<CpuBackend>();
  if (name != "cuda") throw std::invalid_argument("unknown backend '" + name + "' (cpu, cuda)");
#if defined(GMM_MCL_HAVE_CUDA)
  std::string why;
  std::unique_ptr<LikelihoodBackend> cuda = makeCudaBackend(&why);
  if (cuda) return cuda;
  if (warning) *warning = "CUDA backend unavailable (" + why + "); using the CPU backend";
#else
  if (warning) *warning = "CUDA backend not built (GMM_MCL_WITH_CUDA=OFF); using the CPU backend";
#endif
  return std::make_unique<CpuBackend>();
}

}  // namespace gmm_mcl
