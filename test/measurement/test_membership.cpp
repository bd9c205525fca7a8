#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/internal/fast_math.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

// The paper's approximation vs the exact sum over all components (DESIGN.md, Fig. 2).
constexpr double kApproxRelTol = 0.01;

struct MembershipTables {
  PatchMembership fast, brute;
};

// The (patch, component) table of computeMembership and the brute-force one for the synthetic
// world seen from the base pose T_map_base.
MembershipTables membershipTables(const Eigen::Isometry3d& T_map_base, const Intrinsics& K,
                                  const PatchGrid& grid) {
  const auto& w = test::world();
  const RigidTransformF T_cam_map = toRigidF((T_map_base * w.T_base_cam).inverse());
  MembershipTables t;
  std::vector<ProjectedComponent> proj;
  std::vector<char> valid;
  computeMembership(w.map.packed(), T_cam_map, K, grid, MeasurementParams(), &proj, &valid,
                    &t.fast);
  computeMembershipBruteForce(w.map.packed(), T_cam_map, K, grid, MeasurementParams(), &t.brute);
  return t;
}

TEST(MembershipTest, FastTableEqualsBruteForce) {
  FrameParams fp;
  for (const Intrinsics& K : {test::smallCamera(), test::vgaCamera()}) {
    const PatchGrid grid = PatchGrid::forImage(K.width_px, K.height_px, fp.patch_size_px);
    for (double yaw : {-0.6, 0.4, 2.0, 3.0}) {
      Eigen::Isometry3d T = test::referenceBasePose();
      T.linear() = rotationFromRpy(0.02, -0.03, yaw);
      const MembershipTables m = membershipTables(T, K, grid);
      EXPECT_EQ(m.fast.begin, m.brute.begin);
      EXPECT_EQ(m.fast.comps, m.brute.comps);
      EXPECT_GT(m.fast.comps.size(), 0u);
    }
  }
}

// Many random poses (positions and all three angles), so that some patch centres fall within
// float rounding of an ellipse or a box edge: computeMembership's vectorised projection then
// defers to projectComponent, and the table must still be the brute-force one exactly.
TEST(MembershipTest, FastTableEqualsBruteForceAtRandomPoses) {
  FrameParams fp;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> pos(-1.0, 1.0), ang(-3.14159, 3.14159);
  const Intrinsics K = test::vgaCamera();
  const PatchGrid grid = PatchGrid::forImage(K.width_px, K.height_px, fp.patch_size_px);
  size_t pairs = 0;
  for (int k = 0; k < 100; ++k) {
    Eigen::Isometry3d T = test::referenceBasePose();
    T.linear() = rotationFromRpy(0.3 * ang(rng), 0.3 * ang(rng), ang(rng));
    T.translation() += Eigen::Vector3d(pos(rng), pos(rng), 0.3 * pos(rng));
    const MembershipTables m = membershipTables(T, K, grid);
    ASSERT_EQ(m.fast.begin, m.brute.begin) << k;
    ASSERT_EQ(m.fast.comps, m.brute.comps) << k;
    pairs += m.fast.comps.size();
  }
  std::printf("[ measured ] 100 random poses: %zu (patch, component) pairs, all as brute force\n",
              pairs);
}

// Poses spread like the benchmark's particles around the reference pose (+-0.5 m, +-0.3 rad of
// yaw), or in every direction (`all_around`).
std::vector<RigidTransformF> spreadCameraPoses(int n, bool all_around, unsigned seed) {
  const auto& w = test::world();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<RigidTransformF> T_cam_map;
  for (int k = 0; k < n; ++k) {
    Eigen::Isometry3d T = test::referenceBasePose();
    const double yaw = all_around ? 3.14159 * u(rng) : 0.3 * u(rng);
    T.linear() = T.linear() * rotationFromRpy(0.05 * u(rng), 0.05 * u(rng), yaw);
    T.translation() += Eigen::Vector3d(0.5 * u(rng), 0.5 * u(rng), 0.2 * u(rng));
    T_cam_map.push_back(toRigidF((T * w.T_base_cam).inverse()));
  }
  return T_cam_map;
}

