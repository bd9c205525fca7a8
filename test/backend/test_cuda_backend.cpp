// CPU (reference) vs CUDA backend: the same particles and frame give the same per-particle
// log-likelihood within a stated tolerance and the same membership sets (DESIGN.md "Backends").
// Skips with a printed reason when no CUDA device is present.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>
#include <set>
#include <string>

#include "backend/cuda_backend_test_utils.h"
#include "cuda/cuda_backend.h"
#include "cuda/kernels.cuh"
#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/bench/frame_set.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/filter/pose_refinement.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/measurement/normal_equations.h"
#include "gmm_mcl/sim/pose_scatter.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

// Per-particle log-likelihood: |L_cuda - L_cpu| <= kRelTol * max(|L_cpu|, 1 nat x pixels).
// Both evaluate in float32 per pixel and accumulate in double; the CUDA kernel shifts by the
// patch's largest log-normaliser instead of the per-pixel maximum and uses the hardware exp2
// (relative error ~2^-22), so per-pixel values agree to ~1e-6 nats.
constexpr double kRelTol = 1e-5;
// Floor hits may differ on pixels whose mixture density is within rounding of exp(floor).
constexpr double kFloorHitTol = 1e-3;  // of the used pixels
// Membership: a (patch, component) pair may differ only where the patch centre lies on the
// inflated ellipse to within float rounding: |(c - mu)^T Q (c - mu) - 1| below this.
constexpr double kBorderlineTol = 1e-3;
// ... and such pairs are rare.
constexpr double kMaxMembershipMismatchFraction = 1e-3;

using test::noisyImage;

// The true pose and n - 1 poses within +-0.5 m and +-0.3 rad of yaw about it.
std::vector<RigidTransformF> perturbedPoses(const Eigen::Isometry3d& T_true, int n, unsigned seed) {
  return sim::scatterPoses(T_true, n, 0.5, 0.3, seed);
}

// `count` camera poses anywhere over 5 x 5 tiles 14 m apart (tiledMap) at the base pose's height
// and attitude, any yaw.
std::vector<RigidTransformF> posesOverTiles(const Eigen::Isometry3d& T_map_base,
                                            const Eigen::Isometry3d& T_base_cam, int count,
                                            unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> xy(-3.0, 4 * 14.0 + 3.0), yaw(-M_PI, M_PI);
  std::vector<RigidTransformF> poses;
  for (int i = 0; i < count; ++i) {
    Eigen::Isometry3d T = T_map_base;
    T.translation().x() = xy(rng);
    T.translation().y() = xy(rng);
    T.linear() = Eigen::AngleAxisd(yaw(rng), Eigen::Vector3d::UnitZ()) * T_map_base.linear();
    poses.push_back(toRigidF(T * T_base_cam));
  }
  return poses;
}

