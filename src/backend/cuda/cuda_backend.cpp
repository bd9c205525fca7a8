// Host side of the CUDA backend: device state, uploads, launches, downloads, timing.
#include "gmm_mcl/backend/cuda_backend.h"

#include <cuda_runtime_api.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "cuda/cuda_normal_equations.h"
#include "cuda/device_buffer.cuh"
#include "cuda/kernels.cuh"

namespace gmm_mcl {

namespace {

// FP32 lanes per multiprocessor by compute capability (CUDA C Programming Guide, "Arithmetic
// Instructions" throughput table).
int fp32LanesPerSm(int cc) {
  switch (cc) {
    case 60:
      return 64;
    case 61:
    case 62:
      return 128;
    case 70:
    case 72:
    case 75:
      return 64;
    case 80:
      return 64;
    default:
      return 128;  // 8.6, 8.7, 8.9, 9.0, 10.x, 12.x
  }
}

// Device memory for the membership masks and per-particle evaluation forms of one batch of
// particles is bounded by this, and by a sixteenth of the device's memory (512 MB on an 8 GB
// TX2). Measured on an H100: 1 GB instead of 256 MB takes `scale` from 33 batches to 9 (28.8 ms
// per update instead of 29.7-30.5) and `large` (M = 4000) from 2 batches to 1 (1.69 ms instead
// of 1.86-1.96); 4 GB gains nothing more.
constexpr size_t kMaskBudgetBytes = size_t(1) << 30;

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

namespace {
size_t alignUp(size_t n) { return (n + 255) & ~size_t(255); }
}  // namespace

struct CudaBackend::Impl {
  CudaDeviceInfo info;
  int device = 0;
  cuda::Stream stream;
  int num_components = 0;
  cuda::DeviceBuffer<ComponentF> components;
  cuda::DeviceBuffer<EvalComponentF> eval_components;  // log2 form (likelihood kernel)
  // Per-update inputs: one pinned staging buffer, one device buffer of the same layout.
  cuda::PinnedBuffer<unsigned char> staging;
  cuda::DeviceBuffer<unsigned char> inputs;
  // Per-batch scratch and per-particle outputs.
  cuda::DeviceBuffer<uint32_t> mask;
  cuda::DeviceBuffer<float> shift;
  cuda::DeviceBuffer<EvalComponentF> noisy_eval;  // [batch][M] with the depth-noise model on
  cuda::DeviceBuffer<double> item_ll;
  cuda::DeviceBuffer<int> item_hits, item_evals, item_relevant;
  // Per-particle results (and the frame's patch starts when the GPU prepared it) in one block,
  // downloaded with one copy.
  cuda::DeviceBuffer<unsigned char> results;
  cuda::PinnedBuffer<unsigned char> h_results;
  std::vector<cuda::Event> events;  // per batch: start, after membership, after likelihood
  cuda::Event upload_start, upload_end, download_start, download_end;
  cuda::DeviceBuffer<int> counts;  // GPU frame preparation scratch
  cuda::Event prep_end;
  size_t shared_limit_set = 48 * 1024;
  std::unique_ptr<cuda::CudaNormalEquations> normal_equations;  // pose refinement, made on use
  double last_transfer_ms = 0.0;
  double last_frame_prep_ms = 0.0;
  int last_frame_pixels = 0;
  // The device frame (prepareDeviceFrame / uploadDeviceFrame): points and patch starts, the raw
  // image rows, their pinned staging; the patch starts read back once per frame.
  cuda::DeviceBuffer<unsigned char> dframe;
  cuda::DeviceBuffer<unsigned char> dframe_image;
  cuda::PinnedBuffer<unsigned char> dframe_staging;
  cuda::PinnedBuffer<int> dframe_patch_begin;
  bool has_dframe = false;
  int dframe_pixels = 0;
  Intrinsics dframe_K;
  PatchGrid dframe_grid;
  size_t dframe_x = 0, dframe_y = 0, dframe_z = 0, dframe_patch_begin_at = 0;  // offsets
  int dframe_max_patch_pixels = 0;
  int device_batches = 0;  // batches of the last evaluateDevicePoses (events)

