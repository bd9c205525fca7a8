// The CUDA backend's per-update launches: the view cull, membership, likelihood and reduction
// per batch of particles, the download of the results, and the membership table of one pose.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "cuda/cuda_backend_impl.h"
#include "gmm_mcl/measurement/membership.h"
#include "gmm_mcl/measurement/projection.h"

namespace gmm_mcl {

namespace {

// Device memory for the membership masks and per-particle evaluation forms of one batch of
// particles is bounded by this, and by a sixteenth of the device's memory (512 MB on an 8 GB
// TX2). Measured on an H100: 1 GB instead of 256 MB takes `scale` from 33 batches to 9 (28.8 ms
// per update instead of 29.7-30.5) and `large` (M = 4000) from 2 batches to 1 (1.69 ms instead
// of 1.86-1.96); 4 GB gains nothing more.
constexpr size_t kMaskBudgetBytes = size_t(1) << 30;

// From this many components on, the view cull tests only the map grid's candidates.
constexpr int kGridCandidatesMinComponents = 20000;

}  // namespace

// Everything after the inputs are on the device: membership and likelihood per batch, the
// per-particle reduction, the download; fills `out` (and syncs the stream).
void CudaBackend::Impl::run(const DeviceFrameView& f, int n, const MeasurementParams& params,
                            int max_patch_pixels, bool gpu_frame, BackendOutput* out) {
  const int patches = f.grid.count();
  cudaStream_t s = stream.get();
  const cuda::OutputLayout O(n, patches);  // reserved by the caller
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
  out->visible_components = last_visible_components;
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

namespace cuda {
PatchCamera patchCamera(const Intrinsics& K, const PatchGrid& grid) {
  PatchCamera cam;
  cam.K = K;
  cam.patch_size_px = grid.patch_size_px;
  cam.patch_cols = grid.cols;
  cam.patch_rows = grid.rows;
  return cam;
}

MembershipConfig membershipConfig(const Intrinsics& K, const PatchGrid& grid,
                                  const MeasurementParams& params) {
  MembershipConfig cfg;
  cfg.cam = patchCamera(K, grid);
  cfg.min_depth_m = params.min_component_depth_m;
  cfg.sigma_bound = params.sigma_bound;
  cfg.inflate_px = patchInflation(grid.patch_size_px);
  cfg.floor_log_density = params.floor_log_density;
  cfg.depth_noise = params.depth_noise;
  cfg.reach =
      viewReach(K, grid.patch_size_px, grid.cols, grid.rows, cfg.inflate_px,
                std::numeric_limits<float>::infinity(), params.sigma_bound, params.depth_noise);
  return cfg;
}
}  // namespace cuda

namespace {

// The likelihood kernel's shape for the largest patch, with the tuning's overrides
// (cuda_likelihood_shape GROUPSxPX, cuda_stage_members, cuda_band_patches).
cuda::LikelihoodShape likelihoodShape(int max_patch_pixels, const CudaTuningParams& tuning) {
  cuda::LikelihoodShape shape = cuda::chooseLikelihoodShape(max_patch_pixels);
  int lanes = 0, px = 0;
  if (std::sscanf(tuning.likelihood_shape.c_str(), "%dx%d", &lanes, &px) == 2) {
    shape.lanes = lanes;
    shape.pixels_per_lane = px;
    shape.stage_members = lanes == 32 && px == 4 && max_patch_pixels > 128;
  }
  if (tuning.stage_members != "auto") {  // 32x4 only
    shape.stage_members =
        tuning.stage_members == "on" && shape.lanes == 32 && shape.pixels_per_lane == 4;
  }
  if (tuning.band_patches > 0) shape.band_patches = tuning.band_patches;
  return shape;
}

}  // namespace

bool CudaBackend::Impl::groupByPlace(const cuda::MembershipConfig& cfg,
                                     const RigidTransformF* T_cam_map, int n) {
  if (static_cast<long long>(n) * num_components < tuning.view_cull_min_pairs ||
      num_components < kGridCandidatesMinComponents || grid.size() == 0) {
    return false;
  }
  cudaStream_t s = stream.get();
  cull_poses.reserve(n);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(cull_poses.data(), T_cam_map, n * sizeof(RigidTransformF),
                                     cudaMemcpyDeviceToHost, s));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
  host_T_map_cam.resize(n);
  for (int i = 0; i < n; ++i) host_T_map_cam[i] = invertRigid(cull_poses.data()[i]);
  groupPosesByPlace(host_T_map_cam, viewGroupCell(cfg.reach), &group_order, &group_begin);
  return true;
}

CudaBackend::Impl::ComponentSet CudaBackend::Impl::cullView(const cuda::MembershipConfig& cfg,
                                                            const RigidTransformF* T_cam_map,
                                                            int n) {
  if (static_cast<long long>(n) * num_components < tuning.view_cull_min_pairs) {
    last_visible_components = -1;
    return {num_components, components.data(), eval_components.data(), nullptr, nullptr};
  }
  // In a large map, only the grid's components near the poses' views are tested: the poses come
  // back to the host (48 bytes each) and the map grid gives the candidates per group of poses.
  if (groupByPlace(cfg, T_cam_map, n)) {
    viewCandidates(grid, host_T_map_cam, group_order, group_begin, cfg.cam.K, cfg.reach,
                   &host_candidates);
    return cullCandidates(cfg, T_cam_map, n, &host_candidates);
  }
  return cullCandidates(cfg, T_cam_map, n, nullptr);
}

CudaBackend::Impl::ComponentSet CudaBackend::Impl::cullCandidates(
    const cuda::MembershipConfig& cfg, const RigidTransformF* T_cam_map, int n,
    const std::vector<int>* host_list) {
  cudaStream_t s = stream.get();
  const int* candidates = nullptr;
  int num_candidates = 0;
  if (host_list && !map_to_device.empty()) {
    // The grid's map indices in the device's order, ascending (the cull compacts its flags in
    // the list's order: the set comes out in the device's order).
    device_candidates.resize(host_list->size());
    for (size_t k = 0; k < host_list->size(); ++k)
      device_candidates[k] = map_to_device[(*host_list)[k]];
    std::sort(device_candidates.begin(), device_candidates.end());
    host_list = &device_candidates;
  }
  if (host_list) {
    num_candidates = static_cast<int>(host_list->size());
    cull_candidates.reserve(std::max(num_candidates, 1), s);
    if (num_candidates > 0) {
      GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(cull_candidates.data(), host_list->data(),
                                         num_candidates * sizeof(int), cudaMemcpyHostToDevice, s));
    }
    candidates = cull_candidates.data();
  }
  cull_flags.reserve(size_t(num_components) + 1, s);
  cull_index.reserve(size_t(num_components) + 1, s);
  cull_components.reserve(num_components, s);
  cull_eval.reserve(num_components, s);
  cull_chunks.reserve(std::max(cuda::chunkCount(num_components), 1), s);
  cull_count.reserve(1);
  // The visible count is stored after the index list.
  int* count = cull_index.data() + num_components;
  const cuda::ViewCullBuffers b{
      cull_flags.data(), cull_index.data(), cull_components.data(), cull_eval.data(), count,
      cull_chunks.data()};
  GMM_MCL_CUDA_CHECK(cuda::launchViewCull(n, num_components, cfg, components.data(),
                                          eval_components.data(), T_cam_map, candidates,
                                          num_candidates, b, s));
  GMM_MCL_CUDA_CHECK(
      cudaMemcpyAsync(cull_count.data(), count, sizeof(int), cudaMemcpyDeviceToHost, s));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));  // the count sizes the launches below
  last_visible_components = cull_count.data()[0];
  return {last_visible_components, cull_components.data(), cull_eval.data(), cull_index.data(),
          cull_chunks.data()};
}