// The per-update view cull may only drop a component that no pose's patch lists, or whose
// sigma_bound sphere lies outside every pose's view volume (a component near the camera's plane
// and to its side, whose linearised ellipse covers much of the image, so that the brute-force
// table lists it in many patches where every pixel lies metres from it in 3D): every
// other member of every pose's brute-force table must be in the culled list, for the cluster of
// poses at once and for each pose alone (the tightest cull).
TEST(MembershipTest, ViewCullKeepsEveryContributingComponent) {
  const auto& w = test::world();
  FrameParams fp;
  const MeasurementParams params;
  for (const Intrinsics& K : {test::smallCamera(), test::vgaCamera()}) {
    const PatchGrid grid = PatchGrid::forImage(K.width_px, K.height_px, fp.patch_size_px);
    for (bool all_around : {false, true}) {
      const std::vector<RigidTransformF> poses = spreadCameraPoses(16, all_around, 5);
      std::vector<int> visible;
      cullToView(w.map.packed(), poses.data(), static_cast<int>(poses.size()), K, grid, params,
                 &visible);
      ASSERT_TRUE(std::is_sorted(visible.begin(), visible.end()));
      const ViewReach reach =
          viewReach(K, grid.patch_size_px, grid.cols, grid.rows, patchInflation(grid.patch_size_px),
                    std::numeric_limits<float>::infinity(), params.sigma_bound, params.depth_noise);
      size_t members = 0, own_visible = 0, outside = 0;
      for (const RigidTransformF& T_cam_map : poses) {
        PatchMembership brute;
        computeMembershipBruteForce(w.map.packed(), T_cam_map, K, grid, params, &brute);
        std::vector<int> own;
        cullToView(w.map.packed(), &T_cam_map, 1, K, grid, params, &own);
        own_visible += own.size();
        for (int c : brute.comps) {
          if (!componentInView(w.map.packed()[c], T_cam_map, K, reach, params.sigma_bound)) {
            ++outside;
            continue;
          }
          ASSERT_TRUE(std::binary_search(visible.begin(), visible.end(), c)) << c;
          ASSERT_TRUE(std::binary_search(own.begin(), own.end(), c)) << c;
        }
        members += brute.comps.size();
      }
      std::printf(
          "[ measured ] %dx%d, %s: %zu of %zu components visible to the 16 poses "
          "(%.0f per pose alone), %zu (patch, component) pairs kept but %zu outside the view\n",
          K.width_px, K.height_px, all_around ? "all around" : "cluster", visible.size(),
          w.map.size(), double(own_visible) / poses.size(), members - outside, outside);
      // What the view volume drops adds nothing a pixel can see: the likelihood over the culled
      // list equals the whole map's (BackendOnCulledListEqualsWholeMap).
      EXPECT_GT(members, 0u);
      // A cluster looking one way sees part of the room: the cull has something to drop.
      if (!all_around) {
        EXPECT_LT(visible.size(), w.map.size());
      }
    }
  }
}

