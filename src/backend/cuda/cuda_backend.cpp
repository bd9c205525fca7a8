// Host side of the CUDA backend: device set-up, the map, uploads of frames and poses, device
// frames, timing (the per-update launches are in cuda_backend_launch.cpp).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "cuda/cuda_backend_impl.h"
#include "cuda/cuda_factory.h"

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

CudaBackend::CudaBackend(int device, const CudaTuningParams& tuning) {
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
  impl_->tuning = tuning;
  BackendDeviceInfo& info = impl_->info;
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
  info.flops_per_evaluation = kCudaFlopsPerEvaluation;
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

const BackendDeviceInfo& CudaBackend::deviceInfo() const { return impl_->info; }
const CudaTuningParams& CudaBackend::tuning() const { return impl_->tuning; }
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

std::unique_ptr<NormalEquationsEvaluator> CudaBackend::makeNormalEquations() {
  return std::make_unique<cuda::CudaNormalEquations>(impl_->info.device, impl_->stream.get(),
                                                     [](cuda::BackendFrameRef*) { return false; });
}

namespace {

// The Z order's cells (CudaTuningParams::z_order_min_components).
constexpr double kZOrderCell_m = 0.25;

// Interleaves the low 21 bits of x with two zero bits between each.
uint64_t spreadBits(uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}

// The map's component indices in the Z order of their means (ties by index).
std::vector<int> zOrder(const std::vector<ComponentF>& packed) {
  float lo[3] = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                 std::numeric_limits<float>::max()};
  for (const ComponentF& c : packed) {
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], c.mean_m[a]);
  }
  std::vector<std::pair<uint64_t, int>> keyed(packed.size());
  for (size_t i = 0; i < packed.size(); ++i) {
    uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      const double cell = std::floor((packed[i].mean_m[a] - lo[a]) / kZOrderCell_m);
      const uint64_t q = static_cast<uint64_t>(std::min(std::max(cell, 0.0), 2097151.0));
      key |= spreadBits(q) << a;
    }
    keyed[i] = {key, static_cast<int>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int> order(packed.size());
  for (size_t k = 0; k < keyed.size(); ++k) order[k] = keyed[k].second;
  return order;
}

}  // namespace

void CudaBackend::setMap(const GmmMap& map) {
  const cuda::DeviceScope scope(impl_->device);
  Impl& d = *impl_;
  const std::vector<ComponentF>& packed_in = map.packed();
  const int m = static_cast<int>(packed_in.size());
  d.device_to_map.clear();
  d.map_to_device.clear();
  std::vector<ComponentF> reordered;
  if (m >= d.tuning.z_order_min_components) {
    d.device_to_map = zOrder(packed_in);
    d.map_to_device.resize(m);
    reordered.resize(m);
    for (int k = 0; k < m; ++k) {
      d.map_to_device[d.device_to_map[k]] = k;
      reordered[k] = packed_in[d.device_to_map[k]];
    }
  }
  const std::vector<ComponentF>& packed = reordered.empty() ? packed_in : reordered;
  std::vector<EvalComponentF> ev(m);
  for (int i = 0; i < m; ++i) ev[i] = makeEvalComponentF(packed[i], kEvalScaleLog2);
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream.get()));
  d.components.reserve(std::max(m, 1));
  d.eval_components.reserve(std::max(m, 1));
  if (m > 0) {
    GMM_MCL_CUDA_CHECK(cudaMemcpy(d.components.data(), packed.data(), m * sizeof(ComponentF),
                                  cudaMemcpyHostToDevice));
    GMM_MCL_CUDA_CHECK(cudaMemcpy(d.eval_components.data(), ev.data(), m * sizeof(EvalComponentF),
                                  cudaMemcpyHostToDevice));
  }
  d.num_components = m;
  d.grid = map.grid();
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
  fc.cam = cuda::patchCamera(K, grid);
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
  const cuda::InputLayout L(pixels, 0, patches, n);
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
  const cuda::OutputLayout O(n, patches);
  d.results.reserve(O.total);
  d.h_results.reserve(O.total);
  const Impl::DeviceFrameView view = d.view(L, frame.intrinsics, frame.grid, frame.max_range_m);
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
  const cuda::InputLayout L(max_pixels, image_bytes, patches, n);
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
  const cuda::OutputLayout O(n, patches);
  d.results.reserve(O.total);
  d.h_results.reserve(O.total);
  Impl::DeviceFrameView view = d.view(L, K, grid, frame_params.max_range_m);
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

namespace {
// Layout of the device frame block (offsets in bytes): points, patch starts, per-patch counts.
struct DeviceFrameLayout {
  size_t x, y, z, patch_begin, counts, total;
  DeviceFrameLayout(size_t pixels, size_t patches) {
    x = 0;
    y = cuda::alignUp(x + pixels * sizeof(float));
    z = cuda::alignUp(y + pixels * sizeof(float));
    patch_begin = cuda::alignUp(z + pixels * sizeof(float));
    counts = cuda::alignUp(patch_begin + (patches + 1) * sizeof(int));
    total = cuda::alignUp(counts + patches * sizeof(int));
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
  const int side = (frame_params.patch_size_px + st - 1) / st;
  d.setDeviceFrame(K, grid, L, side * side, info.pixels, frame_params.max_range_m);
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
  d.setDeviceFrame(frame.intrinsics, frame.grid, L, max_patch_pixels, info.pixels,
                   frame.max_range_m);
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
  v.max_range_m = d.dframe_max_range_m;
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

std::unique_ptr<LikelihoodBackend> makeCudaBackend(const CudaTuningParams& tuning,
                                                   std::string* why) {
  try {
    return std::unique_ptr<LikelihoodBackend>(new CudaBackend(0, tuning));
  } catch (const BackendError& e) {
    if (why) *why = e.what();
    return nullptr;
  }
}

}  // namespace gmm_mcl