void CudaBackend::Impl::ensureMembershipShared(int patches, int words, int visible, bool local,
                                               bool chunked) {
  const size_t smem = cuda::membershipSharedBytes(patches, words, local, chunked);
  if (smem > info.shared_per_block_bytes) {
    throw BackendError("cuda backend: the membership bitmask needs " + std::to_string(smem) +
                       " bytes of shared memory (" + std::to_string(patches) + " patches x " +
                       std::to_string(visible) + " visible components); the device allows " +
                       std::to_string(info.shared_per_block_bytes));
  }
  if (smem > shared_limit_set) {
    GMM_MCL_CUDA_CHECK(cuda::setMembershipSharedLimit(smem));
    shared_limit_set = smem;
  }
}

int CudaBackend::Impl::membershipPassWords(int patches, int words, bool local, bool chunked) const {
  const int pass_words = tuning.membership_pass_words;
  const int balanced = cuda::balancedPassWords(words, pass_words);
  // Balanced passes are at most half as large again as pass_words: where such a bitmask would
  // not fit a block's shared memory, passes of pass_words words.
  if (balanced > pass_words && pass_words > 0 &&
      cuda::membershipSharedBytes(patches, balanced, local, chunked) >
          info.shared_per_block_bytes) {
    return pass_words;
  }
  return balanced;
}

