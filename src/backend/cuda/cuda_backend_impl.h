// The CUDA backend's device state (CudaBackend::Impl) and the layouts of its transfer blocks,
// shared by cuda_backend.cpp (construction, uploads, device frames) and cuda_backend_launch.cpp
// (view cull, membership and likelihood launches, downloads).
#pragma once

#include <cuda_runtime_api.h>

#include <cstring>
#include <limits>
#include <memory>
#include <vector>

#include "cuda/cuda_backend.h"
#include "cuda/cuda_normal_equations.h"
#include "cuda/device_buffer.cuh"
#include "cuda/kernels.cuh"
#include "gmm_mcl/map/component_grid.h"

namespace gmm_mcl {
namespace cuda {

inline size_t alignUp(size_t n) { return (n + 255) & ~size_t(255); }

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

// The camera K with the patch grid `grid`, as the kernels' configurations hold them.
PatchCamera patchCamera(const Intrinsics& K, const PatchGrid& grid);

// The membership kernel's configuration for a frame's camera and grid.
MembershipConfig membershipConfig(const Intrinsics& K, const PatchGrid& grid,
                                  const MeasurementParams& params);

}  // namespace cuda

struct CudaBackend::Impl {
  BackendDeviceInfo info;
  CudaTuningParams tuning;  // the kernels' shapes and thresholds (the table's cuda_* parameters)
  int device = 0;
  cuda::Stream stream;
  int num_components = 0;
  // The device's component order (setMap: Z order for large maps) against the map's: device
  // index k holds map component device_to_map[k]; both empty: the map's own order.
  std::vector<int> device_to_map, map_to_device;
  cuda::DeviceBuffer<ComponentF> components;
  cuda::DeviceBuffer<EvalComponentF> eval_components;  // log2 form (likelihood kernel)
  // Per-update inputs: one pinned staging buffer, one device buffer of the same layout.
  cuda::PinnedBuffer<unsigned char> staging;
  cuda::DeviceBuffer<unsigned char> inputs;
  // Per-batch scratch and per-particle outputs.
  cuda::DeviceBuffer<uint32_t> mask;
  cuda::DeviceBuffer<float> shift;
  // [batch][M] with the depth-noise model on; [batch][local stride] with local lists
  cuda::DeviceBuffer<EvalComponentF> noisy_eval;
  cuda::DeviceBuffer<int> local_most;  // the local lists' size (launchLocalCount)
  cuda::PinnedBuffer<int> h_local_most;
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
  // Per-update view cull (cullView): flags, compact index list and tables, the count read back.
  cuda::DeviceBuffer<int> cull_flags, cull_index;
  cuda::DeviceBuffer<ComponentF> cull_components;
  cuda::DeviceBuffer<EvalComponentF> cull_eval;
  cuda::DeviceBuffer<float4> cull_chunks;
  std::vector<int> device_candidates;  // the grid's candidates in the device's order
  cuda::PinnedBuffer<int> cull_count;
  int last_visible_components = -1;  // of the last cull (-1: the whole map)
  // The map's component grid (host) and, in a large map, the cull's candidates from it: the
  // poses read back, their inverses, the candidate list and its device copy.
  ComponentGrid grid;
  cuda::PinnedBuffer<RigidTransformF> cull_poses;
  std::vector<RigidTransformF> host_T_map_cam;
  std::vector<int> host_candidates;
  cuda::DeviceBuffer<int> cull_candidates;
  // A cloud spread over several places (launchGroups): the poses' order by place and the group
  // starts, the permuted poses (T_cam_map, then T_map_cam) and the order, staged and on the device.
  std::vector<int> group_order, group_begin;
  cuda::PinnedBuffer<unsigned char> group_staging;
  cuda::DeviceBuffer<unsigned char> group_inputs;
  std::vector<RigidTransformF> group_map_cam;
  std::vector<char> group_visible;  // union of the groups' visible components
  ComponentGrid::Scratch grid_scratch;
  float dframe_max_range_m = std::numeric_limits<float>::infinity();

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
  DeviceFrameView view(const Layout& L, const Intrinsics& K, const PatchGrid& grid,
                       float max_range_m);
  void run(const DeviceFrameView& f, int n, const MeasurementParams& params, int max_patch_pixels,
           bool gpu_frame, BackendOutput* out);
  // Membership, likelihood and the per-particle reduction of n poses in batches, queued on the
  // stream, per-particle results to the given device arrays; returns the batch count (three
  // events per batch).
  int launchBatches(const DeviceFrameView& f, int n, const MeasurementParams& params,
                    int max_patch_pixels, double* ll, int* hits, long long* evals,
                    long long* pairs);