// The CPU backend evaluates on the culled list (the map grid's candidates near the views, then
// the cull within the frame's depth): the same log-likelihoods as the whole map through
// poseLogLikelihood (each pose's own view volume and depth prune) within float rounding, the
// same floor hits, with the depth-noise model on and off.
constexpr double kCulledRelativeTolerance = 1e-8;  // 1.5e-9 seen
TEST(MembershipTest, BackendOnCulledListEqualsWholeMap) {
  const auto& w = test::world();
  const DepthFrame frame =
      test::renderFrame(test::referenceBasePose(), test::vgaCamera(), test::frameParams(4));
  std::vector<RigidTransformF> T_map_cam;
  for (const RigidTransformF& T : spreadCameraPoses(24, false, 9)) {
    T_map_cam.push_back(invertRigid(T));
  }
  CpuBackend backend(2);
  backend.setMap(w.map);
  MeasurementParams noise_off;
  noise_off.depth_noise.a_m = noise_off.depth_noise.b_per_m = 0.f;
  for (const MeasurementParams& mp : {noise_off, MeasurementParams()}) {
    BackendOutput out;
    backend.evaluate(frame, T_map_cam, mp, &out);
    EXPECT_GT(out.visible_components, 0);
    EXPECT_LT(out.visible_components, static_cast<int>(w.map.size()));
    LikelihoodScratch scratch;
    for (size_t i = 0; i < T_map_cam.size(); ++i) {
      const FrameLikelihood ref =
          poseLogLikelihood(w.map.packed(), frame, T_map_cam[i], mp, &scratch);
      // The grid's candidates leave out what lies outside every view's box (a component beside
      // or behind the camera whose linearised projection still reaches the grid): its share of
      // a pixel's density is below float rounding.
      EXPECT_NEAR(out.log_likelihood[i], ref.log_likelihood,
                  kCulledRelativeTolerance * std::abs(ref.log_likelihood))
          << i;
      EXPECT_EQ(out.floor_hits[i], ref.floor_hits) << i;
    }
  }
}

// Sum over the frame's pixels of ln(exp(floor) + sum over the patch's members in `table` of
// lambda N), in double from the evaluation forms (what a table selects, without the float
// kernel's rounding).
double tableLogLikelihood(const EvalComponentF* eval, const DepthFrame& frame,
                          const RigidTransformF& T_map_cam, const PatchMembership& table,
                          double floor) {
  double sum = 0.0;
  for (int p = 0; p < frame.grid.count(); ++p) {
    for (int i = frame.patch_begin[p]; i < frame.patch_begin[p + 1]; ++i) {
      const float* R = T_map_cam.R;
      const double x = frame.x_m[i], y = frame.y_m[i], z = frame.z_m[i];
      const double wx = R[0] * x + R[1] * y + R[2] * z + T_map_cam.t[0];
      const double wy = R[3] * x + R[4] * y + R[5] * z + T_map_cam.t[1];
      const double wz = R[6] * x + R[7] * y + R[8] * z + T_map_cam.t[2];
      std::vector<double> terms{floor};
      for (int k = table.begin[p]; k < table.begin[p + 1]; ++k) {
        const EvalComponentF& e = eval[table.comps[k]];
        const double y0 = e.u00 * wx + e.u01 * wy + e.u02 * wz + e.c[0];
        const double y1 = e.u11 * wy + e.u12 * wz + e.c[1];
        const double y2 = e.u22 * wz + e.c[2];
        terms.push_back(e.base - (y0 * y0 + y1 * y1 + y2 * y2));
      }
      const double top = *std::max_element(terms.begin(), terms.end());
      double s = 0.0;
      for (double t : terms) s += std::exp(t - top);
      sum += top + std::log(s);
    }
  }
  return sum;
}