  struct DeviceFrameView;
  template <typename Layout>
  void stagePoses(const std::vector<RigidTransformF>& T_map_cam, const Layout& L) {
    unsigned char* h = staging.data();
    const size_t n = T_map_cam.size();
    std::memcpy(h + L.T_map_cam, T_map_cam.data(), n * sizeof(RigidTransformF));
    RigidTransformF* inv = reinterpret_cast<RigidTransformF*>(h + L.T_cam_map);
    for (size_t i = 0; i < n; ++i) inv[i] = invertRigid(T_map_cam[i]);  // as the CPU backend
  }
  template <typename Layout>
  DeviceFrameView view(const Layout& L, const Intrinsics& K, const PatchGrid& grid);
  void run(const DeviceFrameView& f, int n, const MeasurementParams& params, int max_patch_pixels,
           bool gpu_frame, BackendOutput* out);
  // Membership, likelihood and the per-particle reduction of n poses in batches, queued on the
  // stream, per-particle results to the given device arrays; returns the batch count (three
  // events per batch).
  int launchBatches(const DeviceFrameView& f, int n, const MeasurementParams& params,
                    int max_patch_pixels, double* ll, int* hits, long long* evals,
                    long long* pairs);

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
  impl_->device = device;
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
  info.fp32_peak_gflops = 2.0 * info.fp32_lanes_per_sm * info.multiprocessors * info.clock_ghz;
  info.shared_per_block_bytes = std::max<size_t>(smem_optin, prop.sharedMemPerBlock);
  info.total_memory_bytes = prop.totalGlobalMem;
  GMM_MCL_CUDA_CHECK(cuda::preferSharedMemoryForMembership());
}

CudaBackend::~CudaBackend() {
  if (!impl_) return;
  // On the calling thread's device, whichever thread destroys it; no kernel outlives its
  // buffers. Errors here are not actionable (a failed device is being let go).
  if (cudaSetDevice(impl_->device) == cudaSuccess) cudaStreamSynchronize(impl_->stream.get());
  impl_.reset();
  cudaGetLastError();
}

int CudaBackend::deviceOrdinal() const { return impl_->device; }
void* CudaBackend::streamHandle() const { return impl_->stream.get(); }

const CudaDeviceInfo& CudaBackend::deviceInfo() const { return impl_->info; }
double CudaBackend::lastTransferMs() const { return impl_->last_transfer_ms; }
double CudaBackend::lastFramePrepMs() const { return impl_->last_frame_prep_ms; }
int CudaBackend::lastFramePixels() const { return impl_->last_frame_pixels; }

NormalEquationsEvaluator* CudaBackend::normalEquations() {
  if (!impl_->normal_equations) {
    Impl* d = impl_.get();
    impl_->normal_equations.reset(new cuda::CudaNormalEquations(
        d->info.device, d->stream.get(), [d](cuda::BackendFrameRef* ref) {
          if (!d->has_dframe) return false;
          unsigned char* dev = d->dframe.data();
          ref->x_m = reinterpret_cast<const float*>(dev + d->dframe_x);
          ref->y_m = reinterpret_cast<const float*>(dev + d->dframe_y);
          ref->z_m = reinterpret_cast<const float*>(dev + d->dframe_z);
          ref->patch_begin = reinterpret_cast<const int*>(dev + d->dframe_patch_begin_at);
          ref->patches = d->dframe_grid.count();
          ref->pixels = d->dframe_pixels;
          return true;
        }));
  }
  return impl_->normal_equations.get();
}

void CudaBackend::setMap(const GmmMap& map) {
  const cuda::DeviceScope scope(impl_->device);
  const std::vector<ComponentF>& packed = map.packed();
  const int m = static_cast<int>(packed.size());
  std::vector<EvalComponentF> ev(m);
  for (int i = 0; i < m; ++i) ev[i] = makeEvalComponentF(packed[i], kEvalScaleLog2);
  Impl& d = *impl_;
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream.get()));
  d.components.reserve(std::max(m, 1));
  d.eval_components.reserve(std::max(m, 1));
  if (m > 0) {
    GMM_MCL_CUDA_CHECK(cudaMemcpy(d.components.data(), packed.data(), m * sizeof(ComponentF),
                                  cudaMemcpyHostToDevice));
    GMM_MCL_CUDA_CHECK(cudaMemcpy(d.eval_components.data(), ev.data(),
                                  m * sizeof(EvalComponentF), cudaMemcpyHostToDevice));
  }
  d.num_components = m;
}

