// Host side of the CUDA backend: device state, uploads, launches, downloads, timing.
#include "gmm_mcl/backend/cuda_backend.h"

#include <cuda_runtime_api.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "cuda/device_buffer.cuh"
#include "cuda/kernels.cuh"

namespace gmm_mcl {

namespace {

// FP32 lanes per multiprocessor by compute capability (CUDA C Programming Guide, "Arithmetic
// Instructions" throughput table).
int fp32LanesPerSm(int cc) {
  switch (cc) {
    case 60: return 64;
    case 61: case 62: return 128;
    case 70: case 72: case 75: return 64;
    case 80: return 64;
    default: return 128;  // 8.6, 8.7, 8.9, 9.0, 10.x, 12.x
  }
}

// Device memory for the membership masks of one batch of particles is bounded by this.
constexpr size_t kMaskBudgetBytes = size_t(256) << 20;

}  // namespace

int cudaDeviceCount(std::string* why) {
  int n = 0;
  const cudaError_t err = cudaGetDeviceCount(&n);
  if (err != cudaSuccess) {
    cudaGetLastError();  // clear the sticky-free error state of the runtime
    if (why) *why = std::string("no CUDA device: ") + cudaGetErrorString(err);
    return 0;
  }
  if (n == 0 && why) *why = "no CUDA device found";
  return n;
}

struct CudaBackend::Impl {
  CudaDeviceInfo info;
  cuda::Stream stream;
  int num_components = 0;
  cuda::DeviceBuffer<ComponentF> components;
  cuda::DeviceBuffer<cuda::EvalComponent> eval_components;
  // Per-update inputs: one pinned staging buffer, one device buffer of the same layout.
  cuda::PinnedBuffer<unsigned char> staging;
  cuda::DeviceBuffer<unsigned char> inputs;
  // Per-batch scratch and per-particle outputs.
  cuda::DeviceBuffer<uint32_t> mask;
  cuda::DeviceBuffer<float> shift;
  cuda::DeviceBuffer<uint32_t> summary;
  cuda::DeviceBuffer<double> item_ll;
  cuda::DeviceBuffer<int> item_hits, item_evals, item_relevant;
  cuda::DeviceBuffer<double> ll;
  cuda::DeviceBuffer<int> hits;
  cuda::DeviceBuffer<long long> evals;
  cuda::DeviceBuffer<long long> pairs;
  cuda::PinnedBuffer<double> h_ll;
  cuda::PinnedBuffer<int> h_hits;
  cuda::PinnedBuffer<long long> h_evals;
  cuda::PinnedBuffer<long long> h_pairs;
  std::vector<cuda::Event> events;  // per batch: start, after membership, after likelihood
  cuda::Event upload_start, upload_end, download_start, download_end;
  size_t shared_limit_set = 48 * 1024;
  double last_transfer_ms = 0.0;

  void ensureEvents(size_t n) {
    while (events.size() < n) events.emplace_back();
  }
};

CudaBackend::CudaBackend(int device) {
  std::string why;
  const int n = cudaDeviceCount(&why);
  if (n == 0) throw BackendError("cuda backend: " + why);
  if (device < 0 || device >= n) {
    throw BackendError("cuda backend: device " + std::to_string(device) + " of " +
                       std::to_string(n));
  }
  GMM_MCL_CUDA_CHECK(cudaSetDevice(device));
  impl_.reset(new Impl());
  CudaDeviceInfo& info = impl_->info;
  cudaDeviceProp prop;
  GMM_MCL_CUDA_CHECK(cudaGetDeviceProperties(&prop, device));
  int clock_khz = 0;
  GMM_MCL_CUDA_CHECK(cudaDeviceGetAttribute(&clock_khz, cudaDevAttrClockRate, device));
  int smem_optin = 0;
  GMM_MCL_CUDA_CHECK(
      cudaDeviceGetAttribute(&smem_optin, cudaDevAttrMaxSharedMemoryPerBlockOptin, device));
  info.name = prop.name;
  info.device = device;
  info.compute_capability = prop.major * 10 + prop.minor;
  info.multiprocessors = prop.multiProcessorCount;
  info.fp32_lanes_per_sm = fp32LanesPerSm(info.compute_capability);
  info.clock_ghz = clock_khz * 1e-6;
  info.fp32_peak_gflops =
      2.0 * info.fp32_lanes_per_sm * info.multiprocessors * info.clock_ghz;
  info.shared_per_block_bytes = std::max<size_t>(smem_optin, prop.sharedMemPerBlock);
}

CudaBackend::~CudaBackend() {
  if (impl_) cudaStreamSynchronize(impl_->stream.get());  // no kernel outlives its buffers
}

const CudaDeviceInfo& CudaBackend::deviceInfo() const { return impl_->info; }
double CudaBackend::lastTransferMs() const { return impl_->last_transfer_ms; }

void CudaBackend::setMap(const GmmMap& map) {
  const std::vector<ComponentF>& packed = map.packed();
  const int m = static_cast<int>(packed.size());
  std::vector<cuda::EvalComponent> ev(m);
  for (int i = 0; i < m; ++i) ev[i] = cuda::makeEvalComponent(packed[i]);
  Impl& d = *impl_;
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream.get()));
  d.components.reserve(std::max(m, 1));
  d.eval_components.reserve(std::max(m, 1));
  if (m > 0) {
    GMM_MCL_CUDA_CHECK(cudaMemcpy(d.components.data(), packed.data(), m * sizeof(ComponentF),
                                  cudaMemcpyHostToDevice));
    GMM_MCL_CUDA_CHECK(cudaMemcpy(d.eval_components.data(), ev.data(),
                                  m * sizeof(cuda::EvalComponent), cudaMemcpyHostToDevice));
  }
  d.num_components = m;
}