// The depth prune (MemberDepthPrune): a (patch, component) pair whose term lies below
// exp(floor - 26) at every pixel of the patch by its depth alone leaves the table. The pruned
// table is a subset of the full one and markedly smaller, and the frame's log-likelihood through
// it (in double, from the same forms) moves by less than the pruned terms' bound: at most
// e^-26 of a pixel's density per pruned member. With the depth noise on (which widens every
// component along the ray: a bound without it drops contributing members) and off.
TEST(MembershipTest, DepthPruneKeepsTheSums) {
  const auto& w = test::world();
  const DepthFrame frame =
      test::renderFrame(test::referenceBasePose(), test::vgaCamera(), test::frameParams(4));
  std::vector<float> min_z, max_z;
  patchDepthRanges(frame, &min_z, &max_z);
  ASSERT_EQ(min_z.size(), static_cast<size_t>(frame.grid.count()) + 8);
  std::vector<EvalComponentF> base;
  makeEvalComponents(w.map.packed(), &base);
  std::vector<float> log_norm;
  for (const EvalComponentF& e : base) log_norm.push_back(e.log_norm);
  MeasurementParams noise_off;
  noise_off.depth_noise.a_m = noise_off.depth_noise.b_per_m = 0.f;
  const ViewReach reach = viewReach(frame, MeasurementParams());
  for (const MeasurementParams& mp : {noise_off, MeasurementParams()}) {
    const MemberDepthPrune prune = memberDepthPrune(min_z, max_z, log_norm.data(), mp);
    long long full_pairs = 0, pruned_pairs = 0;
    double worst = 0.0, worst_allowed = 0.0;
    for (const RigidTransformF& T_cam_map : spreadCameraPoses(12, false, 5)) {
      std::vector<ProjectedComponent> projected;
      std::vector<char> valid_full, valid_pruned;
      PatchMembership full, pruned;
      computeMembership(w.map.packed(), T_cam_map, frame.intrinsics, frame.grid, mp, &projected,
                        &valid_full, &full, &reach);
      computeMembership(w.map.packed(), T_cam_map, frame.intrinsics, frame.grid, mp, &projected,
                        &valid_pruned, &pruned, &reach, &prune);
      double allowed = 0.0;  // sum over pixels of (pruned members) e^-26
      for (int p = 0; p < frame.grid.count(); ++p) {
        const auto fb = full.comps.begin() + full.begin[p];
        const auto fe = full.comps.begin() + full.begin[p + 1];
        for (int k = pruned.begin[p]; k < pruned.begin[p + 1]; ++k) {
          ASSERT_TRUE(std::binary_search(fb, fe, pruned.comps[k])) << p;
        }
        const int pixels = frame.patch_begin[p + 1] - frame.patch_begin[p];
        if (pixels > 0) {
          full_pairs += full.countFor(p);
          pruned_pairs += pruned.countFor(p);
          allowed += pixels * (full.countFor(p) - pruned.countFor(p)) * std::exp(-26.0);
        }
      }
      std::vector<EvalComponentF> noisy;
      const RigidTransformF T_map_cam = invertRigid(T_cam_map);
      const EvalComponentF* eval =
          noisyEvalComponents(w.map.packed(), base, valid_full, T_cam_map, mp.depth_noise, &noisy);
      const double a = tableLogLikelihood(eval, frame, T_map_cam, full, mp.floor_log_density);
      const double b = tableLogLikelihood(eval, frame, T_map_cam, pruned, mp.floor_log_density);
      EXPECT_LE(std::abs(a - b), allowed);
      worst = std::max(worst, std::abs(a - b));
      worst_allowed = std::max(worst_allowed, allowed);
    }
    std::printf(
        "[ measured ] depth noise %s: pairs on patches with pixels %lld pruned to %lld (%.0f%%); "
        "log-likelihood moved by at most %.2e nats (bound %.2e)\n",
        mp.depth_noise.enabled() ? "on" : "off", full_pairs, pruned_pairs,
        100.0 * pruned_pairs / full_pairs, worst, worst_allowed);
    EXPECT_LT(pruned_pairs, 0.9 * full_pairs);
  }
}