// Compares membership of every pose; returns mismatching pairs (all must be borderline).
void expectSameMembership(const GmmMap& map, const DepthFrame& frame,
                          const std::vector<RigidTransformF>& poses, CpuBackend* cpu,
                          CudaBackend* gpu, const char* label) {
  const MeasurementParams mp;
  long long pairs = 0, mismatches = 0;
  double worst_margin = 0.0;
  for (const RigidTransformF& T : poses) {
    PatchMembership a, b;
    cpu->membership(frame, T, mp, &a);
    gpu->membership(frame, T, mp, &b);
    ASSERT_EQ(a.begin.size(), b.begin.size());
    const RigidTransformF T_cam_map = invertRigid(T);
    for (int p = 0; p + 1 < static_cast<int>(a.begin.size()); ++p) {
      const std::set<int> sa(a.comps.begin() + a.begin[p], a.comps.begin() + a.begin[p + 1]);
      const std::set<int> sb(b.comps.begin() + b.begin[p], b.comps.begin() + b.begin[p + 1]);
      pairs += static_cast<long long>(sa.size());
      for (int pass = 0; pass < 2; ++pass) {
        const std::set<int>& x = pass ? sb : sa;
        const std::set<int>& y = pass ? sa : sb;
        for (int i : x) {
          if (y.count(i)) continue;
          ++mismatches;
          ProjectedComponent pc;
          ASSERT_TRUE(projectComponent(map.packed()[i], T_cam_map, frame.intrinsics,
                                       mp.min_component_depth_m, mp.sigma_bound,
                                       patchInflation(frame.grid.patch_size_px), &pc));
          const double du = frame.grid.centreU(p % frame.grid.cols) - pc.u_px;
          const double dv = frame.grid.centreV(p / frame.grid.cols) - pc.v_px;
          const double q = pc.q_uu * du * du + 2 * pc.q_uv * du * dv + pc.q_vv * dv * dv;
          worst_margin = std::max(worst_margin, std::abs(q - 1.0));
          EXPECT_LT(std::abs(q - 1.0), kBorderlineTol)
              << label << ": patch " << p << " component " << i << " differs, q = " << q;
        }
      }
    }
  }
  std::printf(
      "[ measured ] %s membership: %lld pairs over %zu poses, %lld differ (all borderline, "
      "worst |q-1| = %.2e)\n",
      label, pairs, poses.size(), mismatches, worst_margin);
  EXPECT_GT(pairs, 0);
  EXPECT_LE(static_cast<double>(mismatches), kMaxMembershipMismatchFraction * pairs + 1);
}

void expectSameLikelihood(const GmmMap& map, const DepthFrame& frame,
                          const std::vector<RigidTransformF>& poses, CpuBackend* cpu,
                          CudaBackend* gpu, const char* label,
                          const MeasurementParams& mp = MeasurementParams()) {
  BackendOutput a, b;
  cpu->evaluate(frame, poses, mp, &a);
  gpu->evaluate(frame, poses, mp, &b);
  ASSERT_EQ(a.log_likelihood.size(), poses.size());
  ASSERT_EQ(b.log_likelihood.size(), poses.size());
  const double px = static_cast<double>(frame.size());
  double worst = 0.0;
  int worst_hits = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    ASSERT_TRUE(std::isfinite(b.log_likelihood[i])) << label << " particle " << i;
    const double scale = std::max(std::abs(a.log_likelihood[i]), px);
    const double rel = std::abs(a.log_likelihood[i] - b.log_likelihood[i]) / scale;
    worst = std::max(worst, rel);
    EXPECT_LT(rel, kRelTol) << label << " particle " << i << ": cpu " << a.log_likelihood[i]
                            << " cuda " << b.log_likelihood[i];
    const int dh = std::abs(a.floor_hits[i] - b.floor_hits[i]);
    worst_hits = std::max(worst_hits, dh);
    EXPECT_LE(dh, kFloorHitTol * px + 1) << label << " particle " << i;
  }
  // The CPU backend's members are the CUDA membership's less the pairs that the frame's depths
  // rule out (membership.h's MemberDepthPrune, not in the CUDA kernels): fewer evaluations, the
  // same sums within kRelTol.
  const double pruned = double(b.evaluations - a.evaluations) / double(b.evaluations);
  std::printf(
      "[ measured ] %s likelihood: %zu particles, %.0f px, worst relative difference "
      "%.2e (tolerance %.0e), worst floor-hit difference %d px, evaluations cpu %lld "
      "cuda %lld, L(true pose) cpu %.3f cuda %.3f\n",
      label, poses.size(), px, worst, kRelTol, worst_hits, a.evaluations, b.evaluations,
      a.log_likelihood[0], b.log_likelihood[0]);
  EXPECT_GE(pruned, 0.0);
  EXPECT_LT(pruned, 0.9);
  EXPECT_EQ(a.patches_with_pixels, b.patches_with_pixels);
  (void)map;
}