namespace {

size_t alignUp(size_t n) { return (n + 255) & ~size_t(255); }

// Layout of the per-update input block (offsets in bytes).
struct InputLayout {
  size_t x, y, z, patch_begin, T_map_cam, T_cam_map, total;
  InputLayout(size_t pixels, size_t patches, size_t particles) {
    x = 0;
    y = alignUp(x + pixels * sizeof(float));
    z = alignUp(y + pixels * sizeof(float));
    patch_begin = alignUp(z + pixels * sizeof(float));
    T_map_cam = alignUp(patch_begin + (patches + 1) * sizeof(int));
    T_cam_map = alignUp(T_map_cam + particles * sizeof(RigidTransformF));
    total = alignUp(T_cam_map + particles * sizeof(RigidTransformF));
  }
};

}  // namespace

void CudaBackend::evaluate(const DepthFrame& frame, const std::vector<RigidTransformF>& T_map_cam,
                           const MeasurementParams& params, BackendOutput* out) {
  Impl& d = *impl_;
  if (d.num_components == 0) throw BackendError("cuda backend: no map set");
  const int n = static_cast<int>(T_map_cam.size());
  const int patches = frame.grid.count();
  const int words = (d.num_components + 31) / 32;
  const size_t pixels = frame.size();
  out->log_likelihood.assign(n, 0.0);
  out->floor_hits.assign(n, 0);
  out->evaluations = out->relevant_pairs = 0;
  out->projection_membership_ms = out->likelihood_ms = 0.0;
  long long patches_with_pixels = 0;
  int max_patch_pixels = 0;
  for (int p = 0; p < patches; ++p) {
    const int c = frame.patch_begin[p + 1] - frame.patch_begin[p];
    patches_with_pixels += c > 0 ? 1 : 0;
    max_patch_pixels = std::max(max_patch_pixels, c);
  }
  out->patches_with_pixels = patches_with_pixels;
  d.last_transfer_ms = 0.0;
  if (n == 0 || patches == 0) return;

  const size_t smem = cuda::membershipSharedBytes(patches, words);
  if (smem > d.info.shared_per_block_bytes) {
    throw BackendError("cuda backend: the membership bitmask needs " + std::to_string(smem) +
                       " bytes of shared memory (" + std::to_string(patches) + " patches x " +
                       std::to_string(d.num_components) + " components); the device allows " +
                       std::to_string(d.info.shared_per_block_bytes));
  }
  if (smem > d.shared_limit_set) {
    GMM_MCL_CUDA_CHECK(cuda::setMembershipSharedLimit(smem));
    d.shared_limit_set = smem;
  }

  // Upload the frame and the poses once, through pinned memory, on the stream.
  const InputLayout L(pixels, patches, n);
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream.get()));  // staging is free again
  d.staging.reserve(L.total);
  d.inputs.reserve(L.total);
  unsigned char* h = d.staging.data();
  if (pixels > 0) {
    std::memcpy(h + L.x, frame.x_m.data(), pixels * sizeof(float));
    std::memcpy(h + L.y, frame.y_m.data(), pixels * sizeof(float));
    std::memcpy(h + L.z, frame.z_m.data(), pixels * sizeof(float));
  }
  std::memcpy(h + L.patch_begin, frame.patch_begin.data(), (patches + 1) * sizeof(int));
  std::memcpy(h + L.T_map_cam, T_map_cam.data(), n * sizeof(RigidTransformF));
  RigidTransformF* inv = reinterpret_cast<RigidTransformF*>(h + L.T_cam_map);
  for (int i = 0; i < n; ++i) inv[i] = invertRigid(T_map_cam[i]);  // as the CPU backend
  cudaStream_t s = d.stream.get();
  d.upload_start.record(s);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.inputs.data(), h, L.total, cudaMemcpyHostToDevice, s));
  d.upload_end.record(s);
  unsigned char* dev = d.inputs.data();
  const float* x = reinterpret_cast<const float*>(dev + L.x);
  const float* y = reinterpret_cast<const float*>(dev + L.y);
  const float* z = reinterpret_cast<const float*>(dev + L.z);
  const int* patch_begin = reinterpret_cast<const int*>(dev + L.patch_begin);
  const RigidTransformF* d_T_map_cam = reinterpret_cast<const RigidTransformF*>(dev + L.T_map_cam);
  const RigidTransformF* d_T_cam_map = reinterpret_cast<const RigidTransformF*>(dev + L.T_cam_map);

  // Particles in batches whose masks fit the budget.
  const size_t mask_bytes_per_particle = sizeof(uint32_t) * size_t(patches) * std::max(words, 1);
  const size_t max_by_threads = size_t(0x7fffffff) / (size_t(patches) * 32);  // int indices
  const int batch = static_cast<int>(std::max<size_t>(
      1, std::min<size_t>(std::min<size_t>(n, max_by_threads),
                          kMaskBudgetBytes / mask_bytes_per_particle)));
  const int swords = (words + 31) / 32;
  d.mask.reserve(size_t(batch) * patches * std::max(words, 1));
  d.summary.reserve(size_t(batch) * patches * std::max(swords, 1));
  d.shift.reserve(size_t(batch) * patches);
  d.item_ll.reserve(size_t(batch) * patches);
  d.item_hits.reserve(size_t(batch) * patches);
  d.item_evals.reserve(size_t(batch) * patches);
  d.item_relevant.reserve(size_t(batch) * patches);
  const cuda::ItemPartials partials{d.item_ll.data(), d.item_hits.data(), d.item_evals.data(),
                                    d.item_relevant.data()};
  d.ll.reserve(n);
  d.hits.reserve(n);
  d.evals.reserve(n);
  d.pairs.reserve(n);
  d.h_ll.reserve(n);
  d.h_hits.reserve(n);
  d.h_evals.reserve(n);
  d.h_pairs.reserve(n);

  cuda::MembershipConfig cfg;
  cfg.K = frame.intrinsics;
  cfg.patch_size_px = frame.grid.patch_size_px;
  cfg.patch_cols = frame.grid.cols;
  cfg.patch_rows = frame.grid.rows;
  cfg.min_depth_m = params.min_component_depth_m;
  cfg.sigma_bound = params.sigma_bound;
  cfg.inflate_px = patchInflation(frame.grid.patch_size_px);
  cfg.floor_log_density = params.floor_log_density;
  cuda::LikelihoodShape shape = cuda::chooseLikelihoodShape(max_patch_pixels);
  if (const char* env = std::getenv("GMM_MCL_CUDA_SHAPE")) {  // tuning: LANESxPX, e.g. 16x2
    int lanes = 0, px = 0;
    if (std::sscanf(env, "%dx%d", &lanes, &px) == 2) {
      shape.lanes = lanes;
      shape.pixels_per_lane = px;
    }
  }

  if (cuda::likelihoodSharedBytes(shape, words) > 48 * 1024) {
    throw BackendError("cuda backend: " + std::to_string(d.num_components) +
                       " components exceed the likelihood kernel's shared memory");
  }
  const int batches = (n + batch - 1) / batch;
  d.ensureEvents(3 * size_t(batches));
  for (int bi = 0; bi < batches; ++bi) {
    const int first = bi * batch;
    const int count = std::min(batch, n - first);
    d.events[3 * bi].record(s);
    GMM_MCL_CUDA_CHECK(cuda::launchMembership(count, d.num_components, words, cfg,
                                              d.components.data(), d_T_cam_map + first,
                                              d.mask.data(), d.shift.data(), d.summary.data(), s));
    d.events[3 * bi + 1].record(s);
    GMM_MCL_CUDA_CHECK(cuda::launchLikelihood(
        count, patches, words, shape, params.floor_log_density, x, y, z, patch_begin,
        d.eval_components.data(), d_T_map_cam + first, d.mask.data(), d.summary.data(),
        d.shift.data(), partials, s));
    GMM_MCL_CUDA_CHECK(cuda::launchReduce(count, patches, partials, d.ll.data() + first,
                                          d.hits.data() + first, d.evals.data() + first,
                                          d.pairs.data() + first, s));
    d.events[3 * bi + 2].record(s);
  }
  d.download_start.record(s);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_ll.data(), d.ll.data(), n * sizeof(double),
                                     cudaMemcpyDeviceToHost, s));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_hits.data(), d.hits.data(), n * sizeof(int),
                                     cudaMemcpyDeviceToHost, s));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_evals.data(), d.evals.data(), n * sizeof(long long),
                                     cudaMemcpyDeviceToHost, s));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_pairs.data(), d.pairs.data(), n * sizeof(long long),
                                     cudaMemcpyDeviceToHost, s));
  d.download_end.record(s);
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));

  for (int bi = 0; bi < batches; ++bi) {
    out->projection_membership_ms += d.events[3 * bi + 1].msSince(d.events[3 * bi]);
    out->likelihood_ms += d.events[3 * bi + 2].msSince(d.events[3 * bi + 1]);
  }
  d.last_transfer_ms =
      d.upload_end.msSince(d.upload_start) + d.download_end.msSince(d.download_start);
  for (int i = 0; i < n; ++i) {
    out->log_likelihood[i] = d.h_ll[i];
    out->floor_hits[i] = d.h_hits[i];
    out->evaluations += d.h_evals[i];
    out->relevant_pairs += d.h_pairs[i];
  }
}