int CudaBackend::Impl::launchBatches(const DeviceFrameView& f, int n,
                                     const MeasurementParams& params, int max_patch_pixels,
                                     double* ll, int* hits, long long* evals, long long* pairs) {
  cudaStream_t s = stream.get();
  cuda::MembershipConfig cfg = cuda::membershipConfig(f.K, f.grid, params);
  cfg.reach = viewReach(f.K, f.grid.patch_size_px, f.grid.cols, f.grid.rows, cfg.inflate_px,
                        f.max_range_m, params.sigma_bound, params.depth_noise);
  ensureEvents(3);
  events[0].record(s);
  // Membership and likelihood run on the components some pose can see (bitmasks sized by them).
  // A cloud spread over several places of a large map (a start from a uniform cloud, a lost
  // detector's redraw) is evaluated group by group, each over what its own views can see.
  ComponentSet set;
  if (groupByPlace(cfg, f.T_cam_map, n)) {
    if (tuning.place_groups && group_begin.size() > 2) {
      return launchGroups(f, n, params, cfg, max_patch_pixels, ll, hits, evals, pairs);
    }
    viewCandidates(grid, host_T_map_cam, group_order, group_begin, cfg.cam.K, cfg.reach,
                   &host_candidates);
    set = cullCandidates(cfg, f.T_cam_map, n, &host_candidates);
  } else {
    set = cullView(cfg, f.T_cam_map, n);
  }
  return launchSet(f, n, f.T_cam_map, f.T_map_cam, nullptr, params, cfg, max_patch_pixels, set, 0,
                   ll, hits, evals, pairs);
}

int CudaBackend::Impl::launchGroups(const DeviceFrameView& f, int n,
                                    const MeasurementParams& params,
                                    const cuda::MembershipConfig& cfg, int max_patch_pixels,
                                    double* ll, int* hits, long long* evals, long long* pairs) {
  cudaStream_t s = stream.get();
  // The poses in group order, copied from the device arrays as they are (T_cam_map is in
  // cull_poses already; the inverse is not recomputed: the same floats as one launch would use).
  const size_t pose_bytes = size_t(n) * sizeof(RigidTransformF);
  const size_t map_cam_at = cuda::alignUp(pose_bytes);
  const size_t order_at = cuda::alignUp(map_cam_at + pose_bytes);
  const size_t total = order_at + size_t(n) * sizeof(int);
  group_staging.reserve(total);
  group_inputs.reserve(total, s);
  unsigned char* h = group_staging.data();
  GMM_MCL_CUDA_CHECK(
      cudaMemcpyAsync(h + map_cam_at, f.T_map_cam, pose_bytes, cudaMemcpyDeviceToHost, s));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
  group_map_cam.assign(reinterpret_cast<const RigidTransformF*>(h + map_cam_at),
                       reinterpret_cast<const RigidTransformF*>(h + map_cam_at) + n);
  RigidTransformF* cam_map = reinterpret_cast<RigidTransformF*>(h);
  RigidTransformF* map_cam = reinterpret_cast<RigidTransformF*>(h + map_cam_at);
  int* order = reinterpret_cast<int*>(h + order_at);
  for (int k = 0; k < n; ++k) {
    const int i = group_order[k];
    cam_map[k] = cull_poses.data()[i];
    map_cam[k] = group_map_cam[i];
    order[k] = i;
  }
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(group_inputs.data(), h, total, cudaMemcpyHostToDevice, s));
  const RigidTransformF* d_cam_map = reinterpret_cast<const RigidTransformF*>(group_inputs.data());
  const RigidTransformF* d_map_cam =
      reinterpret_cast<const RigidTransformF*>(group_inputs.data() + map_cam_at);
  const int* d_order = reinterpret_cast<const int*>(group_inputs.data() + order_at);
  // Per group: its candidates, cull (the stream waits for its count) and batches. The visible
  // count reported is the union over the groups.
  group_visible.assign(num_components, 0);
  std::vector<int> index;
  int batches = 0;
  const int groups = static_cast<int>(group_begin.size()) - 1;
  for (int g = 0; g < groups; ++g) {
    const int first = group_begin[g], count = group_begin[g + 1] - first;
    if (g > 0) {
      ensureEvents(3 * size_t(batches + 1));
      events[3 * batches].record(s);
    }
    grid.query(
        groupViewBox(host_T_map_cam, group_order.data() + first, count, cfg.cam.K, cfg.reach),
        &host_candidates, &grid_scratch);
    const ComponentSet set = cullCandidates(cfg, d_cam_map + first, count, &host_candidates);
    index.resize(set.count);
    if (set.count > 0) {
      GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(index.data(), set.index, set.count * sizeof(int),
                                         cudaMemcpyDeviceToHost, s));
    }
    batches += launchSet(f, count, d_cam_map + first, d_map_cam + first, d_order + first, params,
                         cfg, max_patch_pixels, set, batches, ll, hits, evals, pairs);
    for (int c : index) group_visible[c] = 1;
  }
  last_visible_components = 0;
  for (char v : group_visible) last_visible_components += v;
  return batches;
}

