#include <stdexcept>

#include "gmm_mcl/filter/particle_filter.h"
#if defined(GMM_MCL_HAVE_CUDA)
#include "cuda/cuda_factory.h"  // src/backend/cuda/
#endif

namespace gmm_mcl {

std::unique_ptr<ParticleFilterBase> makeParticleFilter(const ParticleFilterParams& params,
                                                       LikelihoodBackend* backend, bool device,
                                                       std::string* warning) {
  if (warning) warning->clear();
#if defined(GMM_MCL_HAVE_CUDA)
  if (device && backend != nullptr) {
    try {
      std::unique_ptr<ParticleFilterBase> f = makeCudaParticleFilter(params, backend);
      if (f) return f;
    } catch (const BackendError& e) {
      if (warning) {
        *warning = std::string("device particle filter unavailable (") + e.what() +
                   "); the particle set stays on the host";
      }
    }
  }
#else
  (void)backend;
  (void)device;
#endif
  return std::make_unique<ParticleFilter>(params);
}

}  // namespace gmm_mcl