// The pruned table is the full one less exactly the pairs that MemberDepthPrune's test rules
// out (computed here in double from the component's camera depth and depth variance), pair for
// pair, at patch sizes whose boxes span one or several of the box tests' tiles (4 x 4 patches
// with AVX-512, a row of 8 with AVX2); a pair may differ only where the gap's square is within
// 1e-4 of its bound (float rounding).
TEST(MembershipTest, DepthPruneDropsExactlyThePairsOutOfReach) {
  const auto& w = test::world();
  std::vector<EvalComponentF> base;
  makeEvalComponents(w.map.packed(), &base);
  std::vector<float> log_norm;
  for (const EvalComponentF& e : base) log_norm.push_back(e.log_norm);
  const MeasurementParams mp;
  const DepthNoiseModel& noise = mp.depth_noise;
  long long full_pairs = 0, pruned_pairs = 0, borderline = 0;
  for (int patch : {32, 16, 8}) {
    FrameParams fp = test::frameParams(4);
    fp.patch_size_px = patch;
    const DepthFrame frame = test::renderFrame(test::referenceBasePose(), test::vgaCamera(), fp);
    std::vector<float> min_z, max_z;
    patchDepthRanges(frame, &min_z, &max_z);
    const MemberDepthPrune prune = memberDepthPrune(min_z, max_z, log_norm.data(), mp);
    const ViewReach reach = viewReach(frame, mp);
    std::vector<RigidTransformF> poses = spreadCameraPoses(8, false, 7);
    for (const RigidTransformF& T : spreadCameraPoses(8, true, 8)) poses.push_back(T);
    for (const RigidTransformF& T_cam_map : poses) {
      std::vector<ProjectedComponent> projected;
      std::vector<char> valid;
      PatchMembership full, pruned;
      computeMembership(w.map.packed(), T_cam_map, frame.intrinsics, frame.grid, mp, &projected,
                        &valid, &full, &reach);
      computeMembership(w.map.packed(), T_cam_map, frame.intrinsics, frame.grid, mp, &projected,
                        &valid, &pruned, &reach, &prune);
      const double a0 = T_cam_map.R[6], a1 = T_cam_map.R[7], a2 = T_cam_map.R[8];
      for (int p = 0; p < frame.grid.count(); ++p) {
        const auto pb = pruned.comps.begin() + pruned.begin[p];
        const auto pe = pruned.comps.begin() + pruned.begin[p + 1];
        for (int k = full.begin[p]; k < full.begin[p + 1]; ++k) {
          const ComponentF& c = w.map.packed()[full.comps[k]];
          const double z = a0 * c.mean_m[0] + a1 * c.mean_m[1] + a2 * c.mean_m[2] + T_cam_map.t[2];
          const float* S = c.cov_m2;  // xx xy xz yy yz zz
          const double var = a0 * a0 * S[0] + 2 * a0 * a1 * S[1] + 2 * a0 * a2 * S[2] +
                             a1 * a1 * S[3] + 2 * a1 * a2 * S[4] + a2 * a2 * S[5];
          const double sigma = noise.a_m + noise.b_per_m * (z - noise.z0_m) * (z - noise.z0_m);
          const double dz2_max = 2.0 * (var + sigma * sigma) *
                                 (log_norm[full.comps[k]] + kDepthPruneNats - mp.floor_log_density);
          const double gap = std::max(0.0, std::max(min_z[p] - z, z - max_z[p]));
          const bool expected = gap * gap <= dz2_max;
          const bool kept = std::binary_search(pb, pe, full.comps[k]);
          if (kept != expected) {
            ++borderline;
            EXPECT_LT(std::abs(gap * gap - dz2_max), 1e-4 * std::abs(dz2_max))
                << "patch size " << patch << ", patch " << p << ", component " << full.comps[k]
                << (kept ? " kept" : " pruned");
          }
        }
        full_pairs += full.countFor(p);
        pruned_pairs += pruned.countFor(p);
      }
    }
  }
  std::printf(
      "[ measured ] depth prune at patch sizes 32, 16, 8 (16 poses each): %lld pairs pruned to "
      "%lld, %lld borderline pairs decided otherwise than in double\n",
      full_pairs, pruned_pairs, borderline);
  EXPECT_LT(pruned_pairs, full_pairs);
}