// Device pointers of one update's inputs.
struct CudaBackend::Impl::DeviceFrameView {
  Intrinsics K;
  PatchGrid grid;
  const float *x, *y, *z;
  const int* patch_begin;
  const RigidTransformF* T_map_cam;
  const RigidTransformF* T_cam_map;
};

template <typename Layout>
CudaBackend::Impl::DeviceFrameView CudaBackend::Impl::view(const Layout& L, const Intrinsics& K,
                                                           const PatchGrid& grid) {
  unsigned char* dev = inputs.data();
  DeviceFrameView v;
  v.K = K;
  v.grid = grid;
  v.x = reinterpret_cast<const float*>(dev + L.x);
  v.y = reinterpret_cast<const float*>(dev + L.y);
  v.z = reinterpret_cast<const float*>(dev + L.z);
  v.patch_begin = reinterpret_cast<const int*>(dev + L.patch_begin);
  v.T_map_cam = reinterpret_cast<const RigidTransformF*>(dev + L.T_map_cam);
  v.T_cam_map = reinterpret_cast<const RigidTransformF*>(dev + L.T_cam_map);
  return v;
}

namespace {

// Layout of the per-update input block (offsets in bytes): raw image (GPU frame preparation
// only), points, patch starts, poses.
struct InputLayout {
  size_t image, x, y, z, patch_begin, T_map_cam, T_cam_map, total;
  InputLayout(size_t pixels, size_t image_bytes, size_t patches, size_t particles) {
    x = 0;
    y = alignUp(x + pixels * sizeof(float));
    z = alignUp(y + pixels * sizeof(float));
    patch_begin = alignUp(z + pixels * sizeof(float));
    image = alignUp(patch_begin + (patches + 1) * sizeof(int));
    T_map_cam = alignUp(image + image_bytes);
    T_cam_map = alignUp(T_map_cam + particles * sizeof(RigidTransformF));
    total = alignUp(T_cam_map + particles * sizeof(RigidTransformF));
  }
};

// Layout of the results block: ll [n] double, evaluations [n], pairs [n] long long, floor hits
// [n] int, patch starts [patches + 1] int (GPU frame preparation).
struct OutputLayout {
  size_t ll, evals, pairs, hits, patch_begin, total;
  OutputLayout(size_t n, size_t patches) {
    ll = 0;
    evals = alignUp(ll + n * sizeof(double));
    pairs = alignUp(evals + n * sizeof(long long));
    hits = alignUp(pairs + n * sizeof(long long));
    patch_begin = alignUp(hits + n * sizeof(int));
    total = alignUp(patch_begin + (patches + 1) * sizeof(int));
  }
};

}  // namespace

// Everything after the inputs are on the device: membership and likelihood per batch, the
// per-particle reduction, the download; fills `out` (and syncs the stream).
void CudaBackend::Impl::run(const DeviceFrameView& f, int n, const MeasurementParams& params,
                            int max_patch_pixels, bool gpu_frame, BackendOutput* out) {
  const int patches = f.grid.count();
  cudaStream_t s = stream.get();
  const OutputLayout O(n, patches);  // reserved by the caller
  double* ll = reinterpret_cast<double*>(results.data() + O.ll);
  long long* evals = reinterpret_cast<long long*>(results.data() + O.evals);
  long long* pairs = reinterpret_cast<long long*>(results.data() + O.pairs);
  int* hits = reinterpret_cast<int*>(results.data() + O.hits);
  const int batches = launchBatches(f, n, params, max_patch_pixels, ll, hits, evals, pairs);
  download_start.record(s);
  const size_t bytes = gpu_frame ? O.total : O.patch_begin;
  GMM_MCL_CUDA_CHECK(
      cudaMemcpyAsync(h_results.data(), results.data(), bytes, cudaMemcpyDeviceToHost, s));
  download_end.record(s);
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));

  for (int bi = 0; bi < batches; ++bi) {
    out->projection_membership_ms += events[3 * bi + 1].msSince(events[3 * bi]);
    out->likelihood_ms += events[3 * bi + 2].msSince(events[3 * bi + 1]);
  }
  last_transfer_ms += download_end.msSince(download_start);
  const unsigned char* h = h_results.data();
  const double* h_ll = reinterpret_cast<const double*>(h + O.ll);
  const long long* h_evals = reinterpret_cast<const long long*>(h + O.evals);
  const long long* h_pairs = reinterpret_cast<const long long*>(h + O.pairs);
  const int* h_hits = reinterpret_cast<const int*>(h + O.hits);
  for (int i = 0; i < n; ++i) {
    out->log_likelihood[i] = h_ll[i];
    out->floor_hits[i] = h_hits[i];
    out->evaluations += h_evals[i];
    out->relevant_pairs += h_pairs[i];
  }
  if (gpu_frame) {
    const int* pb = reinterpret_cast<const int*>(h + O.patch_begin);
    long long with_pixels = 0;
    for (int p = 0; p < patches; ++p) with_pixels += pb[p + 1] > pb[p] ? 1 : 0;
    out->patches_with_pixels = with_pixels;
    last_frame_pixels = pb[patches];
  }
}