// The number of components the CUDA backend's view cull keeps for the poses, against the CPU
// backend's (within 1% + 2: borderline components); returns the CUDA count.
int expectVisibleAsCpu(const GmmMap& map, const DepthFrame& frame,
                       const std::vector<RigidTransformF>& poses, CpuBackend* cpu, CudaBackend* gpu,
                       const char* label) {
  BackendOutput a, b;
  const MeasurementParams mp;
  cpu->evaluate(frame, poses, mp, &a);
  gpu->evaluate(frame, poses, mp, &b);
  std::printf("[ measured ] %s: visible components cpu %d cuda %d of %zu\n", label,
              a.visible_components, b.visible_components, map.size());
  EXPECT_NEAR(b.visible_components, a.visible_components, 0.01 * a.visible_components + 2) << label;
  return b.visible_components;
}

// `near` with the poses of `far` inserted among them, in an order that mixes the places (the
// results must come back to each particle's index).
std::vector<RigidTransformF> mixedIn(std::vector<RigidTransformF> near,
                                     const std::vector<RigidTransformF>& far) {
  for (size_t i = 0; i < far.size(); ++i) {
    near.insert(near.begin() + (i * 7) % (near.size() + 1), far[i]);
  }
  return near;
}

TEST_F(CudaBackendTest, SyntheticSceneMatchesCpu) {
  const auto& w = test::world();
  CpuBackend cpu;
  cpu.setMap(w.map);
  gpu->setMap(w.map);
  for (int stride : {4, 1, 8}) {
    FrameParams fp = test::frameParams(stride);
    const Eigen::Isometry3d T_map_base = test::referenceBasePose();
    const DepthFrame frame = test::renderFrame(T_map_base, test::vgaCamera(), fp);
    const auto poses = perturbedPoses(T_map_base * w.T_base_cam, 256, 10u + stride);
    const std::string label = "synthetic stride " + std::to_string(stride);
    expectSameLikelihood(w.map, frame, poses, &cpu, gpu.get(), label.c_str());
    if (stride == 4) {
      // The paper's model (no depth noise): one evaluation form for every particle.
      MeasurementParams noise_off;
      noise_off.depth_noise.a_m = noise_off.depth_noise.b_per_m = 0.f;
      expectSameLikelihood(w.map, frame, poses, &cpu, gpu.get(),
                           (label + ", no depth noise").c_str(), noise_off);
      const std::vector<RigidTransformF> some(poses.begin(), poses.begin() + 32);
      expectSameMembership(w.map, frame, some, &cpu, gpu.get(), label.c_str());
    }
  }
}

// The membership kernel's passes (cuda::balancedPassWords): about pass_words words each, all of
// one size but the last, which differs by fewer words than there are passes, so that no pass is
// left with a few words; one pass below 1.5 times pass_words.
TEST(MembershipPassesTest, PassesAreOfOneSizeAndNearTheTuning) {
  EXPECT_EQ(cuda::balancedPassWords(42, 32), 42);  // one pass, not 32 + 10
  EXPECT_EQ(cuda::balancedPassWords(96, 32), 32);  // three passes of 32
  EXPECT_EQ(cuda::balancedPassWords(48, 32), 24);
  EXPECT_EQ(cuda::balancedPassWords(100, 32), 34);
  EXPECT_EQ(cuda::balancedPassWords(20, 32), 20);
  EXPECT_EQ(cuda::balancedPassWords(420, 0), 420);  // 0: one pass
  for (int pass_words : {1, 8, 32}) {
    for (int words = 1; words <= 400; ++words) {
      const int nw = cuda::balancedPassWords(words, pass_words);
      const int passes = cuda::membershipPasses(words, nw);
      const int last = words - (passes - 1) * nw;
      const std::string at = std::to_string(words) + " words, " + std::to_string(pass_words);
      EXPECT_GE(last, 1) << at;
      EXPECT_LE(last, nw) << at;
      EXPECT_GE(last, nw - passes + 1) << at;
      EXPECT_LE(2 * nw, 3 * pass_words) << at;
      if (passes > 1) {
        EXPECT_GE(3 * nw, 2 * pass_words) << at;
      }
      if (2 * words < 3 * pass_words) {
        EXPECT_EQ(passes, 1) << at;
      }
    }
  }
}