// The vectorisable helpers of the membership projection (fast_math.h).
TEST(MembershipTest, VectorisableHelpersMatchLibm) {
  int worst_ulp = 0;
  for (double lx = -20.0; lx <= 30.0; lx += 0.0007) {
    const float x = static_cast<float>(std::pow(10.0, lx));
    worst_ulp = std::max(worst_ulp, std::abs(floatToBits(sqrtVec(x)) - floatToBits(sqrtf(x))));
  }
  std::printf("[ measured ] sqrtVec: worst %d ulp from sqrtf on [1e-20, 1e30]\n", worst_ulp);
  EXPECT_LE(worst_ulp, 4);
  EXPECT_EQ(sqrtVec(0.f), 0.f);
  EXPECT_TRUE(std::isnan(sqrtVec(std::nanf(""))));
  EXPECT_EQ(maxZero(-3.f), 0.f);
  EXPECT_EQ(maxZero(2.5f), 2.5f);
  for (float x = -70.f; x <= 70.f; x += 0.125f) {
    for (float d : {0.f, 1e-6f, -1e-6f}) {
      const float y = x + d;
      EXPECT_EQ(ceilInt(y), static_cast<int>(std::ceil(y))) << y;
      EXPECT_EQ(floorInt(y), static_cast<int>(std::floor(y))) << y;
    }
  }
}

TEST(MembershipTest, ApproximateLikelihoodWithinOnePercentOfExact) {
  // With and without the depth-noise model: the approximation (membership + float kernel) against
  // the double-precision sum over every component of the same model.
  const auto& w = test::world();
  FrameParams fp = test::frameParams(4);
  MeasurementParams noise_off;
  noise_off.depth_noise.a_m = noise_off.depth_noise.b_per_m = 0.f;
  for (const MeasurementParams& mp : {noise_off, MeasurementParams()}) {
    for (const Intrinsics& K : {test::smallCamera(), test::vgaCamera()}) {
      const Eigen::Isometry3d T_map_base = test::referenceBasePose();
      const DepthFrame frame = test::renderFrame(T_map_base, K, fp);
      const Eigen::Isometry3d T_map_cam = T_map_base * w.T_base_cam;
      LikelihoodScratch scratch;
      const FrameLikelihood approx =
          poseLogLikelihood(w.map.packed(), frame, toRigidF(T_map_cam), mp, &scratch);
      const FrameLikelihood exact = exactFrameLogLikelihood(w.map, frame, T_map_cam, mp);
      const double rel =
          std::abs(approx.log_likelihood - exact.log_likelihood) / std::abs(exact.log_likelihood);
      std::printf(
          "[ measured ] %dx%d, depth noise %s: approx %.2f exact %.2f nats over %d px, "
          "relative error %.2e, evaluations %lld vs %lld, floor hits %d vs %d\n",
          K.width_px, K.height_px, mp.depth_noise.enabled() ? "on" : "off", approx.log_likelihood,
          exact.log_likelihood, approx.pixels, rel, approx.evaluations, exact.evaluations,
          approx.floor_hits, exact.floor_hits);
      EXPECT_LT(rel, kApproxRelTol);
      EXPECT_LT(approx.evaluations, exact.evaluations / 10);  // the point of the approximation
    }
  }
}

TEST(MembershipTest, PatchesWithoutComponentsGetTheFloor) {
  const auto& w = test::world();
  const Intrinsics K = test::smallCamera();
  FrameParams fp;
  const DepthFrame frame = test::renderFrame(test::referenceBasePose(), K, fp);
  PatchMembership none;
  none.begin.assign(frame.grid.count() + 1, 0);
  std::vector<float> values;
  const FrameLikelihood fl =
      frameLogLikelihood(w.map.packed(), frame, toRigidF(test::referenceBasePose() * w.T_base_cam),
                         none, -10.f, &values);
  EXPECT_EQ(fl.floor_hits, fl.pixels);
  EXPECT_NEAR(fl.log_likelihood, -10.0 * fl.pixels, 1e-6 * fl.pixels);
}

}  // namespace
}  // namespace gmm_mcl