int CudaBackend::Impl::launchBatches(const DeviceFrameView& f, int n,
                                     const MeasurementParams& params, int max_patch_pixels,
                                     double* ll, int* hits, long long* evals, long long* pairs) {
  const int patches = f.grid.count();
  const int words = (num_components + 31) / 32;
  cudaStream_t s = stream.get();
  const size_t smem = cuda::membershipSharedBytes(patches, words);
  if (smem > info.shared_per_block_bytes) {
    throw BackendError("cuda backend: the membership bitmask needs " + std::to_string(smem) +
                       " bytes of shared memory (" + std::to_string(patches) + " patches x " +
                       std::to_string(num_components) + " components); the device allows " +
                       std::to_string(info.shared_per_block_bytes));
  }
  if (smem > shared_limit_set) {
    GMM_MCL_CUDA_CHECK(cuda::setMembershipSharedLimit(smem));
    shared_limit_set = smem;
  }
  // Particles in batches whose masks (and per-particle evaluation forms) fit the budget.
  const bool noise = params.depth_noise.enabled();
  const size_t bytes_per_particle =
      sizeof(uint32_t) * size_t(patches) * std::max(words, 1) +
      (noise ? sizeof(EvalComponentF) * size_t(num_components) : 0);
  const size_t max_by_threads = size_t(0x7fffffff) / (size_t(patches) * 32);  // int indices
  const size_t budget = std::min(kMaskBudgetBytes, info.total_memory_bytes / 16);
  const int batch = static_cast<int>(
      std::max<size_t>(1, std::min<size_t>(std::min<size_t>(n, max_by_threads),
                                           budget / bytes_per_particle)));
  // Earlier evaluations may still be queued on the stream (the device filter does not wait):
  // scratch grows only after them.
  mask.reserve(size_t(batch) * patches * std::max(words, 1), s);
  shift.reserve(size_t(batch) * patches, s);
  if (noise) noisy_eval.reserve(size_t(batch) * num_components, s);
  cuda::MembershipConfig cfg;
  cfg.K = f.K;
  cfg.patch_size_px = f.grid.patch_size_px;
  cfg.patch_cols = f.grid.cols;
  cfg.patch_rows = f.grid.rows;
  cfg.min_depth_m = params.min_component_depth_m;
  cfg.sigma_bound = params.sigma_bound;
  cfg.inflate_px = patchInflation(f.grid.patch_size_px);
  cfg.floor_log_density = params.floor_log_density;
  cfg.depth_noise = params.depth_noise;
  cuda::LikelihoodShape shape = cuda::chooseLikelihoodShape(max_patch_pixels);
  if (const char* env = std::getenv("GMM_MCL_CUDA_SHAPE")) {  // tuning: GROUPSxPX, e.g. 16x4
    int lanes = 0, px = 0;
    if (std::sscanf(env, "%dx%d", &lanes, &px) == 2) {
      shape.lanes = lanes;
      shape.pixels_per_lane = px;
      shape.stage_members = lanes == 32 && px == 4 && max_patch_pixels > 128;
    }
  }
  if (const char* env = std::getenv("GMM_MCL_CUDA_STAGE")) {  // tuning: 0/1 (32x4 only)
    shape.stage_members = env[0] == '1' && shape.lanes == 32 && shape.pixels_per_lane == 4;
  }
  if (const char* env = std::getenv("GMM_MCL_CUDA_BAND")) {  // tuning: patches per item
    const int band = std::atoi(env);
    if (band > 0) shape.band_patches = band;
  }
  const int items = cuda::likelihoodItemsPerParticle(shape, patches);
  item_ll.reserve(size_t(batch) * items, s);
  item_hits.reserve(size_t(batch) * items, s);
  item_evals.reserve(size_t(batch) * items, s);
  item_relevant.reserve(size_t(batch) * items, s);
  const cuda::ItemPartials partials{item_ll.data(), item_hits.data(), item_evals.data(),
                                    item_relevant.data()};
  const int batches = (n + batch - 1) / batch;
  ensureEvents(3 * size_t(batches));
  for (int bi = 0; bi < batches; ++bi) {
    const int first = bi * batch;
    const int count = std::min(batch, n - first);
    events[3 * bi].record(s);
    GMM_MCL_CUDA_CHECK(cuda::launchMembership(
        count, num_components, words, cfg, components.data(), eval_components.data(),
        f.T_cam_map + first, mask.data(), shift.data(), noise ? noisy_eval.data() : nullptr, s));
    events[3 * bi + 1].record(s);
    GMM_MCL_CUDA_CHECK(cuda::launchLikelihood(
        count, patches, words, shape, params.floor_log_density, f.x, f.y, f.z, f.patch_begin,
        noise ? noisy_eval.data() : eval_components.data(), noise ? num_components : 0,
        f.T_map_cam + first, mask.data(), shift.data(), partials, s));
    GMM_MCL_CUDA_CHECK(cuda::launchReduce(count, items, partials, ll + first, hits + first,
                                          evals + first, pairs + first, s));
    events[3 * bi + 2].record(s);
  }
  return batches;
}