// A cloud spread over a building (a start from a uniform cloud): with cuda_place_groups the CUDA
// backend evaluates it group by group of poses by place, each over the components its own views
// can see, and gives the CPU backend's per-particle log-likelihoods (in particle order) and
// visible count.
TEST_F(CudaBackendTest, CloudSpreadOverABuildingMatchesCpu) {
  const auto& w = test::world();
  const GmmMap building = tiledMap(w.map, 5, 5, 14.0);  // M about 27,000: the grid's path
  ASSERT_GE(building.size(), 20000u);
  CudaTuningParams tuning;
  tuning.place_groups = true;
  gpu = std::make_unique<CudaBackend>(0, tuning);
  CpuBackend cpu;
  cpu.setMap(building);
  gpu->setMap(building);
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const DepthFrame frame = test::renderFrame(T_map_base, test::smallCamera(), test::frameParams(8));
  // 64 poses about the truth, then 448 anywhere in the building at the camera's height.
  const std::vector<RigidTransformF> poses =
      mixedIn(perturbedPoses(T_map_base * w.T_base_cam, 64, 3u),
              posesOverTiles(T_map_base, w.T_base_cam, 448, 11u));
  expectSameLikelihood(building, frame, poses, &cpu, gpu.get(), "building, spread cloud");
  EXPECT_LT(expectVisibleAsCpu(building, frame, poses, &cpu, gpu.get(), "building, spread cloud"),
            static_cast<int>(building.size()));
}

// The same with the default tuning (the groups' candidates in one call, the cull's flags over
// the candidates only), for a tracking cloud and for the spread cloud: the sums of the CPU
// backend, and the set of a tracking cloud is what its views reach, not the map.
TEST_F(CudaBackendTest, CloudsInABuildingMatchCpuWithTheDefaultTuning) {
  const auto& w = test::world();
  const GmmMap building = tiledMap(w.map, 5, 5, 14.0);
  ASSERT_GE(building.size(), 20000u);
  gpu = std::make_unique<CudaBackend>(0, CudaTuningParams());
  CpuBackend cpu;
  cpu.setMap(building);
  gpu->setMap(building);
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const DepthFrame frame = test::renderFrame(T_map_base, test::smallCamera(), test::frameParams(8));
  const std::vector<RigidTransformF> tracking = perturbedPoses(T_map_base * w.T_base_cam, 256, 5u);
  expectSameLikelihood(building, frame, tracking, &cpu, gpu.get(), "building, tracking cloud");
  EXPECT_LT(
      expectVisibleAsCpu(building, frame, tracking, &cpu, gpu.get(), "building, tracking cloud"),
      static_cast<int>(w.map.size()) * 2);
  const std::vector<RigidTransformF> poses =
      mixedIn(tracking, posesOverTiles(T_map_base, w.T_base_cam, 448, 13u));
  expectSameLikelihood(building, frame, poses, &cpu, gpu.get(), "building, spread cloud");
  expectVisibleAsCpu(building, frame, poses, &cpu, gpu.get(), "building, spread cloud");
}