int CudaBackend::Impl::launchSet(const DeviceFrameView& f, int n, const RigidTransformF* T_cam_map,
                                 const RigidTransformF* T_map_cam, const int* order,
                                 const MeasurementParams& params, const cuda::MembershipConfig& cfg,
                                 int max_patch_pixels, const ComponentSet& set, int first_batch,
                                 double* ll, int* hits, long long* evals, long long* pairs) {
  const int patches = f.grid.count();
  cudaStream_t s = stream.get();
  const int m = set.count;
  // Where many components are visible together (a cloud spread over a building): local lists,
  // each pose's bitmask and forms sized by the most any one pose keeps (local_stride > 0), and
  // each pose skips the set's chunks outside its view (a tracking cloud's set is about one
  // view: the plain kernel, without the chunk tests and their shared memory). Only on the view
  // cull's set, which has the chunk balls; the whole map (too few pairs for the cull) keeps the
  // plain kernel.
  const bool spread = set.chunks != nullptr && m > 0 && m >= tuning.local_lists_min_components;
  const float4* chunks = spread ? set.chunks : nullptr;
  int local_stride = 0;
  if (spread) {
    local_most.reserve(1, s);
    GMM_MCL_CUDA_CHECK(
        cuda::launchLocalCount(n, m, cfg, set.components, chunks, T_cam_map, local_most.data(), s));
    h_local_most.reserve(1);
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(h_local_most.data(), local_most.data(), sizeof(int),
                                       cudaMemcpyDeviceToHost, s));
    GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));  // the count sizes the launches below
    local_stride = std::max((h_local_most.data()[0] + 31) / 32, 1) * 32;
  }
  const bool local = local_stride > 0;
  const int words = local ? local_stride / 32 : std::max((m + 31) / 32, 1);
  const int pass_words = membershipPassWords(patches, words, local, chunks != nullptr);
  const int passes = cuda::membershipPasses(words, pass_words);
  ensureMembershipShared(patches, passes == 1 ? words : pass_words, m, local, chunks != nullptr);
  // Particles in batches whose masks (and per-particle evaluation forms) fit the budget.
  const bool noise = params.depth_noise.enabled();
  const int forms_per_particle = local ? local_stride : (noise ? std::max(m, 1) : 0);
  const size_t bytes_per_particle = sizeof(uint32_t) * size_t(patches) * words +
                                    sizeof(EvalComponentF) * size_t(forms_per_particle);
  const size_t max_by_threads = size_t(0x7fffffff) / (size_t(patches) * 32);  // int indices
  const size_t budget = std::min(kMaskBudgetBytes, info.total_memory_bytes / 16);
  const int batch = static_cast<int>(std::max<size_t>(
      1, std::min<size_t>(std::min<size_t>(n, max_by_threads), budget / bytes_per_particle)));
  // Earlier evaluations may still be queued on the stream (the device filter does not wait):
  // scratch grows only after them.
  mask.reserve(size_t(batch) * patches * words, s);
  shift.reserve(cuda::membershipShiftFloats(batch, patches, passes), s);
  if (forms_per_particle > 0) noisy_eval.reserve(size_t(batch) * forms_per_particle, s);
  const cuda::LikelihoodShape shape = likelihoodShape(max_patch_pixels, tuning);
  const int items = cuda::likelihoodItemsPerParticle(shape, patches);
  item_ll.reserve(size_t(batch) * items, s);
  item_hits.reserve(size_t(batch) * items, s);
  item_evals.reserve(size_t(batch) * items, s);
  item_relevant.reserve(size_t(batch) * items, s);
  const cuda::ItemPartials partials{item_ll.data(), item_hits.data(), item_evals.data(),
                                    item_relevant.data()};
  const int batches = (n + batch - 1) / batch;
  ensureEvents(3 * size_t(first_batch + batches));
  for (int bi = 0; bi < batches; ++bi) {
    const int first = bi * batch;
    const int count = std::min(batch, n - first);
    const int e = 3 * (first_batch + bi);
    if (bi > 0) events[e].record(s);  // the first batch's start is before the cull
    GMM_MCL_CUDA_CHECK(
        cuda::launchMembership(count, m, words, pass_words, local_stride, cfg, set.components,
                               chunks, set.eval, T_cam_map + first, mask.data(), shift.data(),
                               forms_per_particle > 0 ? noisy_eval.data() : nullptr, s));
    events[e + 1].record(s);
    const cuda::LikelihoodInputs in{patches,
                                    words,
                                    f.x,
                                    f.y,
                                    f.z,
                                    f.patch_begin,
                                    forms_per_particle > 0 ? noisy_eval.data() : set.eval,
                                    forms_per_particle,
                                    T_map_cam + first,
                                    mask.data(),
                                    shift.data()};
    GMM_MCL_CUDA_CHECK(
        cuda::launchLikelihood(count, in, shape, params.floor_log_density, partials, s));
    // With an order, the outputs are indexed by it (the particle's own index).
    const int out = order ? 0 : first;
    GMM_MCL_CUDA_CHECK(cuda::launchReduce(count, items, partials, ll + out, hits + out, evals + out,
                                          pairs + out, order ? order + first : nullptr, s));
    events[e + 2].record(s);
  }
  return batches;
}