namespace {
// The checks of prepareFrame, with its messages.
void checkImage(const DepthImage& image, const Intrinsics& K, const FrameParams& frame_params) {
  const std::string param_err = frame_params.validate();
  if (!param_err.empty()) throw std::invalid_argument("frame parameters: " + param_err);
  const std::string layout_err = image.checkLayout();
  if (!layout_err.empty()) throw std::invalid_argument("depth image: " + layout_err);
  if (image.width_px != K.width_px || image.height_px != K.height_px) {
    throw std::invalid_argument("depth image is " + std::to_string(image.width_px) + "x" +
                                std::to_string(image.height_px) + " but the camera info says " +
                                std::to_string(K.width_px) + "x" + std::to_string(K.height_px));
  }
}

// The frame-preparation kernel's configuration for this image, camera, grid and frame parameters.
cuda::FrameConfig frameConfig(const DepthImage& image, const Intrinsics& K, const PatchGrid& grid,
                              const FrameParams& frame_params) {
  cuda::FrameConfig fc;
  fc.K = K;
  fc.patch_size_px = grid.patch_size_px;
  fc.cols = grid.cols;
  fc.rows = grid.rows;
  fc.stride_px = frame_params.pixel_stride;
  fc.min_range_m = frame_params.min_range_m;
  fc.max_range_m = frame_params.max_range_m;
  fc.millimetres = image.encoding == DepthEncoding::kMono16Millimetres ? 1 : 0;
  fc.row_bytes = image.row_bytes;
  return fc;
}

void resetOutput(int n, BackendOutput* out) {
  out->log_likelihood.assign(n, 0.0);
  out->floor_hits.assign(n, 0);
  out->evaluations = out->relevant_pairs = out->patches_with_pixels = 0;
  out->projection_membership_ms = out->likelihood_ms = 0.0;
}
}  // namespace