// Each pose's own list of the components it can see (local lists), built over the view cull's
// set of the map held in Z order, chunk by chunk (the chunks whose bounding ball lies outside
// the pose's view skipped), holds the members that the bitmask over the whole map in its own
// order holds: the same evaluations, member pairs and membership tables (in map indices),
// exactly, and per-particle log-likelihoods and floor hits within the CPU-parity tolerances (the
// members are summed in another order, and in slices per round of 1024 bits), for a cloud
// spread over a building and for a tracking cloud, with and without the depth noise, in one pass
// and in passes of one word. Fails if a pose's list misses a component or its forms are taken at
// the wrong places.
TEST_F(CudaBackendTest, LocalListsGiveTheSameSumsAsTheSharedBitmask) {
  const auto& w = test::world();
  const GmmMap building = tiledMap(w.map, 5, 5, 14.0);
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const DepthFrame frame = test::renderFrame(T_map_base, test::smallCamera(), test::frameParams(8));
  std::vector<RigidTransformF> tracking = perturbedPoses(T_map_base * w.T_base_cam, 256, 21u);
  std::vector<RigidTransformF> spread(tracking.begin(), tracking.begin() + 32);
  const std::vector<RigidTransformF> far = posesOverTiles(T_map_base, w.T_base_cam, 480, 5u);
  spread.insert(spread.end(), far.begin(), far.end());
  MeasurementParams noise_off;
  noise_off.depth_noise.a_m = noise_off.depth_noise.b_per_m = 0.f;
  for (const MeasurementParams& mp : {MeasurementParams(), noise_off}) {
    for (const std::vector<RigidTransformF>* poses : {&spread, &tracking}) {
      for (int pass_words : {32, 1}) {
        CudaTuningParams shared, local;
        shared.local_lists_min_components = std::numeric_limits<int>::max();
        local.local_lists_min_components = 0;
        shared.view_cull_min_pairs = std::numeric_limits<long long>::max();  // the whole map
        shared.z_order_min_components = std::numeric_limits<int>::max();     // in map order
        local.view_cull_min_pairs = 0;  // the cull's set (of the map in Z order), chunk balls
        shared.membership_pass_words = local.membership_pass_words = pass_words;
        CudaBackend a(0, shared), b(0, local);
        a.setMap(building);
        b.setMap(building);
        BackendOutput oa, ob;
        a.evaluate(frame, *poses, mp, &oa);
        b.evaluate(frame, *poses, mp, &ob);
        const std::string label = std::string(poses == &spread ? "spread" : "tracking") +
                                  (mp.depth_noise.enabled() ? ", depth noise" : ", no noise") +
                                  ", pass words " + std::to_string(pass_words);
        ASSERT_EQ(oa.log_likelihood.size(), poses->size()) << label;
        ASSERT_EQ(ob.log_likelihood.size(), poses->size()) << label;
        const double px = static_cast<double>(frame.size());
        int differ = 0;
        double worst = 0.0;
        for (size_t i = 0; i < poses->size(); ++i) {
          differ += oa.log_likelihood[i] != ob.log_likelihood[i];
          const double scale = std::max(std::abs(oa.log_likelihood[i]), px);
          const double rel = std::abs(oa.log_likelihood[i] - ob.log_likelihood[i]) / scale;
          worst = std::max(worst, rel);
          EXPECT_LT(rel, kRelTol) << label << " particle " << i << ": shared bitmask "
                                  << oa.log_likelihood[i] << " local " << ob.log_likelihood[i];
          EXPECT_LE(std::abs(oa.floor_hits[i] - ob.floor_hits[i]), kFloorHitTol * px + 1)
              << label << " particle " << i;
        }
        EXPECT_EQ(oa.evaluations, ob.evaluations) << label;
        EXPECT_EQ(oa.relevant_pairs, ob.relevant_pairs) << label;
        EXPECT_GT(oa.relevant_pairs, 0) << label;
        // The membership tables in map indices, whatever order the device holds the map in.
        for (int k = 0; k < 4; ++k) {
          PatchMembership ma, mb;
          a.membership(frame, (*poses)[k * 7], mp, &ma);
          b.membership(frame, (*poses)[k * 7], mp, &mb);
          EXPECT_EQ(ma.begin, mb.begin) << label << " pose " << k * 7;
          EXPECT_EQ(ma.comps, mb.comps) << label << " pose " << k * 7;
        }
        std::printf(
            "[ measured ] local lists, %s: %zu poses, %d not bit-identical, worst relative "
            "difference %.2e, %lld member pairs, visible %d of %zu\n",
            label.c_str(), poses->size(), differ, worst, ob.relevant_pairs, ob.visible_components,
            building.size());
      }
    }
  }
}