void CudaBackend::membership(const DepthFrame& frame, const RigidTransformF& T_map_cam,
                             const MeasurementParams& params, PatchMembership* out) {
  Impl& d = *impl_;
  if (d.num_components == 0) throw BackendError("cuda backend: no map set");
  const int patches = frame.grid.count();
  const int words = (d.num_components + 31) / 32;
  out->begin.assign(patches + 1, 0);
  out->comps.clear();
  if (patches == 0) return;
  const size_t smem = cuda::membershipSharedBytes(patches, words);
  if (smem > d.info.shared_per_block_bytes) {
    throw BackendError("cuda backend: membership bitmask too large for shared memory");
  }
  if (smem > d.shared_limit_set) {
    GMM_MCL_CUDA_CHECK(cuda::setMembershipSharedLimit(smem));
    d.shared_limit_set = smem;
  }
  cudaStream_t s = d.stream.get();
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
  cuda::DeviceBuffer<RigidTransformF> pose(1);
  cuda::DeviceBuffer<uint32_t> mask(size_t(patches) * words);
  cuda::DeviceBuffer<float> shift(patches);
  cuda::DeviceBuffer<uint32_t> summary(size_t(patches) * ((words + 31) / 32));
  const RigidTransformF T_cam_map = invertRigid(T_map_cam);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(pose.data(), &T_cam_map, sizeof(T_cam_map),
                                     cudaMemcpyHostToDevice, s));
  cuda::MembershipConfig cfg;
  cfg.K = frame.intrinsics;
  cfg.patch_size_px = frame.grid.patch_size_px;
  cfg.patch_cols = frame.grid.cols;
  cfg.patch_rows = frame.grid.rows;
  cfg.min_depth_m = params.min_component_depth_m;
  cfg.sigma_bound = params.sigma_bound;
  cfg.inflate_px = patchInflation(frame.grid.patch_size_px);
  cfg.floor_log_density = params.floor_log_density;
  GMM_MCL_CUDA_CHECK(cuda::launchMembership(1, d.num_components, words, cfg, d.components.data(),
                                            pose.data(), mask.data(), shift.data(),
                                            summary.data(), s));
  std::vector<uint32_t> h(size_t(patches) * words);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(h.data(), mask.data(), h.size() * sizeof(uint32_t),
                                     cudaMemcpyDeviceToHost, s));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
  for (int p = 0; p < patches; ++p) {
    for (int w = 0; w < words; ++w) {
      uint32_t bits = h[size_t(p) * words + w];
      for (int b = 0; b < 32; ++b) {
        if (bits & (1u << b)) out->comps.push_back(w * 32 + b);
      }
    }
    out->begin[p + 1] = static_cast<int>(out->comps.size());
  }
}

std::unique_ptr<LikelihoodBackend> makeCudaBackend(std::string* why) {
  try {
    return std::unique_ptr<LikelihoodBackend>(new CudaBackend(0));
  } catch (const BackendError& e) {
    if (why) *why = e.what();
    return nullptr;
  }
}

}  // namespace gmm_mcl