void CudaBackend::evaluate(const DepthFrame& frame, const std::vector<RigidTransformF>& T_map_cam,
                           const MeasurementParams& params, BackendOutput* out) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  if (d.num_components == 0) throw BackendError("cuda backend: no map set");
  const int n = static_cast<int>(T_map_cam.size());
  const int patches = frame.grid.count();
  const size_t pixels = frame.size();
  resetOutput(n, out);
  int max_patch_pixels = 0;
  for (int p = 0; p < patches; ++p) {
    const int c = frame.patch_begin[p + 1] - frame.patch_begin[p];
    out->patches_with_pixels += c > 0 ? 1 : 0;
    max_patch_pixels = std::max(max_patch_pixels, c);
  }
  d.last_transfer_ms = d.last_frame_prep_ms = 0.0;
  d.last_frame_pixels = static_cast<int>(pixels);
  if (n == 0 || patches == 0) return;

  // Upload the frame and the poses once, through pinned memory, on the stream.
  const InputLayout L(pixels, 0, patches, n);
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
  d.stagePoses(T_map_cam, L);
  cudaStream_t s = d.stream.get();
  d.upload_start.record(s);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.inputs.data(), h, L.total, cudaMemcpyHostToDevice, s));
  d.upload_end.record(s);
  const OutputLayout O(n, patches);
  d.results.reserve(O.total);
  d.h_results.reserve(O.total);
  const Impl::DeviceFrameView view = d.view(L, frame.intrinsics, frame.grid);
  d.run(view, n, params, max_patch_pixels, false, out);
  d.last_transfer_ms += d.upload_end.msSince(d.upload_start);
}

void CudaBackend::evaluateImage(const DepthImage& image, const Intrinsics& K,
                                const FrameParams& frame_params,
                                const std::vector<RigidTransformF>& T_map_cam,
                                const MeasurementParams& params, BackendOutput* out) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  if (d.num_components == 0) throw BackendError("cuda backend: no map set");
  checkImage(image, K, frame_params);
  const int n = static_cast<int>(T_map_cam.size());
  const PatchGrid grid =
      PatchGrid::forImage(image.width_px, image.height_px, frame_params.patch_size_px);
  const int patches = grid.count();
  resetOutput(n, out);
  d.last_transfer_ms = d.last_frame_prep_ms = 0.0;
  d.last_frame_pixels = 0;
  if (n == 0 || patches == 0) return;
  const int st = frame_params.pixel_stride;
  const size_t max_pixels =
      size_t((image.width_px + st - 1) / st) * ((image.height_px + st - 1) / st);
  // Only the rows on the stride grid (v = 0, st, 2 st, ...) are uploaded.
  const int rows = (image.height_px + st - 1) / st;
  const size_t image_bytes = image.row_bytes * rows;
  const InputLayout L(max_pixels, image_bytes, patches, n);
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream.get()));
  d.staging.reserve(L.total);
  d.inputs.reserve(L.total);
  d.counts.reserve(patches);
  unsigned char* h = d.staging.data();
  for (int r = 0; r < rows; ++r) {
    std::memcpy(h + L.image + r * image.row_bytes,
                image.data.data() + size_t(r) * st * image.row_bytes, image.row_bytes);
  }
  d.stagePoses(T_map_cam, L);
  cudaStream_t s = d.stream.get();
  // Upload only the image and the poses (not the points: they are made here).
  d.upload_start.record(s);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.inputs.data() + L.image, h + L.image, L.total - L.image,
                                     cudaMemcpyHostToDevice, s));
  d.upload_end.record(s);
  const OutputLayout O(n, patches);
  d.results.reserve(O.total);
  d.h_results.reserve(O.total);
  Impl::DeviceFrameView view = d.view(L, K, grid);
  view.patch_begin = reinterpret_cast<const int*>(d.results.data() + O.patch_begin);
  const cuda::FrameConfig fc = frameConfig(image, K, grid, frame_params);
  GMM_MCL_CUDA_CHECK(cuda::launchFramePrep(
      fc, d.inputs.data() + L.image, d.counts.data(), const_cast<int*>(view.patch_begin),
      const_cast<float*>(view.x), const_cast<float*>(view.y), const_cast<float*>(view.z), s));
  d.prep_end.record(s);
  const int side = (frame_params.patch_size_px + st - 1) / st;
  d.run(view, n, params, side * side, true, out);
  d.last_transfer_ms += d.upload_end.msSince(d.upload_start);
  d.last_frame_prep_ms = d.prep_end.msSince(d.upload_end);
}