// More components in the evaluated set than a 16-bit index holds: the likelihood kernel's member
// lists, built per round of 1024 components, must still name the right components. The room the
// camera is in comes last in a map of more than 65,536 components, and the view cull is off, so
// that the set is the whole map and the seen components' indices exceed 65,535. Both member
// paths (records read through L1, and staged in shared memory) against the CPU backend.
TEST_F(CudaBackendTest, MoreThan65536ComponentsMatchCpu) {
  const auto& w = test::world();
  const int room = static_cast<int>(w.map.size());
  const int side = static_cast<int>(std::ceil(std::sqrt((65536.0 + 2.0 * room) / room)));
  const GmmMap tiles = tiledMap(w.map, side, side, 14.0);
  std::vector<GaussianComponent> comps(tiles.components().begin() + room, tiles.components().end());
  comps.insert(comps.end(), tiles.components().begin(), tiles.components().begin() + room);
  const GmmMap big(std::move(comps), "tiles, the camera's room last");
  ASSERT_GT(big.size() - room, 65536u);
  CpuBackend cpu;
  cpu.setMap(big);
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const DepthFrame frame = test::renderFrame(T_map_base, test::smallCamera(), test::frameParams(8));
  const auto poses = perturbedPoses(T_map_base * w.T_base_cam, 16, 5u);
  for (const char* stage : {"off", "on"}) {
    CudaTuningParams tuning;
    tuning.view_cull_min_pairs = std::numeric_limits<long long>::max();
    tuning.z_order_min_components = std::numeric_limits<int>::max();  // the room stays last
    tuning.likelihood_shape = "32x4";
    tuning.stage_members = stage;
    gpu = std::make_unique<CudaBackend>(0, tuning);
    gpu->setMap(big);
    const std::string label =
        std::string("M = ") + std::to_string(big.size()) + ", room last, staged members " + stage;
    expectSameLikelihood(big, frame, poses, &cpu, gpu.get(), label.c_str());
  }
}

// The pose refinement's pixel sums on the GPU (float per pair, double per block) match the host's
// (double throughout): the log-likelihood and the normal equations at poses near and off the
// truth, and the refined pose.
// Frame preparation on the GPU gives prepareFrame's points: the same likelihoods, to the bit
// when the order and arithmetic agree, for both encodings and several strides.
TEST_F(CudaBackendTest, GpuFramePreparationMatchesHost) {
  const auto& w = test::world();
  gpu->setMap(w.map);
  const Intrinsics K = test::vgaCamera();
  const Eigen::Isometry3d T_map_cam = test::referenceBasePose() * w.T_base_cam;
  const auto poses = perturbedPoses(T_map_cam, 64, 5);
  for (DepthEncoding enc : {DepthEncoding::kMono16Millimetres, DepthEncoding::kFloat32Metres}) {
    std::mt19937_64 rng(7);
    const DepthImage img = noisyImage(K, T_map_cam, enc, &rng);
    for (int stride : {1, 3, 4, 8}) {
      FrameParams fp;
      fp.pixel_stride = stride;
      fp.max_range_m = 5.f;
      const DepthFrame frame = prepareFrame(img, K, fp);
      BackendOutput host, dev;
      gpu->evaluate(frame, poses, MeasurementParams(), &host);
      gpu->evaluateImage(img, K, fp, poses, MeasurementParams(), &dev);
      EXPECT_EQ(gpu->lastFramePixels(), static_cast<int>(frame.size()));
      EXPECT_EQ(host.patches_with_pixels, dev.patches_with_pixels);
      EXPECT_EQ(host.evaluations, dev.evaluations);
      double worst = 0.0;
      for (size_t i = 0; i < poses.size(); ++i) {
        worst = std::max(worst, std::abs(host.log_likelihood[i] - dev.log_likelihood[i]) /
                                    std::max(1.0, std::abs(host.log_likelihood[i])));
        EXPECT_EQ(host.floor_hits[i], dev.floor_hits[i]);
      }
      EXPECT_LT(worst, 1e-12) << "stride " << stride;
      std::printf(
          "[ measured ] GPU frame prep, %s stride %d: %zu px, worst relative difference "
          "%.1e\n",
          depthEncodingName(enc), stride, frame.size(), worst);
    }
  }
  // What prepareFrame rejects, evaluateImage rejects.
  FrameParams bad;
  bad.pixel_stride = 0;
  BackendOutput out;
  const DepthImage img =
      sim::renderDepth(w.scene, K, T_map_cam, DepthEncoding::kMono16Millimetres, 6.0);
  EXPECT_THROW(gpu->evaluateImage(img, K, bad, poses, MeasurementParams(), &out),
               std::invalid_argument);
  EXPECT_THROW(
      gpu->evaluateImage(img, test::smallCamera(), FrameParams(), poses, MeasurementParams(), &out),
      std::invalid_argument);
}

