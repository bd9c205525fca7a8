// The CUDA parts' entries into the core's factories, declared once: makeBackend()
// (src/backend/backend_factory.cpp) and makeParticleFilter()
// (src/filter/particle_filter_factory.cpp) call them; src/backend/cuda/cuda_backend.cpp and
// src/filter/cuda/cuda_particle_filter.cpp define them. Compiled only with GMM_MCL_HAVE_CUDA; no
// CUDA header is needed to include it.
#pragma once

#include <memory>
#include <string>

namespace gmm_mcl {

class LikelihoodBackend;
class ParticleFilterBase;
struct CudaTuningParams;
struct ParticleFilterParams;

// The CUDA backend on device 0 with `tuning`; nullptr with *why set when no usable device is
// present.
std::unique_ptr<LikelihoodBackend> makeCudaBackend(const CudaTuningParams& tuning,
                                                   std::string* why);

// The device filter on the CUDA backend's device and stream; nullptr when `backend` is not the
// CUDA backend. Throws BackendError when the device cannot hold the set.
std::unique_ptr<ParticleFilterBase> makeCudaParticleFilter(const ParticleFilterParams& params,
                                                           LikelihoodBackend* backend);

}  // namespace gmm_mcl