void CudaBackend::membership(const DepthFrame& frame, const RigidTransformF& T_map_cam,
                             const MeasurementParams& params, PatchMembership* out) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
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
  const RigidTransformF T_cam_map = invertRigid(T_map_cam);
  GMM_MCL_CUDA_CHECK(
      cudaMemcpyAsync(pose.data(), &T_cam_map, sizeof(T_cam_map), cudaMemcpyHostToDevice, s));
  cuda::MembershipConfig cfg;
  cfg.K = frame.intrinsics;
  cfg.patch_size_px = frame.grid.patch_size_px;
  cfg.patch_cols = frame.grid.cols;
  cfg.patch_rows = frame.grid.rows;
  cfg.min_depth_m = params.min_component_depth_m;
  cfg.sigma_bound = params.sigma_bound;
  cfg.inflate_px = patchInflation(frame.grid.patch_size_px);
  cfg.floor_log_density = params.floor_log_density;
  cfg.depth_noise = params.depth_noise;
  cuda::DeviceBuffer<EvalComponentF> noisy(params.depth_noise.enabled() ? d.num_components : 1);
  GMM_MCL_CUDA_CHECK(cuda::launchMembership(1, d.num_components, words, cfg, d.components.data(),
                                            d.eval_components.data(), pose.data(), mask.data(),
                                            shift.data(), noisy.data(), s));
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

namespace {
// Layout of the device frame block (offsets in bytes): points, patch starts, per-patch counts.
struct DeviceFrameLayout {
  size_t x, y, z, patch_begin, counts, total;
  DeviceFrameLayout(size_t pixels, size_t patches) {
    x = 0;
    y = alignUp(x + pixels * sizeof(float));
    z = alignUp(y + pixels * sizeof(float));
    patch_begin = alignUp(z + pixels * sizeof(float));
    counts = alignUp(patch_begin + (patches + 1) * sizeof(int));
    total = alignUp(counts + patches * sizeof(int));
  }
};
}  // namespace

CudaBackend::DeviceFrameInfo CudaBackend::prepareDeviceFrame(const DepthImage& image,
                                                             const Intrinsics& K,
                                                             const FrameParams& frame_params) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  checkImage(image, K, frame_params);
  d.has_dframe = false;
  const PatchGrid grid =
      PatchGrid::forImage(image.width_px, image.height_px, frame_params.patch_size_px);
  const int patches = grid.count();
  const int st = frame_params.pixel_stride;
  const size_t max_pixels =
      size_t((image.width_px + st - 1) / st) * ((image.height_px + st - 1) / st);
  const int rows = (image.height_px + st - 1) / st;
  const size_t image_bytes = image.row_bytes * rows;
  const DeviceFrameLayout L(max_pixels, patches);
  cudaStream_t s = d.stream.get();
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));  // the staging buffers are free again
  d.dframe.reserve(L.total);
  d.dframe_image.reserve(std::max<size_t>(image_bytes, 1));
  d.dframe_staging.reserve(std::max<size_t>(image_bytes, 1));
  d.dframe_patch_begin.reserve(patches + 1);
  // Only the rows on the stride grid (v = 0, st, 2 st, ...) are uploaded.
  for (int r = 0; r < rows; ++r) {
    std::memcpy(d.dframe_staging.data() + size_t(r) * image.row_bytes,
                image.data.data() + size_t(r) * st * image.row_bytes, image.row_bytes);
  }
  unsigned char* dev = d.dframe.data();
  DeviceFrameInfo info;
  if (patches > 0) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.dframe_image.data(), d.dframe_staging.data(), image_bytes,
                                       cudaMemcpyHostToDevice, s));
    const cuda::FrameConfig fc = frameConfig(image, K, grid, frame_params);
    GMM_MCL_CUDA_CHECK(cuda::launchFramePrep(
        fc, d.dframe_image.data(), reinterpret_cast<int*>(dev + L.counts),
        reinterpret_cast<int*>(dev + L.patch_begin), reinterpret_cast<float*>(dev + L.x),
        reinterpret_cast<float*>(dev + L.y), reinterpret_cast<float*>(dev + L.z), s));
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.dframe_patch_begin.data(), dev + L.patch_begin,
                                       (patches + 1) * sizeof(int), cudaMemcpyDeviceToHost, s));
    GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
    const int* pb = d.dframe_patch_begin.data();
    for (int p = 0; p < patches; ++p) info.patches_with_pixels += pb[p + 1] > pb[p] ? 1 : 0;
    info.pixels = pb[patches];
  }
  d.dframe_K = K;
  d.dframe_grid = grid;
  d.dframe_x = L.x;
  d.dframe_y = L.y;
  d.dframe_z = L.z;
  d.dframe_patch_begin_at = L.patch_begin;
  const int side = (frame_params.patch_size_px + st - 1) / st;
  d.dframe_max_patch_pixels = side * side;
  d.dframe_pixels = info.pixels;
  d.has_dframe = true;
  return info;
}