TEST_F(CudaBackendTest, EmptyAndDegenerateInputs) {
  const auto& w = test::world();
  BackendOutput out;
  FrameParams fp;
  const DepthFrame frame = test::renderFrame(test::referenceBasePose(), test::vgaCamera(), fp);
  EXPECT_THROW(gpu->evaluate(frame, {}, MeasurementParams(), &out), BackendError);  // no map
  gpu->setMap(w.map);
  gpu->evaluate(frame, {}, MeasurementParams(), &out);
  EXPECT_TRUE(out.log_likelihood.empty());
  // A frame with no used pixels: every particle scores 0 nats.
  DepthFrame empty = frame;
  empty.x_m.clear();
  empty.y_m.clear();
  empty.z_m.clear();
  std::fill(empty.patch_begin.begin(), empty.patch_begin.end(), 0);
  const auto poses = perturbedPoses(test::referenceBasePose() * w.T_base_cam, 5, 3);
  gpu->evaluate(empty, poses, MeasurementParams(), &out);
  ASSERT_EQ(out.log_likelihood.size(), 5u);
  for (double l : out.log_likelihood) EXPECT_EQ(l, 0.0);
  // More particles than one mask batch holds still gives every particle its value.
  CpuBackend cpu;
  cpu.setMap(w.map);
  FrameParams coarse;
  coarse.pixel_stride = 16;
  const DepthFrame small = test::renderFrame(test::referenceBasePose(), test::vgaCamera(), coarse);
  const auto many = perturbedPoses(test::referenceBasePose() * w.T_base_cam, 7000, 4);
  BackendOutput a, b;
  cpu.evaluate(small, many, MeasurementParams(), &a);
  gpu->evaluate(small, many, MeasurementParams(), &b);
  for (size_t i = 0; i < many.size(); i += 97) {
    EXPECT_NEAR(a.log_likelihood[i], b.log_likelihood[i],
                kRelTol * std::max(std::abs(a.log_likelihood[i]), double(small.size())));
  }
}