void CudaBackend::membership(const DepthFrame& frame, const RigidTransformF& T_map_cam,
                             const MeasurementParams& params, PatchMembership* out) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  if (d.num_components == 0) throw BackendError("cuda backend: no map set");
  const int patches = frame.grid.count();
  out->begin.assign(patches + 1, 0);
  out->comps.clear();
  if (patches == 0) return;
  cudaStream_t s = d.stream.get();
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
  cuda::DeviceBuffer<RigidTransformF> pose(1);
  const RigidTransformF T_cam_map = invertRigid(T_map_cam);
  GMM_MCL_CUDA_CHECK(
      cudaMemcpyAsync(pose.data(), &T_cam_map, sizeof(T_cam_map), cudaMemcpyHostToDevice, s));
  cuda::MembershipConfig cfg = cuda::membershipConfig(frame.intrinsics, frame.grid, params);
  cfg.reach = viewReach(frame, params);
  const Impl::ComponentSet set = d.cullView(cfg, pose.data(), 1);
  const int words = std::max((set.count + 31) / 32, 1);
  const int pass_words = d.membershipPassWords(patches, words, false, false);
  const int passes = cuda::membershipPasses(words, pass_words);
  d.ensureMembershipShared(patches, passes == 1 ? words : pass_words, set.count);
  cuda::DeviceBuffer<uint32_t> mask(size_t(patches) * words);
  cuda::DeviceBuffer<float> shift(cuda::membershipShiftFloats(1, patches, passes));
  cuda::DeviceBuffer<EvalComponentF> noisy(std::max(set.count, 1));
  GMM_MCL_CUDA_CHECK(cuda::launchMembership(1, set.count, words, pass_words, 0, cfg, set.components,
                                            nullptr, set.eval, pose.data(), mask.data(),
                                            shift.data(), noisy.data(), s));
  std::vector<uint32_t> h(size_t(patches) * words);
  std::vector<int> index(set.count);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(h.data(), mask.data(), h.size() * sizeof(uint32_t),
                                     cudaMemcpyDeviceToHost, s));
  for (int k = 0; k < set.count; ++k) index[k] = k;
  if (set.index && set.count > 0) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(index.data(), set.index, set.count * sizeof(int),
                                       cudaMemcpyDeviceToHost, s));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
  // Map indices, ascending per patch (the compact list is in the device's order).
  const bool reordered = !d.device_to_map.empty();
  for (int p = 0; p < patches; ++p) {
    for (int w = 0; w < words; ++w) {
      const uint32_t bits = h[size_t(p) * words + w];
      for (int b = 0; b < 32; ++b) {
        if (!(bits & (1u << b))) continue;
        const int k = index[w * 32 + b];
        out->comps.push_back(reordered ? d.device_to_map[k] : k);
      }
    }
    if (reordered) std::sort(out->comps.begin() + out->begin[p], out->comps.end());
    out->begin[p + 1] = static_cast<int>(out->comps.size());
  }
}

}  // namespace gmm_mcl