  // The components a membership launch over these n poses works on: the compact visible list
  // of the view cull (after a wait for its count), or the whole map below the number of
  // (pose, component) pairs where the cull pays; `index` maps compact to map indices (null:
  // the identity).
  struct ComponentSet {
    int count;
    const ComponentF* components;
    const EvalComponentF* eval;
    const int* index;
    const float4* chunks;  // the chunk balls of the compact list (null: none, every chunk tested)
  };
  ComponentSet cullView(const cuda::MembershipConfig& cfg, const RigidTransformF* T_cam_map, int n);
  // The cull over the given candidates (host list; null: the whole map).
  ComponentSet cullCandidates(const cuda::MembershipConfig& cfg, const RigidTransformF* T_cam_map,
                              int n, const std::vector<int>* candidates);
  // Where a large map's grid gives candidates: the poses read back to the host (their
  // inverses in host_T_map_cam) and grouped by place; false below the sizes where it pays.
  bool groupByPlace(const cuda::MembershipConfig& cfg, const RigidTransformF* T_cam_map, int n);
  // launchBatches per group of groupByPlace (more than one): the poses gathered by group, per
  // group its candidates, cull and batches, the results scattered back to particle order.
  int launchGroups(const DeviceFrameView& f, int n, const MeasurementParams& params,
                   const cuda::MembershipConfig& cfg, int max_patch_pixels, double* ll, int* hits,
                   long long* evals, long long* pairs);
  // Membership, likelihood and reduction of poses [0, n) of the given arrays over `set`, from
  // event batch `first_batch` (its start already recorded); order (device, may be null): the
  // output index of each pose. Returns the batches launched.
  int launchSet(const DeviceFrameView& f, int n, const RigidTransformF* T_cam_map,
                const RigidTransformF* T_map_cam, const int* order, const MeasurementParams& params,
                const cuda::MembershipConfig& cfg, int max_patch_pixels, const ComponentSet& set,
                int first_batch, double* ll, int* hits, long long* evals, long long* pairs);

  // The membership kernel's bitmask words per pass for `words` words (cuda::balancedPassWords
  // of tuning.membership_pass_words, where the block's shared memory holds them).
  int membershipPassWords(int patches, int words, bool local, bool chunked) const;
  // Raises the membership kernel's shared-memory limit for this grid and bitmask; throws when
  // the device cannot hold it.
  void ensureMembershipShared(int patches, int words, int visible, bool local = false,
                              bool chunked = false);

  // Records the device frame just uploaded or prepared (offsets of its layout L).
  template <typename Layout>
  void setDeviceFrame(const Intrinsics& K, const PatchGrid& grid, const Layout& L,
                      int max_patch_pixels, int pixels, float max_range_m) {
    dframe_max_range_m = max_range_m;
    dframe_K = K;
    dframe_grid = grid;
    dframe_x = L.x;
    dframe_y = L.y;
    dframe_z = L.z;
    dframe_patch_begin_at = L.patch_begin;
    dframe_max_patch_pixels = max_patch_pixels;
    dframe_pixels = pixels;
    has_dframe = true;
  }

  void ensureEvents(size_t n) {
    while (events.size() < n) events.emplace_back();
  }
};

// Device pointers of one update's inputs.
struct CudaBackend::Impl::DeviceFrameView {
  Intrinsics K;
  PatchGrid grid;
  const float *x, *y, *z;
  const int* patch_begin;
  const RigidTransformF* T_map_cam;
  const RigidTransformF* T_cam_map;
  float max_range_m;  // the frame's range window's far end (the view cull's depth)
};

template <typename Layout>
CudaBackend::Impl::DeviceFrameView CudaBackend::Impl::view(const Layout& L, const Intrinsics& K,
                                                           const PatchGrid& grid,
                                                           float max_range_m) {
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
  v.max_range_m = max_range_m;
  return v;
}

}  // namespace gmm_mcl