CudaBackend::DeviceFrameInfo CudaBackend::uploadDeviceFrame(const DepthFrame& frame) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  d.has_dframe = false;
  const int patches = frame.grid.count();
  const size_t pixels = frame.size();
  const DeviceFrameLayout L(pixels, patches);
  cudaStream_t s = d.stream.get();
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
  d.dframe.reserve(L.total);
  d.dframe_staging.reserve(L.total);
  unsigned char* h = d.dframe_staging.data();
  DeviceFrameInfo info;
  int max_patch_pixels = 0;
  for (int p = 0; p < patches; ++p) {
    const int c = frame.patch_begin[p + 1] - frame.patch_begin[p];
    info.patches_with_pixels += c > 0 ? 1 : 0;
    max_patch_pixels = std::max(max_patch_pixels, c);
  }
  info.pixels = static_cast<int>(pixels);
  if (pixels > 0) {
    std::memcpy(h + L.x, frame.x_m.data(), pixels * sizeof(float));
    std::memcpy(h + L.y, frame.y_m.data(), pixels * sizeof(float));
    std::memcpy(h + L.z, frame.z_m.data(), pixels * sizeof(float));
  }
  if (patches > 0) {
    std::memcpy(h + L.patch_begin, frame.patch_begin.data(), (patches + 1) * sizeof(int));
  }
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.dframe.data(), h, L.total, cudaMemcpyHostToDevice, s));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));  // the staging buffer is free again
  d.dframe_K = frame.intrinsics;
  d.dframe_grid = frame.grid;
  d.dframe_x = L.x;
  d.dframe_y = L.y;
  d.dframe_z = L.z;
  d.dframe_patch_begin_at = L.patch_begin;
  d.dframe_max_patch_pixels = max_patch_pixels;
  d.dframe_pixels = info.pixels;
  d.has_dframe = true;
  return info;
}

bool CudaBackend::hasDeviceFrame() const { return impl_->has_dframe; }

void CudaBackend::evaluateDevicePoses(int n, const RigidTransformF* T_map_cam,
                                      const RigidTransformF* T_cam_map,
                                      const MeasurementParams& params, double* log_likelihood,
                                      int* floor_hits, long long* evaluations,
                                      long long* relevant_pairs) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  if (d.num_components == 0) throw BackendError("cuda backend: no map set");
  if (!d.has_dframe) throw BackendError("cuda backend: no frame on the device");
  d.device_batches = 0;
  if (n <= 0 || d.dframe_grid.count() == 0) return;
  const unsigned char* dev = d.dframe.data();
  Impl::DeviceFrameView v;
  v.K = d.dframe_K;
  v.grid = d.dframe_grid;
  v.x = reinterpret_cast<const float*>(dev + d.dframe_x);
  v.y = reinterpret_cast<const float*>(dev + d.dframe_y);
  v.z = reinterpret_cast<const float*>(dev + d.dframe_z);
  v.patch_begin = reinterpret_cast<const int*>(dev + d.dframe_patch_begin_at);
  v.T_map_cam = T_map_cam;
  v.T_cam_map = T_cam_map;
  d.device_batches = d.launchBatches(v, n, params, d.dframe_max_patch_pixels, log_likelihood,
                                     floor_hits, evaluations, relevant_pairs);
}

void CudaBackend::deviceStageMs(double* projection_membership_ms, double* likelihood_ms) const {
  const Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  *projection_membership_ms = *likelihood_ms = 0.0;
  for (int bi = 0; bi < d.device_batches; ++bi) {
    *projection_membership_ms += d.events[3 * bi + 1].msSince(d.events[3 * bi]);
    *likelihood_ms += d.events[3 * bi + 2].msSince(d.events[3 * bi + 1]);
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
