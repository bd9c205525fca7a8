#include <stdexcept>

#include "gmm_mcl/backend/cpu_backend.h"
#if defined(GMM_MCL_HAVE_CUDA)
#include "cuda/cuda_factory.h"
#endif

namespace gmm_mcl {

#if defined(GMM_MCL_HAVE_CUDA)
bool cudaBackendCompiled() { return true; }
#else
bool cudaBackendCompiled() { return false; }
#endif

std::unique_ptr<LikelihoodBackend> makeBackend(const std::string& name, std::string* warning,
                                               const BackendOptions& options) {
  if (warning) warning->clear();
  if (name == "cpu") return std::make_unique<CpuBackend>(options.cpu_threads);
  if (name != "cuda") throw std::invalid_argument("unknown backend '" + name + "' (cpu, cuda)");
#if defined(GMM_MCL_HAVE_CUDA)
  std::string why;
  std::unique_ptr<LikelihoodBackend> cuda = makeCudaBackend(options.cuda, &why);
  if (cuda) return cuda;
  if (warning) *warning = "CUDA backend unavailable (" + why + "); using the CPU backend";
#else
  if (warning) *warning = "CUDA backend not built (GMM_MCL_WITH_CUDA=OFF); using the CPU backend";
#endif
  return std::make_unique<CpuBackend>(options.cpu_threads);
}

}  // namespace gmm_mcl