// 7-Scenes redkitchen, M = 1000 map: frames from $GMM_MCL_7SCENES_FRAMES (a raw frame file
// written by `gmm_mcl_bench --export-frames`) or the data set's PNGs; map from $GMM_MCL_MAP or
// build/maps/7scenes_redkitchen_m1000.gmm.
TEST_F(CudaBackendTest, SevenScenesFramesMatchCpu) {
  struct stat st;
  const char* env_map = std::getenv("GMM_MCL_MAP");
  std::string map_path = env_map && *env_map ? env_map : "";
  for (const char* cand :
       {"build/maps/7scenes_redkitchen_m1000.gmm", "../build/maps/7scenes_redkitchen_m1000.gmm",
        "../../build/maps/7scenes_redkitchen_m1000.gmm"}) {
    if (map_path.empty() && stat(cand, &st) == 0) map_path = cand;
  }
  if (map_path.empty() || stat(map_path.c_str(), &st) != 0) {
    GTEST_SKIP() << "7-Scenes M=1000 map not found (set GMM_MCL_MAP)";
  }
  bench::FrameSet frames;
  const char* env_frames = std::getenv("GMM_MCL_7SCENES_FRAMES");
  if (env_frames && *env_frames) {
    frames = bench::loadFrameSet(env_frames);
  } else {
#if defined(GMM_MCL_HAVE_PNG)
    const std::string dir = test::datasetsRoot() + "/7scenes_redkitchen/data";
    if (test::datasetsRoot().empty() || stat((dir + "/frame-000000.depth.png").c_str(), &st) != 0) {
      GTEST_SKIP() << "7-Scenes frames not found (set GMM_MCL_7SCENES_FRAMES or GMM_MCL_DATASETS)";
    }
    frames = bench::loadSevenScenes(dir, 0, 1);
    const bench::FrameSet frame50 = bench::loadSevenScenes(dir, 50, 1);
    frames.images.push_back(frame50.images[0]);
    frames.T_map_cam.push_back(frame50.T_map_cam[0]);
#else
    GTEST_SKIP() << "7-Scenes frames need libpng or GMM_MCL_7SCENES_FRAMES";
#endif
  }
  const GmmMap map = loadMap(map_path);
  CpuBackend cpu;
  cpu.setMap(map);
  gpu->setMap(map);
  const size_t used = std::min<size_t>(frames.images.size(), 3);
  for (size_t f = 0; f < used; ++f) {
    const size_t idx = f * (frames.images.size() / used);
    FrameParams fp;
    fp.pixel_stride = 4;
    const DepthFrame frame = prepareFrame(frames.images[idx], frames.K, fp);
    const auto poses = perturbedPoses(frames.T_map_cam[idx], 256, 100u + unsigned(idx));
    const std::string label = "7-Scenes frame " + std::to_string(idx);
    expectSameLikelihood(map, frame, poses, &cpu, gpu.get(), label.c_str());
    const std::vector<RigidTransformF> some(poses.begin(), poses.begin() + 32);
    expectSameMembership(map, frame, some, &cpu, gpu.get(), label.c_str());
  }
  // Another patch size (a parameter of the model) on the first frame (8x8 patches: 4,800 of them
  // exceed the membership bitmask's shared memory at M = 1000).
  for (int patch : {16}) {
    FrameParams fp;
    fp.pixel_stride = 4;
    fp.patch_size_px = patch;
    const DepthFrame frame = prepareFrame(frames.images[0], frames.K, fp);
    const auto poses = perturbedPoses(frames.T_map_cam[0], 64, 300u + unsigned(patch));
    const std::string label =
        "7-Scenes frame 0, " + std::to_string(patch) + "x" + std::to_string(patch) + " patches";
    expectSameLikelihood(map, frame, poses, &cpu, gpu.get(), label.c_str());
    const std::vector<RigidTransformF> some(poses.begin(), poses.begin() + 8);
    expectSameMembership(map, frame, some, &cpu, gpu.get(), label.c_str());
  }
  // The benchmark's `large` map (M = 4000, $GMM_MCL_LARGE_MAP) when given.
  const char* env_large = std::getenv("GMM_MCL_LARGE_MAP");
  if (env_large && *env_large && stat(env_large, &st) == 0) {
    const GmmMap large = loadMap(env_large);
    cpu.setMap(large);
    gpu->setMap(large);
    for (int stride : {4, 8}) {
      FrameParams fp;
      fp.pixel_stride = stride;
      const DepthFrame frame = prepareFrame(frames.images[0], frames.K, fp);
      const auto poses = perturbedPoses(frames.T_map_cam[0], 128, 400u + unsigned(stride));
      const std::string label = "7-Scenes frame 0, M=" + std::to_string(large.size()) +
                                ", stride " + std::to_string(stride);
      expectSameLikelihood(large, frame, poses, &cpu, gpu.get(), label.c_str());
      const std::vector<RigidTransformF> some(poses.begin(), poses.begin() + 8);
      expectSameMembership(large, frame, some, &cpu, gpu.get(), label.c_str());
    }
  } else {
    std::printf("[ skipped  ] M=4000 map: GMM_MCL_LARGE_MAP not set\n");
  }
}

}  // namespace
}  // namespace gmm_mcl
